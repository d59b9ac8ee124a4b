//! The slaves, one by one: how the master reacts to node events, SDO results and its timers, and
//! how it drives the per-slave boot processes over the SDO client's sessions.

use super::boot::{BootPhase, ErrorStatus, Outcome, Process};
use super::config::{ExpectedIdentity, NmtStartup, SlaveConfig, StartPolicy};
use super::events::{MasterError, MasterEventKind};
use super::network::Network;
use super::objects::{self, request, REQUEST_ALL};
use super::Master;
use crate::cia301::nmt::{NmtCommand, NmtState, NmtTarget};
use crate::cia301::sdo::{RequestId, SdoErrorKind, SdoEvent, SdoOptions, TransferBuffer};
use crate::frame::cob_id::NodeId;
use crate::frame::cob_id::NodeSet;
use crate::frame::instant::{earliest, earliest_of, shift_back, Duration, Instant};
use crate::machine::Machine;
use crate::node::{NodeEvent, NodeEventKind};
use crate::od::abort::AbortCode;
use crate::od::{comm, ObjectDictionary};
use crate::profile::IdProfile;

/// Everything the master keeps per node-ID.
pub(super) struct Slot {
    pub(super) cfg: SlaveConfig,
    pub(super) phase: BootPhase,
    pub(super) process: Option<Process>,
    /// The SDO request in flight to the node (of the running process, or of one dropped).
    pub(super) request: Option<RequestId>,
    /// Begin the process once the request in flight ends.
    pub(super) restart: bool,
    pub(super) queued: bool,
    pub(super) probe_at: Option<Instant>,
    pub(super) wait_until: Option<Instant>,
    /// K watchdog: (configured at, first heartbeat due by).
    pub(super) hb_check: Option<(Instant, Instant)>,
    /// Last NMT command that addressed the node: the state it leads to (`None`: a reset), when.
    pub(super) commanded: Option<(Option<NmtState>, Instant)>,
    pub(super) missing: bool,
    pub(super) missing_reported: bool,
    /// This master's node guards it (0x1F81 guard time), active or standby.
    pub(super) guarded: bool,
    pub(super) last_error: Option<ErrorStatus>,
    pub(super) boot_ups: u32,
}

impl Slot {
    pub(super) fn new(n: NodeId) -> Slot {
        Slot {
            cfg: SlaveConfig::new(n),
            phase: BootPhase::Unassigned,
            process: None,
            request: None,
            restart: false,
            queued: false,
            probe_at: None,
            wait_until: None,
            hb_check: None,
            commanded: None,
            missing: false,
            missing_reported: false,
            guarded: false,
            last_error: None,
            boot_ups: 0,
        }
    }

    pub(super) fn deadline(&self) -> Option<Instant> {
        earliest_of([
            self.probe_at,
            self.wait_until,
            self.hb_check.map(|(_, d)| d),
        ])
    }

    /// The caller's clock stepped back `by` (the clock contract, [`crate::frame::instant`]).
    fn step_back(&mut self, by: Duration) {
        shift_back(&mut self.probe_at, by);
        shift_back(&mut self.wait_until, by);
        if let Some((armed, due)) = self.hb_check.as_mut() {
            *armed = *armed - by;
            *due = *due - by;
        }
        if let Some((_, at)) = self.commanded.as_mut() {
            *at = *at - by;
        }
    }
}

impl<D: ObjectDictionary, P: IdProfile> Master<D, P> {
    // ----- inputs -----

    /// Drains the node's and the client's events, reacting to each, until nothing moves.
    pub(super) fn pump(&mut self, now: Instant) {
        loop {
            let mut moved = false;
            while let Some(e) = self.node.poll_event() {
                moved = true;
                self.on_node_event(e);
            }
            while let Some(e) = self.sdo.poll_event() {
                moved = true;
                self.on_sdo_event(e);
            }
            self.dispatch(now);
            if !moved {
                break;
            }
        }
    }

