//! Network management: NMT states and commands, which services run in which state, the frames
//! of module control, and the master's view of every node's state.

use crate::frame::cob_id::NodeId;
use crate::frame::instant::{Duration, Instant};
use crate::frame::Malformed;
use crate::frame::{Frame, Id};
use core::fmt;

/// NMT state of a node, with the byte heartbeats and guarding answers carry.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum NmtState {
    /// Initialising; the boot-up message carries this state (0).
    Initialising,
    /// Stopped (4): only NMT and error control.
    Stopped,
    /// Operational (5): everything.
    Operational,
    /// Pre-operational (127): everything but PDO.
    PreOperational,
}

impl NmtState {
    /// The state byte of heartbeat and guarding frames (toggle bit excluded).
    pub const fn code(self) -> u8 {
        match self {
            NmtState::Initialising => 0x00,
            NmtState::Stopped => 0x04,
            NmtState::Operational => 0x05,
            NmtState::PreOperational => 0x7F,
        }
    }
    /// Decodes a state byte (toggle bit must be stripped first).
    pub const fn from_code(code: u8) -> Option<NmtState> {
        match code {
            0x00 => Some(NmtState::Initialising),
            0x04 => Some(NmtState::Stopped),
            0x05 => Some(NmtState::Operational),
            0x7F => Some(NmtState::PreOperational),
            _ => None,
        }
    }
    /// The services CiA 301 allows in this state.
    pub const fn services(self) -> Services {
        match self {
            NmtState::Initialising => Services::NONE,
            NmtState::Stopped => Services {
                sdo: false,
                pdo: false,
                sync: false,
                time: false,
                emcy: false,
                error_control: true,
            },
            NmtState::PreOperational => Services {
                sdo: true,
                pdo: false,
                sync: true,
                time: true,
                emcy: true,
                error_control: true,
            },
            NmtState::Operational => Services {
                sdo: true,
                pdo: true,
                sync: true,
                time: true,
                emcy: true,
                error_control: true,
            },
        }
    }
}

impl fmt::Display for NmtState {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            NmtState::Initialising => "initialising",
            NmtState::Stopped => "stopped",
            NmtState::Operational => "operational",
            NmtState::PreOperational => "pre-operational",
        })
    }
}

/// Which communication services run in a state (NMT itself always runs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Services {
    /// SDO.
    pub sdo: bool,
    /// PDO.
    pub pdo: bool,
    /// SYNC production and consumption.
    pub sync: bool,
    /// TIME production and consumption.
    pub time: bool,
    /// EMCY production and consumption.
    pub emcy: bool,
    /// Heartbeat, boot-up and node/life guarding.
    pub error_control: bool,
}

impl Services {
    const NONE: Services = Services {
        sdo: false,
        pdo: false,
        sync: false,
        time: false,
        emcy: false,
        error_control: false,
    };
}

/// NMT module-control command specifiers.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum NmtCommand {
    /// Start remote node (0x01).
    Start,
    /// Stop remote node (0x02).
    Stop,
    /// Enter pre-operational (0x80).
    EnterPreOperational,
    /// Reset node (0x81).
    ResetNode,
    /// Reset communication (0x82).
    ResetCommunication,
}

impl NmtCommand {
    /// Command specifier byte.
    pub const fn code(self) -> u8 {
        match self {
            NmtCommand::Start => 0x01,
            NmtCommand::Stop => 0x02,
            NmtCommand::EnterPreOperational => 0x80,
            NmtCommand::ResetNode => 0x81,
            NmtCommand::ResetCommunication => 0x82,
        }
    }
    /// Decodes a command specifier.
    pub const fn from_code(cs: u8) -> Option<NmtCommand> {
        match cs {
            0x01 => Some(NmtCommand::Start),
            0x02 => Some(NmtCommand::Stop),
            0x80 => Some(NmtCommand::EnterPreOperational),
            0x81 => Some(NmtCommand::ResetNode),
            0x82 => Some(NmtCommand::ResetCommunication),
            _ => None,
        }
    }
    /// The state a node is in after obeying the command (resets end in pre-operational).
    pub const fn resulting_state(self) -> NmtState {
        match self {
            NmtCommand::Start => NmtState::Operational,
            NmtCommand::Stop => NmtState::Stopped,
            _ => NmtState::PreOperational,
        }
    }
}

