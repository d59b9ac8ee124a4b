//! An I/O board: a standard duocan node (heartbeat, NMT, SDO server, configured by the master)
//! with the board's firmware on top: while operational (the active member of its pair) it
//! executes the interlocking's commands on its field device, answers them, and reports every
//! state change of the device; while pre-operational (standby) it only listens.
//!
//! Every board has an LSS slave (CiA 305, [`LssNode`]) with its identity (0x1018). A board of
//! the station has its node-ID from the start; a spare from the shelf ([`spare`]) has none
//! (0xFF): it sends nothing but LSS answers until the active master gives it its slot's
//! node-ID, then it boots like any board.

use super::field::{Kind, Shared};
use super::scheme::Scheme;
use duocan::cia305::codec::UNCONFIGURED;
use duocan::cia305::{LssAddress, LssSlave, NoMedium};
use duocan::eds::Description;
use duocan::frame::instant::earliest;
use duocan::machine::Machine;
use duocan::node::{LssNode, NodeEventKind};
use duocan::od::{comm, Access, DynamicDictionary, ObjectDef, ObjectDictionary, ObjectType};
use duocan::{Frame, Instant, NmtState, Node, NodeConfig, NodeId, Station};
use duocan_redundancy::{DualBus, DualBusConfig, LinkMode};
use std::collections::VecDeque;
use std::rc::Rc;

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

/// Starts a board's firmware with the node-ID it has (from the start, or from LSS) at `now`.
pub type Firmware<S> = Box<dyn FnMut(NodeId, Instant) -> Board<S>>;

/// A board's controller: its LSS slave, and its firmware once it has a node-ID.
pub type Controller<S> = LssNode<Board<S>, Firmware<S>, NoMedium>;

/// A board on both buses.
pub type BoardDev<S> = Station<DualBus<S>, Controller<S>>;

/// What a board is made of: the rack's scheme, the boards' EDS and the field device it drives.
#[derive(Clone)]
pub struct Parts<S: Scheme> {
    /// The rack's identifier scheme.
    pub scheme: S,
    /// The boards' EDS: the dictionary and the identity.
    pub eds: Rc<Description>,
    /// The field device.
    pub field: Shared,
    /// The dual-bus layer's guard period.
    pub guard: duocan::Duration,
}

/// A board `id` of the station, powered on at `now`: it sends its boot-up and waits for the
/// master to configure it. Its serial number is the one the EDS gives it.
pub fn board<S: Scheme>(parts: &Parts<S>, id: NodeId, now: Instant) -> BoardDev<S> {
    let serial = parts
        .eds
        .dictionary(id.raw())
        .get_u32(comm::IDENTITY, 4)
        .unwrap_or(0);
    device(parts, serial, id.raw(), now)
}

/// A spare board with serial number `serial`, powered on at `now` without node-ID: it waits
/// for an LSS master to give it one.
pub fn spare<S: Scheme>(parts: &Parts<S>, serial: u32, now: Instant) -> BoardDev<S> {
    device(parts, serial, UNCONFIGURED, now)
}

fn device<S: Scheme>(parts: &Parts<S>, serial: u32, node: u8, now: Instant) -> BoardDev<S> {
    let info = &parts.eds.device_info;
    let address = LssAddress {
        vendor: info.vendor_number.unwrap_or(0),
        product: info.product_number.unwrap_or(0),
        revision: info.revision_number.unwrap_or(0),
        serial,
    };
    let p = parts.clone();
    let firmware: Firmware<S> = Box::new(move |id, at| firmware(&p, id, serial, at));
    let link = DualBus::with_classifier(
        DualBusConfig::with_guard_period(LinkMode::ActiveActive, parts.guard),
        parts.scheme.clone(),
    );
    let lss = LssSlave::new(address, node);
    Station::new(link, LssNode::new(now, lss, firmware))
}

/// The firmware of board `id` with serial number `serial`, booted at `now`.
fn firmware<S: Scheme>(parts: &Parts<S>, id: NodeId, serial: u32, now: Instant) -> Board<S> {
    let mut od = parts.eds.dictionary(id.raw());
    // The board's own serial number, which its LSS slave reports too.
    od.upsert(
        ObjectDef::u32(comm::IDENTITY, 4, Access::Const, serial)
            .object_type(ObjectType::Record)
            .named("Serial number"),
    );
    parts.scheme.fit_dictionary(&mut od, id);
    let mut node = Node::with_profile(NodeConfig::slave(id), od, parts.scheme.clone());
    node.boot(now);
    Board {
        node,
        scheme: parts.scheme.clone(),
        id,
        field: parts.field.clone(),
        checked: now,
        operational: false,
        last: None,
        seq: 0,
        executed: VecDeque::new(),
        out: VecDeque::new(),
        events: VecDeque::new(),
    }
}

impl<S: Scheme> Board<S> {
    /// The board's NMT state.
    pub fn state(&self) -> NmtState {
        self.node.nmt_state()
    }
    /// The board's application changes its NMT state (a self-test failed, its error behaviour
    /// acted): the node announces it at once.
    pub fn set_state(&mut self, now: Instant, state: NmtState) {
        self.node.set_nmt_state(now, state);
        self.check(now);
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