    pub(super) fn deadline(&self) -> Option<Instant> {
        let net = match self.network {
            Network::Booting {
                deadline,
                reported: false,
            } => deadline,
            _ => None,
        };
        debug_assert!(
            self.slot_deadline()
                .is_none_or(|t| self.slot_timer.is_some_and(|b| b <= t)),
            "a slot timer was armed without Master::arm"
        );
        earliest(net, self.slot_timer)
    }

    /// The earliest timer of any slot, computed (127 slots: not on every poll).
    fn slot_deadline(&self) -> Option<Instant> {
        earliest_of(self.slots.iter().map(|s| s.deadline()))
    }

    /// A slot timer was set to `t`: the cached lower bound of every slot's timers follows.
    /// Clearing a timer needs nothing (a bound reached early only costs a look at the slots).
    pub(super) fn arm(&mut self, t: Option<Instant>) {
        self.slot_timer = earliest(self.slot_timer, t);
    }

    /// The clock contract ([`crate::frame::instant`]): on every input that carries a time, a step
    /// back of the caller's clock moves every timer of the master back with it (its node and SDO
    /// client watch the clock themselves).
    #[inline]
    pub(super) fn watch_clock(&mut self, now: Instant) {
        if let Some(by) = self.clock.step_back(now) {
            self.step_back(by);
        }
    }

    #[cold]
    fn step_back(&mut self, by: Duration) {
        for s in self.slots.iter_mut() {
            s.step_back(by);
        }
        // Recomputed rather than shifted: a timer that saturated at the end of time was "never"
        // in the cached bound, and is a real deadline once moved back.
        self.slot_timer = self.slot_deadline();
        if let Network::Booting { deadline, .. } = &mut self.network {
            shift_back(deadline, by);
        }
    }

    pub(super) fn on_timers(&mut self, now: Instant) {
        if let Network::Booting {
            deadline: Some(d),
            reported: false,
        } = self.network
        {
            if d <= now {
                self.network = Network::Booting {
                    deadline: Some(d),
                    reported: true,
                };
                let mut nodes = NodeSet::EMPTY;
                for n in self.assigned() {
                    if self.assignment(n).is_mandatory() && !self.slot(n).phase.is_booted() {
                        nodes.insert(n);
                    }
                }
                if !nodes.is_empty() {
                    self.emit(d, MasterEventKind::MandatoryMissing { nodes });
                }
            }
        }
        if self.slot_timer.is_none_or(|t| t > now) {
            return;
        }
        for i in 0..self.slots.len() {
            let Some(n) = NodeId::new(i as u8 + 1) else {
                continue;
            };
            let s = &mut self.slots[i];
            if s.wait_until.is_some_and(|t| t <= now) {
                s.wait_until = None;
                self.decide_keep_alive(now, n);
            }
            let s = &mut self.slots[i];
            if s.probe_at.is_some_and(|t| t <= now) {
                s.probe_at = None;
                if s.phase == BootPhase::WaitBootUp && self.acting() {
                    self.stats.probes += 1;
                    self.begin(now, n);
                }
            }
            let s = &mut self.slots[i];
            if let Some((armed, due)) = s.hb_check {
                if due <= now {
                    s.hb_check = None;
                    let heard = self.node.remote(n).is_some_and(|v| v.seen > armed);
                    if !heard {
                        self.error_control(due, n, ErrorStatus::K);
                    }
                }
            }
        }
        self.slot_timer = self.slot_deadline();
    }

