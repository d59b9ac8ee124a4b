//! One interlocking computer on one rack: duocan's [`LogicalNetwork`] (dual-bus layer, CiA
//! 302-2 master, pair supervision, flying master) with the interlocking's application on top.
//!
//! Both computers run the same application (a hot standby): each follows the route schedule,
//! hears every answer and state change, and keeps the list of commands still unanswered. Only
//! the active one sends: each due command goes to the board its pair table names active, and
//! is sent again to the then-active board until it is answered (a board that took over after a
//! failure gets it then; a board that has it already answers without executing it twice). A
//! computer that takes over sends what is still unanswered.

use super::field::Kind;
use super::scheme::Scheme;
use duocan::cia305::{LssMasterEventKind, LssOutcome};
use duocan::frame::instant::earliest;
use duocan::machine::{BusLink, Device, PortRequest, PortStatus};
use duocan::od::DynamicDictionary;
use duocan::{Duration, Frame, Id, Instant, NodeId};
use duocan_redundancy::supervisor::pairs::PairsEvent;
use duocan_redundancy::{LogicalNetwork, Member, NetworkEvent, NetworkEventKind, SupervisorEvent};
use std::collections::{BTreeMap, VecDeque};
use std::rc::Rc;

/// The logical network object of one computer on one rack. Its master has room for an answer
/// and a state-change PDO per board mirrored (the master's default [`duocan::master::RPDOS`]).
pub type Net<S> = LogicalNetwork<DynamicDictionary, S>;

/// An unanswered command is sent again after this long.
pub const ANSWER_TIMEOUT: Duration = Duration::from_millis(30);
/// A command still unanswered this long after it was due is given up (and counted as lost).
pub const GIVE_UP: Duration = Duration::from_secs(2);

/// One command of the route schedule: at `at`, drive the device of `pair` to `code`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Route {
    /// When it is due.
    pub at: Instant,
    /// The pair (field device).
    pub pair: usize,
    /// The state commanded.
    pub code: u8,
}

/// Whether a mirrored PDO carries a board's answers or its state changes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Msg {
    Answer,
    Report,
}

/// What the interlocking did or heard.
#[derive(Clone, Debug, PartialEq)]
pub enum IlEvent {
    /// From the logical network (ports, pairs, master role, joins).
    Net(NetworkEvent),
    /// Command `seq` sent to `to` (attempt 1, 2, …).
    Sent {
        /// Command number (1-based index in the schedule).
        seq: u16,
        /// The board it went to.
        to: NodeId,
        /// Attempt.
        attempt: u8,
    },
    /// The answer to command `seq` from `from`.
    Answer {
        /// Command number.
        seq: u16,
        /// The board.
        from: NodeId,
    },
    /// State change `seq` of `from`.
    Report {
        /// The board.
        from: NodeId,
        /// Its number.
        seq: u16,
        /// The state.
        code: u8,
    },
    /// A payload that failed its check (CRC or layout) from `from`.
    Rejected {
        /// The board.
        from: NodeId,
    },
    /// Command `seq` gave up unanswered.
    GaveUp {
        /// Command number.
        seq: u16,
    },
}

#[derive(Clone, Copy, Debug)]
struct Pending {
    route: Route,
    sent: Option<Instant>,
    attempts: u8,
}

/// The interlocking application of one computer on one rack.
pub struct Interlocking<S: Scheme> {
    /// The logical network object.
    pub net: Net<S>,
    scheme: S,
    kind: Kind,
    schedule: Rc<Vec<Route>>,
    /// Next schedule entry not yet due.
    next: usize,
    pending: BTreeMap<u16, Pending>,
    /// Mirrored PDO `k + 1`: (board, message, identifier, local index).
    mirrors: Vec<(NodeId, Msg, Id, u16)>,
    events: VecDeque<IlEvent>,
}

