//! The node at work: boot and NMT state, frame dispatch, timeouts, EMCY.

use super::{
    NodeCore, NodeEvent, NodeEventKind, NodeStats, QueueFull, StateCause, EVENT_QUEUE, TX_QUEUE,
};
use crate::cia301::emcy::{self, EmcyMessage, EmcyProducer};
use crate::cia301::guarding::{GuardEvent, LifeEvent};
use crate::cia301::heartbeat::ConsumerEvent;
use crate::cia301::nmt::{self, NmtCommand, NmtState};
use crate::cia301::pdo::{self, PdoEngine};
use crate::frame::cob_id::NodeId;
use crate::frame::instant::{earliest, Instant};
use crate::frame::queue::Bounded;
use crate::frame::Malformed;
use crate::frame::{Frame, Id};
use crate::od::{comm, ObjectDictionary};
use crate::profile::{IdProfile, ProfileFrame};

impl<D: ObjectDictionary, P: IdProfile, const G: usize, const TPDOS: usize, const RPDOS: usize>
    NodeCore<D, P, G, TPDOS, RPDOS>
{
    pub(super) fn id(&self) -> NodeId {
        self.cfg.node_id
    }

    pub(super) fn event(&mut self, at: Instant, kind: NodeEventKind) {
        self.events.push(NodeEvent { at, kind });
    }

    pub(super) fn pdo_io(&mut self) -> (&mut PdoEngine<TPDOS, RPDOS>, pdo::Io<'_, D, PdoOut<'_>>) {
        let io = pdo::Io {
            od: &mut self.od,
            out: PdoOut {
                tx: &mut self.tx,
                stats: &mut self.stats,
                events: &mut self.events,
            },
        };
        (&mut self.pdo, io)
    }

    pub(super) fn pdo_emcy(&mut self, now: Instant) {
        while let Some(a) = self.pdo.take_emcy() {
            match a {
                pdo::EmcyAction::Raise(code, data) => {
                    self.emcy_raise(now, code, emcy::register::COMMUNICATION, data)
                }
                pdo::EmcyAction::Clear(code) => self.emcy_clear(now, code),
            }
        }
    }

    pub(super) fn pdo_sync(&mut self, now: Instant, counter: Option<u8>) {
        let (engine, mut io) = self.pdo_io();
        engine.on_sync(now, counter, &mut io);
        self.pdo_emcy(now);
    }

    /// A write landed: PDO parameters reload their PDO, other entries may trigger TPDOs.
    pub(super) fn pdo_written(&mut self, now: Instant, index: u16, sub: u8) {
        let (engine, mut io) = self.pdo_io();
        match pdo::classify(index) {
            Some((dir, _, slot)) => engine.reload(now, dir, slot, &mut io),
            None => engine.written(now, index, sub, &mut io),
        }
        self.pdo_emcy(now);
    }

    pub(super) fn send(&mut self, f: Frame) -> Result<(), QueueFull> {
        if self.tx.push(f) {
            self.stats.tx_frames += 1;
            Ok(())
        } else {
            Err(QueueFull)
        }
    }

    /// Queues a frame for the bus (for protocol servers composed with the node).
    pub fn transmit(&mut self, f: Frame) -> Result<(), QueueFull> {
        self.send(f)
    }

    /// Reports a malformed frame.
    pub fn malformed(&mut self, now: Instant, id: Id, reason: Malformed) {
        self.stats.malformed += 1;
        self.event(now, NodeEventKind::Malformed { id, reason });
    }

    /// The dictionary.
    pub fn od(&self) -> &D {
        &self.od
    }
    /// The node-ID.
    pub fn node_id(&self) -> NodeId {
        self.cfg.node_id
    }
    /// The identifier profile.
    pub fn profile(&self) -> &P {
        &self.profile
    }

    pub(super) fn boot(&mut self, now: Instant) {
        self.boots = self.boots.wrapping_add(1);
        let from = self.state;
        self.state = NmtState::Initialising;
        self.apply_config(now);
        let boot_up = Frame::from_array(
            self.profile.heartbeat(self.id()),
            [NmtState::Initialising.code()],
        );
        let _ = self.send(boot_up);
        if from != NmtState::Initialising {
            self.event(
                now,
                NodeEventKind::StateChanged {
                    from,
                    to: NmtState::Initialising,
                    cause: StateCause::Boot,
                },
            );
        }
        self.enter(now, NmtState::PreOperational, StateCause::Boot);
        if self.cfg.auto_start {
            self.enter(now, NmtState::Operational, StateCause::Boot);
        }
    }

    pub(super) fn enter(&mut self, now: Instant, to: NmtState, cause: StateCause) {
        let from = self.state;
        if from == to {
            return;
        }
        self.state = to;
        self.event(now, NodeEventKind::StateChanged { from, to, cause });
        if to == NmtState::Operational {
            let (engine, mut io) = self.pdo_io();
            engine.start(now, &mut io);
        } else if from == NmtState::Operational {
            self.pdo.stop();
        }
        self.pdo_emcy(now);
    }

    pub(super) fn emcy_raise(&mut self, now: Instant, code: u16, register_bits: u8, data: [u8; 5]) {
        let Some(msg) = self.emcy.raise(code, register_bits, data) else {
            return;
        };
        let _ = self.od.store(comm::ERROR_REGISTER, 0, &[msg.register]);
        if self.history_slots > 0 {
            let count = (self.od.get_u32(comm::ERROR_HISTORY, 0).unwrap_or(0) as u8)
                .min(self.history_slots);
            for s in (1..count.min(self.history_slots - 1) + 1).rev() {
                if let Some(v) = self.od.get_u32(comm::ERROR_HISTORY, s) {
                    let _ = self.od.store(comm::ERROR_HISTORY, s + 1, &v.to_le_bytes());
                }
            }
            let _ = self
                .od
                .store(comm::ERROR_HISTORY, 1, &(code as u32).to_le_bytes());
            let _ = self.od.store(
                comm::ERROR_HISTORY,
                0,
                &[(count + 1).min(self.history_slots)],
            );
        }
        self.flush_emcy(now);
    }

    pub(super) fn emcy_clear(&mut self, now: Instant, code: u16) {
        if self.emcy.clear(code) {
            let _ = self
                .od
                .store(comm::ERROR_REGISTER, 0, &[self.emcy.register()]);
            self.flush_emcy(now);
        }
    }

    pub(super) fn flush_emcy(&mut self, now: Instant) {
        if !self.state.services().emcy {
            return;
        }
        while let Some(f) = self.emcy.poll_frame(now) {
            let _ = self.send(f);
        }
    }

    pub(super) fn nmt_received(&mut self, now: Instant, frame: &Frame) {
        let (cmd, target) = match nmt::parse_command(frame) {
            Ok(x) => x,
            Err(reason) => return self.malformed(now, frame.id(), reason),
        };
        self.event(now, NodeEventKind::NmtObserved { cmd, target });
        if !self.cfg.accept_nmt || (target != 0 && target != self.id().raw()) {
            return;
        }
        let cause = StateCause::Command(cmd);
        match cmd {
            NmtCommand::Start | NmtCommand::Stop | NmtCommand::EnterPreOperational => {
                self.enter(now, cmd.resulting_state(), cause)
            }
            NmtCommand::ResetNode => {
                self.od.reset_range(0x1000..=0xFFFF);
                self.emcy = EmcyProducer::default();
                self.boot(now);
            }
            NmtCommand::ResetCommunication => {
                self.od.reset_range(0x1000..=0x1FFF);
                self.boot(now);
            }
        }
    }

    pub(super) fn error_control_received(&mut self, now: Instant, node: NodeId, frame: &Frame) {
        if node == self.id() {
            // Our own identifier from someone else: a configuration fault elsewhere; not ours.
            self.stats.unhandled += 1;
            return;
        }
        let (state, toggle) = match nmt::parse_error_control(frame) {
            Ok(x) => x,
            Err(reason) => return self.malformed(now, frame.id(), reason),
        };
        let changed = self.nodes.observe(node, state, now);
        if state == NmtState::Initialising {
            // Every boot-up is news, also a second one with no heartbeat in between (a slave
            // without a producer that reboots again): a master reconfigures on each.
            self.event(now, NodeEventKind::BootUp { node });
        } else if let Some(from) = changed {
            self.event(
                now,
                NodeEventKind::RemoteState {
                    node,
                    from,
                    to: state,
                },
            );
        }
        if state == NmtState::Initialising {
            self.guard_master.booted(node);
        }
        if let Some(ConsumerEvent::Resumed { node }) = self.consumer.heard(node, now) {
            self.event(now, NodeEventKind::HeartbeatResumed { node });
        }
        let mut evs: heapless::Vec<GuardEvent, 2> = heapless::Vec::new();
        self.guard_master.answer(now, node, state, toggle, |e| {
            let _ = evs.push(e);
        });
        for e in evs {
            self.guard_event(now, e);
        }
    }

    pub(super) fn guard_event(&mut self, now: Instant, e: GuardEvent) {
        let kind = match e {
            // The state itself was recorded from the frame already.
            GuardEvent::State { .. } => return,
            GuardEvent::Timeout { node } => NodeEventKind::GuardingTimeout { node },
            GuardEvent::Resumed { node } => NodeEventKind::GuardingResumed { node },
            GuardEvent::ToggleError { node, .. } => NodeEventKind::GuardToggleError { node },
        };
        self.event(now, kind);
    }

    pub(super) fn guard_request(&mut self, now: Instant, frame: &Frame) {
        if !frame.is_remote() {
            return self.malformed(now, frame.id(), Malformed::UnexpectedData);
        }
        let (byte, resumed) = self.guard.request(now, self.state);
        let _ = self.send(Frame::from_array(self.profile.guarding(self.id()), [byte]));
        if resumed.is_some() {
            self.emcy_clear(now, emcy::code::LIFE_GUARD);
            self.event(now, NodeEventKind::LifeGuardingResumed);
        }
    }

    pub(super) fn handle_frame(&mut self, now: Instant, frame: &Frame) {
        self.stats.rx_frames += 1;
        if self.state == NmtState::Initialising {
            return;
        }
        let services = self.state.services();
        let id = frame.id();
        if Some(id) == self.sync.id() {
            if !services.sync {
                return;
            }
            match self.sync.received(now, frame) {
                Ok(tick) => {
                    self.event(
                        now,
                        NodeEventKind::Sync {
                            counter: tick.counter,
                            produced: false,
                        },
                    );
                    self.pdo_sync(now, tick.counter);
                }
                Err(reason) => {
                    self.malformed(now, id, reason);
                    self.emcy_raise(
                        now,
                        emcy::code::SYNC_LENGTH,
                        emcy::register::COMMUNICATION,
                        [0; 5],
                    );
                }
            }
            return;
        }
        if Some(id) == self.time.id() {
            if !services.time {
                return;
            }
            match self.time.received(now, frame) {
                Ok(tod) => self.event(now, NodeEventKind::Time { tod }),
                Err(reason) => self.malformed(now, id, reason),
            }
            return;
        }
        let (engine, mut io) = self.pdo_io();
        if engine.handle_frame(now, frame, &mut io) {
            self.pdo_emcy(now);
            return;
        }
        match self.profile.classify(id, frame.is_remote()) {
            Some(ProfileFrame::Nmt) => self.nmt_received(now, frame),
            Some(ProfileFrame::Heartbeat(n)) => {
                if frame.is_remote() {
                    // Shared identifier: a remote frame here is a guarding request.
                    if n == self.id() {
                        self.guard_request(now, frame);
                    } else if !self.guard_master.observed_request(n) {
                        self.stats.unhandled += 1;
                    }
                } else {
                    self.error_control_received(now, n, frame);
                }
            }
            Some(ProfileFrame::Guarding(n)) => {
                if n == self.id() {
                    self.guard_request(now, frame);
                } else if frame.is_remote() {
                    // Another master guarding a node this one guards too: the answer follows.
                    if !self.guard_master.observed_request(n) {
                        self.stats.unhandled += 1;
                    }
                } else {
                    self.error_control_received(now, n, frame);
                }
            }
            Some(ProfileFrame::Emcy(n)) => {
                if n == self.id() || !services.emcy || !self.cfg.consume_emcy {
                    self.stats.unhandled += 1;
                    return;
                }
                match EmcyMessage::from_frame(frame) {
                    Ok(msg) => self.event(now, NodeEventKind::Emcy { node: n, msg }),
                    Err(reason) => self.malformed(now, id, reason),
                }
            }
            None => self.stats.unhandled += 1,
        }
    }

    pub(super) fn handle_timeout(&mut self, now: Instant) {
        if self.state == NmtState::Initialising {
            return;
        }
        let services = self.state.services();
        if self.hb.due(now) && services.error_control {
            let _ = self.send(Frame::from_array(
                self.profile.heartbeat(self.id()),
                [self.state.code()],
            ));
        }
        let events = &mut self.events;
        self.consumer.handle_timeout(now, |e| {
            if let ConsumerEvent::Timeout { node, last } = e {
                events.push(NodeEvent {
                    at: now,
                    kind: NodeEventKind::HeartbeatTimeout { node, last },
                });
            }
        });
        if self.guard.handle_timeout(now) == Some(LifeEvent::Lost) {
            self.event(now, NodeEventKind::LifeGuardingLost);
            self.emcy_raise(
                now,
                emcy::code::LIFE_GUARD,
                emcy::register::COMMUNICATION,
                [0; 5],
            );
        }
        let mut requests: heapless::Vec<NodeId, G> = heapless::Vec::new();
        let mut gevs: heapless::Vec<GuardEvent, G> = heapless::Vec::new();
        self.guard_master.handle_timeout(
            now,
            |n| {
                let _ = requests.push(n);
            },
            |e| {
                let _ = gevs.push(e);
            },
        );
        for e in gevs {
            self.guard_event(now, e);
        }
        for n in requests {
            if let Ok(f) = Frame::remote(self.profile.guarding(n), 1) {
                let _ = self.send(f);
            }
        }
        if let Some((f, tick)) = self.sync.handle_timeout(now) {
            if services.sync {
                let _ = self.send(f);
                self.event(
                    now,
                    NodeEventKind::Sync {
                        counter: tick.counter,
                        produced: true,
                    },
                );
                self.pdo_sync(now, tick.counter);
            }
        }
        if let Some(f) = self.time.handle_timeout(now) {
            if services.time {
                let _ = self.send(f);
            }
        }
        let (engine, mut io) = self.pdo_io();
        engine.handle_timeout(now, &mut io);
        self.pdo_emcy(now);
        self.flush_emcy(now);
    }

    #[must_use]
    pub(super) fn poll_timeout(&self) -> Option<Instant> {
        if self.state == NmtState::Initialising {
            return None;
        }
        let mut t = earliest(self.hb.poll_timeout(), self.consumer.poll_timeout());
        t = earliest(t, self.guard.poll_timeout());
        t = earliest(t, self.guard_master.poll_timeout());
        t = earliest(t, self.sync.poll_timeout());
        t = earliest(t, self.time.poll_timeout());
        t = earliest(t, self.pdo.poll_timeout());
        if self.state.services().emcy {
            t = earliest(t, self.emcy.poll_timeout());
        }
        t
    }
}

/// The node's queues, as the PDO engine's output.
pub(super) struct PdoOut<'a> {
    tx: &'a mut Bounded<Frame, TX_QUEUE>,
    stats: &'a mut NodeStats,
    events: &'a mut Bounded<NodeEvent, EVENT_QUEUE>,
}

impl pdo::PdoOutput for PdoOut<'_> {
    fn send(&mut self, frame: Frame) {
        if self.tx.push(frame) {
            self.stats.tx_frames += 1;
        }
    }
    fn event(&mut self, at: Instant, e: pdo::PdoEvent) {
        self.events.push(NodeEvent {
            at,
            kind: NodeEventKind::Pdo(e),
        });
    }
}