    pub(super) fn on_node_event(&mut self, e: NodeEvent) {
        let now = e.at;
        self.emit(now, MasterEventKind::Node(e.kind));
        match e.kind {
            NodeEventKind::BootUp { node } => {
                self.on_boot_up(now, node);
                self.standby_guard(now, node);
            }
            NodeEventKind::RemoteState { node, .. } => {
                self.standby_guard(now, node);
                self.refresh(node);
                if self.slot(node).phase == BootPhase::WaitState {
                    self.decide_keep_alive(now, node);
                }
            }
            NodeEventKind::HeartbeatTimeout { node, .. } => {
                self.error_control(now, node, ErrorStatus::E)
            }
            NodeEventKind::GuardingTimeout { node } => {
                self.error_control(now, node, ErrorStatus::F)
            }
            NodeEventKind::HeartbeatResumed { node } | NodeEventKind::GuardingResumed { node } => {
                self.slot_mut(node).missing = false;
                self.refresh(node);
            }
            NodeEventKind::ObjectWritten { index, sub, .. } => match index {
                objects::REQUEST_NMT => self.on_request_nmt(now, sub),
                objects::SLAVE_ASSIGNMENT => {
                    if let Some(n) = NodeId::new(sub) {
                        self.on_assignment(now, n);
                    }
                }
                comm::SYNC_COB_ID | comm::TIME_COB_ID => self.on_producer_written(now, index),
                _ => {}
            },
            NodeEventKind::NmtObserved { cmd, target } => {
                // Another node's command (the active master, seen by a standby; or a third
                // party): what the addressed nodes are now, until they are heard.
                let target = match NodeId::new(target) {
                    Some(n) => NmtTarget::Node(n),
                    None => NmtTarget::All,
                };
                self.note_command(now, cmd, target);
            }
            _ => {}
        }
    }

    pub(super) fn on_sdo_event(&mut self, e: SdoEvent) {
        let now = e.at;
        let n = e.node;
        let s = self.slot_mut(n);
        if s.request != Some(e.request) {
            self.emit(now, MasterEventKind::Sdo(e));
            return;
        }
        s.request = None;
        if s.process.is_none() {
            // Of a dropped process: the result means nothing now.
            if core::mem::take(&mut s.restart) {
                self.begin(now, n);
            }
            return;
        }
        if e.result.is_ok() {
            s.missing = false;
            s.missing_reported = false;
        }
        let id = self.expected_identity(n);
        let s = self.slot_mut(n);
        let result = e.result.as_ref().map(|b| b.as_slice()).map_err(|x| *x);
        let Some(p) = s.process.as_mut() else {
            return;
        };
        let out = p.handle(&s.cfg, &id, result);
        self.apply(now, n, out);
    }

    pub(super) fn on_boot_up(&mut self, now: Instant, n: NodeId) {
        let s = self.slot_mut(n);
        s.boot_ups = s.boot_ups.saturating_add(1);
        s.missing = false;
        s.missing_reported = false;
        self.refresh(n);
        let a = self.assignment(n);
        if !a.is_slave() {
            return;
        }
        self.emit(now, MasterEventKind::SlaveBootUp { node: n });
        if !self.acting() {
            self.slot_mut(n).phase = BootPhase::Observed;
            return;
        }
        let booting = matches!(self.network, Network::Booting { .. });
        if a.reboots() || booting || self.slot(n).phase == BootPhase::WaitBootUp {
            self.begin(now, n);
        } else {
            // 0x1F81 bit 2 clear: reported only; the application decides (boot_slave).
            self.cancel(n);
            self.slot_mut(n).phase = BootPhase::WaitBootUp;
        }
    }