impl fmt::Display for NmtCommand {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            NmtCommand::Start => "start",
            NmtCommand::Stop => "stop",
            NmtCommand::EnterPreOperational => "enter pre-operational",
            NmtCommand::ResetNode => "reset node",
            NmtCommand::ResetCommunication => "reset communication",
        })
    }
}

/// Which nodes an NMT command addresses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum NmtTarget {
    /// Node-ID 0: every node.
    All,
    /// One node.
    Node(NodeId),
}

impl NmtTarget {
    /// The node-ID byte of the command (0 for all).
    pub const fn code(self) -> u8 {
        match self {
            NmtTarget::All => 0,
            NmtTarget::Node(n) => n.raw(),
        }
    }
    /// True if the command addresses `node`.
    pub fn includes(self, node: NodeId) -> bool {
        match self {
            NmtTarget::All => true,
            NmtTarget::Node(n) => n == node,
        }
    }
}

impl From<NodeId> for NmtTarget {
    fn from(n: NodeId) -> Self {
        NmtTarget::Node(n)
    }
}

/// The NMT module-control frame for `cmd` to `target` on identifier `id`.
pub fn command_frame(id: Id, cmd: NmtCommand, target: NmtTarget) -> Frame {
    Frame::from_array(id, [cmd.code(), target.code()])
}

/// Decodes an NMT module-control frame: `(command, addressed node-ID byte)`.
pub fn parse_command(frame: &Frame) -> Result<(NmtCommand, u8), Malformed> {
    if frame.is_remote() {
        return Err(Malformed::UnexpectedRemote);
    }
    match frame.data() {
        [cs, node] => NmtCommand::from_code(*cs)
            .map(|c| (c, *node))
            .ok_or(Malformed::BadValue { value: *cs }),
        d => Err(Malformed::WrongLength {
            expected: 2,
            got: d.len() as u8,
        }),
    }
}

/// Decodes an error-control data frame (boot-up, heartbeat, guarding answer): the state and the
/// toggle bit.
pub fn parse_error_control(frame: &Frame) -> Result<(NmtState, bool), Malformed> {
    if frame.is_remote() {
        return Err(Malformed::UnexpectedRemote);
    }
    match frame.data() {
        [b] => NmtState::from_code(b & 0x7F)
            .map(|s| (s, b & 0x80 != 0))
            .ok_or(Malformed::BadValue { value: *b }),
        d => Err(Malformed::WrongLength {
            expected: 1,
            got: d.len() as u8,
        }),
    }
}

/// What the master knows of one node.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct NodeView {
    /// Last state heard (boot-up, heartbeat or guarding answer).
    pub state: NmtState,
    /// When it was heard.
    pub seen: Instant,
}

/// The master's table of every node's last known state, fed by boot-ups, heartbeats and
/// guarding answers from all nodes (configured as consumers or not).
#[derive(Clone, Debug)]
pub struct NodeTable {
    /// State code per node-ID; `UNKNOWN` when never heard (kept apart from the times so a
    /// no_std node's table stays small).
    states: [u8; 128],
    seen: [Instant; 128],
}

const UNKNOWN: u8 = 0xFF;

impl Default for NodeTable {
    fn default() -> Self {
        NodeTable {
            states: [UNKNOWN; 128],
            seen: [Instant::ZERO; 128],
        }
    }
}

