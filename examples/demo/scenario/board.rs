//! An I/O board: a standard duocan node (heartbeat, NMT, SDO server, configured by the master)
//! with the board's firmware on top: while operational (the active member of its pair) it
//! executes the interlocking's commands on its field device, answers them, and reports every
//! state change of the device; while pre-operational (standby) it only listens.

use super::field::{Kind, Shared};
use super::scheme::Scheme;
use duocan::eds::Description;
use duocan::frame::instant::earliest;
use duocan::machine::Machine;
use duocan::node::NodeEventKind;
use duocan::od::DynamicDictionary;
use duocan::{Frame, Instant, NmtState, Node, NodeConfig, NodeId, Station};
use duocan_redundancy::{DualBus, DualBusConfig, LinkMode};
use std::collections::VecDeque;

/// What a board did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BoardEvent {
    /// Its NMT state changed.
    State(NmtState),
    /// It executed command `seq` (first reception).
    Executed {
        /// The command's number.
        seq: u16,
        /// The state commanded.
        code: u8,
    },
    /// It sent an answer to command `seq`.
    Answered {
        /// The command's number.
        seq: u16,
    },
    /// It sent state change number `seq`.
    Reported {
        /// Its number.
        seq: u16,
        /// The state.
        code: u8,
    },
}

/// Commands a board remembers having executed (repeats of them are answered, not executed).
const REMEMBERED: usize = 64;

/// The firmware of one board.
pub struct Board<S: Scheme> {
    node: Node<DynamicDictionary, S>,
    scheme: S,
    id: NodeId,
    field: Shared,
    /// Up to when the field has been looked at.
    checked: Instant,
    operational: bool,
    last: Option<u8>,
    seq: u16,
    executed: VecDeque<u16>,
    out: VecDeque<Frame>,
    events: VecDeque<BoardEvent>,
}

/// A board on both buses.
pub type BoardDev<S> = Station<DualBus<S>, Board<S>>;

/// A board `id` driving `field`, its dictionary built from the boards' EDS `eds`, powered on
/// at `now` (it sends its boot-up and waits for the master to configure it).
pub fn board<S: Scheme>(
    scheme: &S,
    eds: &Description,
    id: NodeId,
    field: Shared,
    guard: duocan::Duration,
    now: Instant,
) -> BoardDev<S> {
    let mut od = eds.dictionary(id.raw());
    scheme.fit_dictionary(&mut od, id);
    let mut node = Node::with_profile(NodeConfig::slave(id), od, scheme.clone());
    node.boot(now);
    let link = DualBus::with_classifier(
        DualBusConfig::with_guard_period(LinkMode::ActiveActive, guard),
        scheme.clone(),
    );
    Station::new(
        link,
        Board {
            node,
            scheme: scheme.clone(),
            id,
            field,
            checked: now,
            operational: false,
            last: None,
            seq: 0,
            executed: VecDeque::new(),
            out: VecDeque::new(),
            events: VecDeque::new(),
        },
    )
}

impl<S: Scheme> Board<S> {
    /// The board's NMT state.
    pub fn state(&self) -> NmtState {
        self.node.nmt_state()
    }
    /// The board's dictionary.
    pub fn od(&self) -> &DynamicDictionary {
        self.node.od()
    }
    fn kind(&self) -> Kind {
        self.field.borrow().kind
    }

    fn execute(&mut self, now: Instant, seq: u16, code: u8) {
        if !self.executed.contains(&seq) {
            if self.executed.len() == REMEMBERED {
                self.executed.pop_front();
            }
            self.executed.push_back(seq);
            self.field.borrow_mut().command(now, code);
            self.events.push_back(BoardEvent::Executed { seq, code });
        }
        let kind = self.kind();
        self.out
            .push_back(self.scheme.answer(self.id, kind, seq, code));
        self.events.push_back(BoardEvent::Answered { seq });
    }

    /// Reports the field device's state if it changed, and always on becoming operational
    /// (the interlocking learns the state from the board that just took over).
    fn check(&mut self, now: Instant) {
        let op = self.node.nmt_state() == NmtState::Operational;
        let code = self.field.borrow().code_at(now);
        if op && (!self.operational || self.last != Some(code)) {
            self.seq = self.seq.wrapping_add(1);
            let kind = self.kind();
            self.out
                .push_back(self.scheme.report(self.id, kind, self.seq, code));
            self.events.push_back(BoardEvent::Reported {
                seq: self.seq,
                code,
            });
            self.last = Some(code);
        }
        self.operational = op;
        self.checked = now;
    }
}

impl<S: Scheme> Machine for Board<S> {
    type Event = BoardEvent;
    type LinkCommand = std::convert::Infallible;

    fn handle_frame(&mut self, now: Instant, frame: &Frame) {
        self.node.handle_frame(now, frame);
        if self.node.nmt_state() == NmtState::Operational {
            let kind = self.kind();
            if let Some((seq, code)) = self.scheme.parse_command(self.id, kind, frame) {
                self.execute(now, seq, code);
            }
        }
        self.check(now);
    }
    fn handle_timeout(&mut self, now: Instant) {
        self.node.handle_timeout(now);
        self.check(now);
    }
    fn poll_transmit(&mut self) -> Option<Frame> {
        self.node.poll_transmit().or_else(|| self.out.pop_front())
    }
    fn poll_timeout(&self) -> Option<Instant> {
        earliest(
            self.node.poll_timeout(),
            self.field.borrow().next_after(self.checked),
        )
    }
    fn poll_event(&mut self) -> Option<BoardEvent> {
        if let Some(e) = self.events.pop_front() {
            return Some(e);
        }
        while let Some(e) = self.node.poll_event() {
            if let NodeEventKind::StateChanged { to, .. } = e.kind {
                return Some(BoardEvent::State(to));
            }
        }
        None
    }
}