    pub(super) fn on_request_nmt(&mut self, now: Instant, sub: u8) {
        let value = self
            .node
            .od()
            .get_u32(objects::REQUEST_NMT, sub)
            .unwrap_or(0) as u8;
        let cmd = match value {
            request::STOP => NmtCommand::Stop,
            request::START => NmtCommand::Start,
            request::RESET_NODE => NmtCommand::ResetNode,
            request::RESET_COMMUNICATION => NmtCommand::ResetCommunication,
            request::PRE_OPERATIONAL => NmtCommand::EnterPreOperational,
            // A read-back value written by the master itself: nothing was asked.
            _ => return,
        };
        let target = match NodeId::new(sub) {
            Some(n) => NmtTarget::Node(n),
            None if sub == REQUEST_ALL => NmtTarget::All,
            None => return,
        };
        let sent = if target == NmtTarget::Node(self.node.id()) {
            // A request about the master itself: states yes, resets not over the bus.
            match cmd {
                NmtCommand::ResetNode | NmtCommand::ResetCommunication => false,
                c => {
                    self.node.set_nmt_state(now, c.resulting_state());
                    true
                }
            }
        } else {
            self.acting() && self.command(now, cmd, target).is_ok()
        };
        self.emit(now, MasterEventKind::NmtRequest { target, cmd, sent });
        match target {
            NmtTarget::Node(n) => self.refresh(n),
            NmtTarget::All => {
                let _ = self.node.od_mut().store(
                    objects::REQUEST_NMT,
                    REQUEST_ALL,
                    &[request::UNKNOWN],
                );
            }
        }
    }

    pub(super) fn on_assignment(&mut self, now: Instant, n: NodeId) {
        let a = self.assignment(n);
        if let Err(MasterError::Refused { code, .. }) = self.set_consumer(now, n, a.is_slave()) {
            self.emit(
                now,
                MasterEventKind::ConsumerNotConfigured { node: n, code },
            );
        }
        if !a.is_slave() {
            self.cancel(n);
            self.slot_mut(n).phase = BootPhase::Unassigned;
            if core::mem::take(&mut self.slot_mut(n).guarded) {
                self.node.unguard_node(n);
            }
            return;
        }
        if self.slot(n).phase == BootPhase::Unassigned {
            if self.acting() {
                let s = self.slot_mut(n);
                s.phase = BootPhase::WaitBootUp;
                s.probe_at = Some(now);
                self.arm(Some(now));
            } else {
                self.slot_mut(n).phase = BootPhase::Observed;
            }
        }
    }

    /// A write to 0x1005/0x1012 while standby must not make the master a producer: the wish is
    /// kept for when it becomes active.
    pub(super) fn on_producer_written(&mut self, now: Instant, index: u16) {
        let Some(v) = self.node.od().get_u32(index, 0) else {
            return;
        };
        let on = v & crate::frame::cob_id::CobId::BIT30 != 0;
        if !self.active && on {
            match index {
                comm::SYNC_COB_ID => self.produce_sync = true,
                _ => self.produce_time = true,
            }
            self.set_producers(now, false);
        } else if self.active {
            match index {
                comm::SYNC_COB_ID => self.produce_sync = on,
                _ => self.produce_time = on,
            }
        }
    }

    // ----- one slave -----

    /// (Re)starts the boot process of `n` from the identity check.
    ///
    /// A request still in flight to `n` is waited for, not aborted: SDO frames carry no
    /// transaction number, so a server that got the old request (after its reset, say) would
    /// answer it into the new transfer. Its result is dropped and the process begins then.
    pub(super) fn begin(&mut self, now: Instant, n: NodeId) {
        self.cancel(n);
        let s = self.slot_mut(n);
        s.phase = BootPhase::Identifying;
        if s.request.is_some() {
            s.restart = true;
            return;
        }
        s.process = Some(Process::new(&s.cfg));
        self.stats.boots_started += 1;
        self.issue(now, n);
    }

    /// Drops whatever runs for `n`: its process, its place in the session queue, its timers.
    /// A transfer in flight ends by itself (its result is dropped).
    pub(super) fn cancel(&mut self, n: NodeId) {
        let s = self.slot_mut(n);
        s.process = None;
        s.restart = false;
        s.probe_at = None;
        s.wait_until = None;
        s.hb_check = None;
        if core::mem::take(&mut s.queued) {
            self.waiting.retain(|x| *x != n);
        }
    }