impl<S: Scheme> Interlocking<S> {
    /// The application on `net`, mirroring the answers and state changes of `boards`, sending
    /// the commands of `schedule` due from `now` on.
    pub fn new(
        mut net: Net<S>,
        scheme: S,
        kind: Kind,
        boards: &[NodeId],
        schedule: Rc<Vec<Route>>,
        now: Instant,
    ) -> Result<Self, duocan::cia302::pdo_config::MirrorError> {
        let mut mirrors = Vec::new();
        for &b in boards {
            let msgs: &[Msg] = if kind == Kind::Track {
                &[Msg::Report]
            } else {
                &[Msg::Report, Msg::Answer]
            };
            for &m in msgs {
                let id = match m {
                    Msg::Report => scheme.report_id(b),
                    Msg::Answer => scheme.answer_id(b),
                };
                let index = 0x3000 + mirrors.len() as u16;
                let locals: Vec<Option<duocan::cia302::pdo_config::Local>> = scheme
                    .layout()
                    .iter()
                    .enumerate()
                    .map(|(i, (_, t))| {
                        Some(duocan::cia302::pdo_config::Local::new(
                            index,
                            i as u8 + 1,
                            *t,
                        ))
                    })
                    .collect();
                let remote =
                    duocan::cia302::pdo_config::PdoConfig::new(duocan::CobId::from_id(id), 255)
                        .mapping(&scheme.mapping())
                        .ok_or(duocan::cia302::pdo_config::MirrorError::NoMapping)?;
                net.mirror_tpdo(
                    now,
                    &remote,
                    &duocan::cia302::pdo_config::Mirror {
                        pdo: mirrors.len() as u16 + 1,
                        transmission_type: 255,
                        event_timer_ms: 0,
                        inhibit_100us: 0,
                        locals: &locals,
                    },
                )?;
                mirrors.push((b, m, id, index));
            }
        }
        // A computer that starts late joins the schedule where it is (its partner had the rest).
        let next = schedule.iter().take_while(|r| r.at < now).count();
        Ok(Interlocking {
            net,
            scheme,
            kind,
            schedule,
            next,
            pending: BTreeMap::new(),
            mirrors,
            events: VecDeque::new(),
        })
    }

    /// Commands due but not answered yet.
    pub fn unanswered(&self) -> usize {
        self.pending.len()
    }

    fn received(&mut self, pdo: u16) {
        let Some(&(board, msg, id, index)) = self.mirrors.get(pdo as usize - 1) else {
            return;
        };
        let mut bytes = Vec::with_capacity(8);
        for sub in 1..=self.scheme.layout().len() as u8 {
            if let Ok(b) = self.net.pdo_value(index, sub) {
                bytes.extend_from_slice(b);
            }
        }
        let Some((seq, code)) = self.scheme.decode(id, self.kind, &bytes) else {
            self.events.push_back(IlEvent::Rejected { from: board });
            return;
        };
        match msg {
            Msg::Report => self.events.push_back(IlEvent::Report {
                from: board,
                seq,
                code,
            }),
            Msg::Answer => {
                self.pending.remove(&seq);
                self.events.push_back(IlEvent::Answer { seq, from: board });
            }
        }
    }

    /// Moves the network's events into the application's, reading mirrored PDOs at once
    /// (before the next frame overwrites them).
    fn drain(&mut self) {
        while let Some(e) = self.net.poll_event() {
            use NetworkEventKind as K;
            match &e.kind {
                K::PdoReceived { pdo } => self.received(*pdo),
                K::Port { .. } | K::PairRole(_) | K::MasterRole(_) | K::NodeBooted { .. } => {
                    self.events.push_back(IlEvent::Net(e))
                }
                K::Other(duocan::machine::StationEvent::Machine(
                    SupervisorEvent::Pairs(PairsEvent::Joined { .. } | PairsEvent::Lost { .. })
                    | SupervisorEvent::Addressed(_),
                )) => self.events.push_back(IlEvent::Net(e)),
                // Of LSS, what a board without node-ID met: not the looks that found none.
                K::Other(duocan::machine::StationEvent::Machine(SupervisorEvent::Lss(l)))
                    if !matches!(
                        l.kind,
                        LssMasterEventKind::Done(LssOutcome::Identified(_, false))
                    ) =>
                {
                    self.events.push_back(IlEvent::Net(e))
                }
                _ => {}
            }
        }
    }