impl NodeTable {
    /// Records a state heard at `now`; returns the previous state if it changed (or `None` for the
    /// first sighting, reported as a change from nothing).
    pub fn observe(
        &mut self,
        node: NodeId,
        state: NmtState,
        now: Instant,
    ) -> Option<Option<NmtState>> {
        let i = node.raw() as usize;
        let prev = NmtState::from_code(self.states[i]);
        self.states[i] = state.code();
        self.seen[i] = now;
        if prev == Some(state) {
            None
        } else {
            Some(prev)
        }
    }
    /// The caller's clock stepped back `by` (the clock contract, [`crate::frame::instant`]).
    pub fn step_back(&mut self, by: Duration) {
        for t in self.seen.iter_mut() {
            *t = *t - by;
        }
    }
    /// Last known view of a node.
    pub fn get(&self, node: NodeId) -> Option<NodeView> {
        let i = node.raw() as usize;
        NmtState::from_code(self.states[i]).map(|state| NodeView {
            state,
            seen: self.seen[i],
        })
    }
    /// Forgets a node (e.g. after the master reset it and awaits its boot-up).
    pub fn forget(&mut self, node: NodeId) {
        self.states[node.raw() as usize] = UNKNOWN;
    }
    /// Every node with a known state.
    pub fn iter(&self) -> impl Iterator<Item = (NodeId, NodeView)> + '_ {
        (1..=127u8).filter_map(|i| {
            let n = NodeId::new(i)?;
            Some((n, self.get(n)?))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn command_frames_byte_for_byte() {
        let f = command_frame(
            Id::Standard(0),
            NmtCommand::Start,
            NmtTarget::Node(NodeId::must(5)),
        );
        assert_eq!(f.data(), &[0x01, 0x05]);
        let f = command_frame(
            Id::Standard(0),
            NmtCommand::ResetCommunication,
            NmtTarget::All,
        );
        assert_eq!(f.data(), &[0x82, 0x00]);
        assert_eq!(parse_command(&f), Ok((NmtCommand::ResetCommunication, 0)));
    }

    #[test]
    fn bad_nmt_frames_are_reported() {
        let short = Frame::new(Id::Standard(0), &[1]).unwrap();
        assert_eq!(
            parse_command(&short),
            Err(Malformed::WrongLength {
                expected: 2,
                got: 1
            })
        );
        let rtr = Frame::remote(Id::Standard(0), 2).unwrap();
        assert_eq!(parse_command(&rtr), Err(Malformed::UnexpectedRemote));
        let bad = Frame::new(Id::Standard(0), &[0x03, 0]).unwrap();
        assert_eq!(parse_command(&bad), Err(Malformed::BadValue { value: 3 }));
    }

    #[test]
    fn error_control_decoding() {
        let f = Frame::new(Id::Standard(0x705), &[0x85]).unwrap();
        assert_eq!(parse_error_control(&f), Ok((NmtState::Operational, true)));
        let f = Frame::new(Id::Standard(0x705), &[0x33]).unwrap();
        assert_eq!(
            parse_error_control(&f),
            Err(Malformed::BadValue { value: 0x33 })
        );
    }

    #[test]
    fn services_per_state_follow_cia_301() {
        assert!(!NmtState::PreOperational.services().pdo);
        assert!(NmtState::PreOperational.services().sdo);
        assert!(!NmtState::Stopped.services().sdo);
        assert!(NmtState::Stopped.services().error_control);
        assert!(NmtState::Operational.services().pdo);
    }

    #[test]
    fn node_table_reports_changes_only() {
        let mut t = NodeTable::default();
        let n = NodeId::must(3);
        assert_eq!(
            t.observe(n, NmtState::Initialising, Instant::ZERO),
            Some(None)
        );
        assert_eq!(
            t.observe(n, NmtState::PreOperational, Instant::ZERO),
            Some(Some(NmtState::Initialising))
        );
        assert_eq!(
            t.observe(n, NmtState::PreOperational, Instant::from_millis(1)),
            None
        );
        assert_eq!(t.iter().count(), 1);
    }
}