    /// Starts the current access of `n`'s process, or queues `n` for a session.
    pub(super) fn issue(&mut self, now: Instant, n: NodeId) {
        let opts = SdoOptions {
            timeout: self.sdo_timeout,
            ..SdoOptions::default()
        };
        let i = n.raw() as usize - 1;
        let s = &mut self.slots[i];
        let Some(p) = s.process.as_ref() else {
            return;
        };
        let Some(access) = p.access(&s.cfg) else {
            return;
        };
        self.sdo_idle = false;
        let started = match access {
            super::boot::Access::Read { index, sub } => self.sdo.upload(now, n, index, sub, opts),
            super::boot::Access::Write { index, sub, data } => {
                self.sdo.download(now, n, index, sub, data, opts)
            }
        };
        match started {
            Ok(r) => {
                s.request = Some(r);
                s.phase = if p.configuring() {
                    BootPhase::Configuring
                } else {
                    BootPhase::Identifying
                };
            }
            Err(e) if matches!(e.kind, SdoErrorKind::Busy | SdoErrorKind::NoSession { .. }) => {
                if !s.queued {
                    s.queued = true;
                    self.waiting.push_back(n);
                    self.stats.jobs_queued += 1;
                    self.stats.max_waiting = self.stats.max_waiting.max(self.waiting.len() as u32);
                }
            }
            Err(e) => {
                let id = self.expected_identity(n);
                let s = &mut self.slots[i];
                if let Some(p) = s.process.as_mut() {
                    let out = p.handle(&s.cfg, &id, Err(e));
                    self.apply(now, n, out);
                }
            }
        }
    }

    /// Gives waiting slaves the sessions that became free, in arrival order.
    pub(super) fn dispatch(&mut self, now: Instant) {
        let mut tries = self.waiting.len();
        while tries > 0 && self.sdo.in_flight() < self.sdo.sessions() {
            tries -= 1;
            let Some(n) = self.waiting.pop_front() else {
                break;
            };
            self.slot_mut(n).queued = false;
            let counted = self.stats.jobs_queued;
            self.issue(now, n);
            // Still waiting (its node busy with the application's transfer): the same wait.
            if self.slot(n).queued {
                self.stats.jobs_queued = counted;
            }
        }
    }

    pub(super) fn apply(&mut self, now: Instant, n: NodeId, out: Outcome) {
        match out {
            Outcome::Continue => self.issue(now, n),
            Outcome::Done => {
                self.slot_mut(n).process = None;
                self.configured(now, n);
            }
            Outcome::Mismatch {
                status,
                index,
                sub,
                expected,
                actual,
            } => {
                self.fail(n, status);
                self.emit(
                    now,
                    MasterEventKind::IdentityMismatch {
                        node: n,
                        status,
                        index,
                        sub,
                        expected,
                        actual,
                    },
                );
            }
            Outcome::Failed {
                status: ErrorStatus::B,
                reason,
            } => {
                // Not answering: missing. Reported once per absence; probed until it answers.
                let probe = self.probe_after(now);
                let s = self.slot_mut(n);
                s.process = None;
                s.phase = BootPhase::WaitBootUp;
                s.probe_at = probe;
                s.missing = true;
                s.last_error = Some(ErrorStatus::B);
                let report = !core::mem::replace(&mut s.missing_reported, true);
                self.arm(probe);
                self.refresh(n);
                if report {
                    self.emit(
                        now,
                        MasterEventKind::ConfigFailed {
                            node: n,
                            status: ErrorStatus::B,
                            reason,
                        },
                    );
                }
            }
            Outcome::Failed { status, reason } => {
                self.fail(n, status);
                self.emit(
                    now,
                    MasterEventKind::ConfigFailed {
                        node: n,
                        status,
                        reason,
                    },
                );
            }
        }
    }

    pub(super) fn fail(&mut self, n: NodeId, status: ErrorStatus) {
        let s = self.slot_mut(n);
        s.process = None;
        s.phase = BootPhase::Failed(status);
        s.last_error = Some(status);
    }