    fn active_board(&self, pair: usize) -> Option<NodeId> {
        let (_, p) = self.net.pairs().nth(pair)?;
        let m: Member = p.active?;
        Some(p.spec.node(m))
    }

    /// Schedules what is due and, if this computer commands, sends what is unanswered.
    fn commands(&mut self, now: Instant) {
        if self.pending.is_empty() && self.schedule.get(self.next).is_none_or(|r| r.at > now) {
            return;
        }
        while let Some(r) = self.schedule.get(self.next).filter(|r| r.at <= now) {
            let seq = self.next as u16 + 1;
            self.pending.insert(
                seq,
                Pending {
                    route: *r,
                    sent: None,
                    attempts: 0,
                },
            );
            self.next += 1;
        }
        let stale: Vec<u16> = self
            .pending
            .iter()
            .filter(|(_, p)| now >= p.route.at + GIVE_UP)
            .map(|(s, _)| *s)
            .collect();
        for seq in stale {
            self.pending.remove(&seq);
            self.events.push_back(IlEvent::GaveUp { seq });
        }
        let commanding = self.net.supervisor().flying_master().may_command(now);
        if !commanding {
            // A standby sends nothing; what it would have sent is sent afresh when it takes over.
            for p in self.pending.values_mut() {
                p.sent = None;
            }
            return;
        }
        let due: Vec<u16> = self
            .pending
            .iter()
            .filter(|(_, p)| p.sent.is_none_or(|t| now >= t + ANSWER_TIMEOUT))
            .map(|(s, _)| *s)
            .collect();
        for seq in due {
            let route = self.pending[&seq].route;
            let Some(to) = self.active_board(route.pair) else {
                // No board to send to (the pair lost both): wait for the next input.
                if let Some(p) = self.pending.get_mut(&seq) {
                    p.sent = None;
                }
                continue;
            };
            let frame = self.scheme.command(to, self.kind, seq, route.code);
            self.net.station_mut().link.send(now, &frame);
            let p = self.pending.get_mut(&seq).map(|p| {
                p.sent = Some(now);
                p.attempts = p.attempts.saturating_add(1);
                p.attempts
            });
            self.events.push_back(IlEvent::Sent {
                seq,
                to,
                attempt: p.unwrap_or(1),
            });
        }
    }

    fn next_deadline(&self) -> Option<Instant> {
        let mut t = self.schedule.get(self.next).map(|r| r.at);
        for p in self.pending.values() {
            t = earliest(t, Some(p.route.at + GIVE_UP));
            if let Some(s) = p.sent {
                t = earliest(t, Some(s + ANSWER_TIMEOUT));
            }
        }
        t
    }
}

impl<S: Scheme> Device for Interlocking<S> {
    type Event = IlEvent;

    fn port_count(&self) -> usize {
        2
    }
    fn handle_rx(&mut self, now: Instant, port: usize, frame: &Frame) {
        self.net.handle_rx(now, port, frame);
        self.drain();
        self.commands(now);
    }
    fn handle_rx_at(&mut self, now: Instant, port: usize, frame: &Frame, at: Instant) {
        self.net.handle_rx_at(now, port, frame, at);
        self.drain();
        self.commands(now);
    }
    fn handle_port_status(&mut self, now: Instant, port: usize, status: PortStatus) {
        self.net.handle_port_status(now, port, status);
        self.drain();
    }
    fn handle_timeout(&mut self, now: Instant) {
        self.net.handle_timeout(now);
        self.drain();
        self.commands(now);
    }
    fn poll_transmit(&mut self) -> Option<(usize, Frame)> {
        self.net.poll_transmit()
    }
    fn poll_port_request(&mut self) -> Option<(usize, PortRequest)> {
        self.net.poll_port_request()
    }
    fn poll_timeout(&self) -> Option<Instant> {
        earliest(self.net.poll_timeout(), self.next_deadline())
    }
    fn poll_event(&mut self) -> Option<IlEvent> {
        self.events.pop_front()
    }
}