    pub(super) fn configured(&mut self, now: Instant, n: NodeId) {
        self.guard(now, n);
        let consumer = self.consumer_ms(n);
        let startup = self.startup();
        let beats = self
            .slot(n)
            .cfg
            .heartbeat_producer_ms
            .is_some_and(|p| p > 0);
        if beats && consumer > 0 {
            // Error control starts now: the consumer entry is re-armed to wait for the first
            // heartbeat of the configured producer (its boot-up had started it, and a long
            // configuration must not count as silence); the K watchdog covers a slave that
            // never beats.
            if let Err(MasterError::Refused { code, .. }) = self.set_consumer(now, n, true) {
                self.emit(
                    now,
                    MasterEventKind::ConsumerNotConfigured { node: n, code },
                );
            }
            let due = now + Duration::from_millis(consumer as u64);
            self.slot_mut(n).hb_check = Some((now, due));
            self.arm(Some(due));
        }
        let s = self.slot_mut(n);
        s.last_error = None;
        let policy = if startup.has(NmtStartup::NO_SLAVE_START) {
            StartPolicy::Application
        } else {
            s.cfg.start
        };
        self.emit(
            now,
            MasterEventKind::SlaveConfigured {
                node: n,
                start: policy,
            },
        );
        match policy {
            StartPolicy::Application => self.slot_mut(n).phase = BootPhase::Ready,
            StartPolicy::Auto if self.network_started() => self.start_one(now, n),
            StartPolicy::Auto => self.slot_mut(n).phase = BootPhase::WaitStart,
        }
        self.check_network_start(now);
    }

    pub(super) fn start_one(&mut self, now: Instant, n: NodeId) {
        if self.send_nmt(now, NmtCommand::Start, n.into()).is_ok() {
            self.slot_mut(n).phase = BootPhase::Started;
            self.emit(
                now,
                MasterEventKind::SlaveStarted {
                    node: n,
                    broadcast: false,
                },
            );
        }
    }

    pub(super) fn adopt(&mut self, now: Instant, n: NodeId, state: NmtState) {
        self.cancel(n);
        self.slot_mut(n).phase = BootPhase::Adopted;
        self.emit(now, MasterEventKind::SlaveAdopted { node: n, state });
    }

    pub(super) fn decide_keep_alive(&mut self, now: Instant, n: NodeId) {
        self.slot_mut(n).wait_until = None;
        if !self.acting() {
            return;
        }
        match self.view_state(n) {
            Some(NmtState::Operational) => self.adopt(now, n, NmtState::Operational),
            _ => self.begin(now, n),
        }
        self.check_network_start(now);
    }

    /// Error control lost `n` (E, F, K).
    pub(super) fn error_control(&mut self, now: Instant, n: NodeId, status: ErrorStatus) {
        let a = self.assignment(n);
        let phase = self.slot(n).phase;
        // Only a slave whose error control was started counts (a standby cannot tell, so it
        // reports what it sees). Before that its boot-up alone started the consumer: a slave
        // being booted again, failed, or not yet heard is not "lost".
        if !a.is_slave() || !(phase.is_booted() || phase == BootPhase::Observed) {
            return;
        }
        let s = self.slot_mut(n);
        s.missing = true;
        s.last_error = Some(status);
        self.refresh(n);
        self.emit(now, MasterEventKind::SlaveLost { node: n, status });
        if !self.acting() {
            return;
        }
        let startup = self.startup();
        if a.is_mandatory() && startup.has(NmtStartup::RESET_ALL) {
            let _ = self.command(now, NmtCommand::ResetCommunication, NmtTarget::All);
        } else if a.is_mandatory() && startup.has(NmtStartup::STOP_ALL) {
            let _ = self.command(now, NmtCommand::Stop, NmtTarget::All);
        } else if a.reboots() {
            let probe = self.probe_after(now);
            let s = self.slot_mut(n);
            s.phase = BootPhase::WaitBootUp;
            s.probe_at = probe;
            self.arm(probe);
        } else {
            self.slot_mut(n).phase = BootPhase::Failed(status);
        }
    }

    // ----- helpers -----

    /// Starts (or re-times) node guarding of `n` if its 0x1F81 entry gives a guard time.
    pub(super) fn guard(&mut self, now: Instant, n: NodeId) {
        let a = self.assignment(n);
        if !a.is_slave() || a.guard_time_ms() == 0 {
            return;
        }
        let t = Duration::from_millis(a.guard_time_ms() as u64);
        let guarded = self.node.guard_node(now, n, t, a.retry_factor().max(1));
        self.slot_mut(n).guarded = guarded;
    }

    /// A standby guards the slaves it hears (redundancy: both masters guard, so that each
    /// slave's life guarding sees both, and the standby knows who is alive before it takes
    /// over). An active master starts guarding at the end of the boot process instead.
    pub(super) fn standby_guard(&mut self, now: Instant, n: NodeId) {
        if self.booted && !self.acting() && !self.slot(n).guarded {
            self.guard(now, n);
        }
    }

    /// Stores `n`'s state as 0x1F82 sub n reads it.
    pub(super) fn refresh(&mut self, n: NodeId) {
        let code = self.slave(n).request_nmt_code();
        let _ = self
            .node
            .od_mut()
            .store(objects::REQUEST_NMT, n.raw(), &[code]);
    }

    pub(super) fn expected_identity(&self, n: NodeId) -> ExpectedIdentity {
        let od = self.node.od();
        let get = |index| od.get_u32(index, n.raw()).unwrap_or(0);
        ExpectedIdentity {
            device_type: get(objects::DEVICE_TYPE_ID),
            vendor: get(objects::VENDOR_ID),
            product: get(objects::PRODUCT_CODE),
            revision: get(objects::REVISION_NUMBER),
            serial: get(objects::SERIAL_NUMBER),
        }
    }

    pub(super) fn consumer_ms(&self, n: NodeId) -> u16 {
        match self.slot(n).cfg.heartbeat_consumer_ms {
            0 => self.default_consumer_ms,
            ms => ms,
        }
    }

    pub(super) fn probe_after(&self, now: Instant) -> Option<Instant> {
        (!self.probe_interval.is_zero()).then(|| now + self.probe_interval)
    }

    /// Adds (`on`) or clears the master's 0x1016 entry for `n`: the entry already naming `n`,
    /// else sub n if free, else the first free one.
    pub(super) fn set_consumer(
        &mut self,
        now: Instant,
        n: NodeId,
        on: bool,
    ) -> Result<(), MasterError> {
        let ms = if on { self.consumer_ms(n) } else { 0 };
        let od = self.node.od();
        let count = od
            .get_u32(comm::HEARTBEAT_CONSUMER, 0)
            .unwrap_or(0)
            .min(127) as u8;
        let value = |sub: u8| od.get_u32(comm::HEARTBEAT_CONSUMER, sub);
        let names = |sub: u8| value(sub).is_some_and(|v| (v >> 16) as u8 == n.raw());
        let free = |sub: u8| value(sub).is_some_and(|v| v & 0xFFFF == 0 || (v >> 16) as u8 == 0);
        let existing = (1..=count).find(|s| names(*s));
        let sub = match (existing, ms) {
            (Some(s), _) => s,
            (None, 0) => return Ok(()),
            (None, _) => {
                let own = (n.raw() <= count && free(n.raw())).then_some(n.raw());
                match own.or_else(|| (1..=count).find(|s| free(*s))) {
                    Some(s) => s,
                    None => {
                        return Err(MasterError::Refused {
                            index: comm::HEARTBEAT_CONSUMER,
                            sub: 0,
                            code: AbortCode::NO_RESOURCE,
                        })
                    }
                }
            }
        };
        let v = if ms == 0 {
            0
        } else {
            ((n.raw() as u32) << 16) | ms as u32
        };
        self.write_own(now, comm::HEARTBEAT_CONSUMER, sub, v)
    }
}
