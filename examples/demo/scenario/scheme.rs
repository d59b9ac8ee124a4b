//! How the application messages of the demo travel on each kind of network.
//!
//! Three messages, each carrying a state code and a sequence number:
//!
//! | message | direction | CANopen predefined set | railway 29-bit profile |
//! |---|---|---|---|
//! | command | interlocking → board | RPDO1 of the board, 0x200 + node | command 0x012 at the board's I/O port 1 |
//! | answer | board → interlocking | TPDO2 of the board, 0x280 + node | command answer 0x010 at port 1 |
//! | state change | board → interlocking | TPDO1 of the board, 0x180 + node | state change 0x020 at port 1 |
//!
//! On CANopen the payload is `[code, seq lo, seq hi]`; on the railway profile it is the
//! profile's checked payload (object index of the device kind, sub-index 1, the same three
//! bytes, CRC over identifier and content). The masters receive answers and state changes as
//! RPDOs mirroring the boards' TPDOs, so the dual-bus layer's same-function merge delivers only
//! the active board's.

use super::field::Kind;
use duocan::od::{DataType, DynamicDictionary};
use duocan::pdo::MapEntry;
use duocan::profile::railway::{self, DeviceAddress, Payload, RailFunction, RailwayProfile};
use duocan::profile::{IdProfile, Predefined};
use duocan::sdo::Channel;
use duocan::{Frame, Id, NodeId};
use duocan_redundancy::FrameClassifier;

/// A network's identifier scheme, as the demo's boards and interlocking use it.
pub trait Scheme: IdProfile + FrameClassifier + Clone + 'static {
    /// What to call it.
    const NAME: &'static str;
    /// The command to `board`.
    fn command(&self, board: NodeId, kind: Kind, seq: u16, code: u8) -> Frame;
    /// The answer of `board` to command `seq`.
    fn answer(&self, board: NodeId, kind: Kind, seq: u16, code: u8) -> Frame;
    /// State change number `seq` of `board`.
    fn report(&self, board: NodeId, kind: Kind, seq: u16, code: u8) -> Frame;
    /// `(seq, code)` of a command addressed to `me`.
    fn parse_command(&self, me: NodeId, kind: Kind, f: &Frame) -> Option<(u16, u8)>;
    /// Identifier of `board`'s state changes.
    fn report_id(&self, board: NodeId) -> Id;
    /// Identifier of `board`'s answers.
    fn answer_id(&self, board: NodeId) -> Id;
    /// `(seq, code)` of an answer or state change from its identifier and payload bytes; `None`
    /// if it fails its check.
    fn decode(&self, id: Id, kind: Kind, bytes: &[u8]) -> Option<(u16, u8)>;
    /// How a master maps the payload into its dictionary: `(bits, type)` per entry.
    fn layout(&self) -> &'static [(u8, DataType)];
    /// The SDO channel of a node.
    fn channels(&self) -> fn(NodeId) -> Channel;
    /// Fits a node's dictionary to the scheme.
    fn fit_dictionary(&self, od: &mut DynamicDictionary, node: NodeId);
    /// The SYNC identifier.
    fn sync_id(&self) -> Id;

    /// The mapping of a board's TPDO carrying these payloads (the master's mirror needs it).
    fn mapping(&self) -> Vec<MapEntry> {
        self.layout()
            .iter()
            .enumerate()
            .map(|(i, (bits, _))| MapEntry::new(0x2000, i as u8 + 1, *bits))
            .collect()
    }
}

fn three(seq: u16, code: u8) -> [u8; 3] {
    let [lo, hi] = seq.to_le_bytes();
    [code, lo, hi]
}

fn pdo(base: u16, node: NodeId) -> Id {
    Id::Standard(base + node.raw() as u16)
}

impl Scheme for Predefined {
    const NAME: &'static str = "CANopen predefined connection set";
    fn command(&self, board: NodeId, _: Kind, seq: u16, code: u8) -> Frame {
        Frame::from_array(pdo(0x200, board), three(seq, code))
    }
    fn answer(&self, board: NodeId, _: Kind, seq: u16, code: u8) -> Frame {
        Frame::from_array(self.answer_id(board), three(seq, code))
    }
    fn report(&self, board: NodeId, _: Kind, seq: u16, code: u8) -> Frame {
        Frame::from_array(self.report_id(board), three(seq, code))
    }
    fn parse_command(&self, me: NodeId, _: Kind, f: &Frame) -> Option<(u16, u8)> {
        if f.is_remote() || f.id() != pdo(0x200, me) {
            return None;
        }
        match f.data() {
            [code, lo, hi] => Some((u16::from_le_bytes([*lo, *hi]), *code)),
            _ => None,
        }
    }
    fn report_id(&self, board: NodeId) -> Id {
        pdo(0x180, board)
    }
    fn answer_id(&self, board: NodeId) -> Id {
        pdo(0x280, board)
    }
    fn decode(&self, _: Id, _: Kind, bytes: &[u8]) -> Option<(u16, u8)> {
        match bytes {
            [code, lo, hi] => Some((u16::from_le_bytes([*lo, *hi]), *code)),
            _ => None,
        }
    }
    fn layout(&self) -> &'static [(u8, DataType)] {
        &[(8, DataType::Unsigned8), (16, DataType::Unsigned16)]
    }
    fn channels(&self) -> fn(NodeId) -> Channel {
        Channel::predefined
    }
    fn fit_dictionary(&self, _: &mut DynamicDictionary, _: NodeId) {}
    fn sync_id(&self) -> Id {
        Id::Standard(0x80)
    }
}

/// Where node `n` sits on a railway rack in row `ROW`: cabinet = high nibble of the node-ID,
/// layer 1, board = low nibble (masters 1 and 2 in cabinet 0, A boards 0x1n in cabinet 1, B
/// boards 0x2n in cabinet 2).
pub const fn address<const ROW: u8>(n: NodeId) -> DeviceAddress {
    DeviceAddress::board_at(ROW, n.raw() >> 4, 1, n.raw() & 0xF)
}

fn channel<const ROW: u8>(n: NodeId) -> Channel {
    let a = address::<ROW>(n);
    Channel {
        request: railway::id(RailFunction::SdoRequest, a),
        response: railway::id(RailFunction::SdoResponse, a),
    }
}

/// The profile of a railway rack in `row` holding `nodes`.
pub fn railway_profile(row: u8, nodes: impl IntoIterator<Item = NodeId>) -> RailwayProfile {
    let mut p = RailwayProfile::new();
    for n in nodes {
        let a = match row {
            2 => address::<2>(n),
            _ => address::<3>(n),
        };
        // Node-IDs below 0x80 give distinct in-range addresses: the table cannot refuse them.
        p.add(n, a).expect("room for every node of the rack");
    }
    p
}

impl Scheme for RailwayProfile {
    const NAME: &'static str = "railway 29-bit profile";
    fn command(&self, board: NodeId, kind: Kind, seq: u16, code: u8) -> Frame {
        self.message(RailFunction::Command, board, kind, seq, code)
    }
    fn answer(&self, board: NodeId, kind: Kind, seq: u16, code: u8) -> Frame {
        self.message(RailFunction::CommandAnswer, board, kind, seq, code)
    }
    fn report(&self, board: NodeId, kind: Kind, seq: u16, code: u8) -> Frame {
        self.message(RailFunction::StateChange, board, kind, seq, code)
    }
    fn parse_command(&self, me: NodeId, kind: Kind, f: &Frame) -> Option<(u16, u8)> {
        if f.is_remote() || Some(f.id()) != self.id(RailFunction::Command, me, 1) {
            return None;
        }
        Scheme::decode(self, f.id(), kind, f.data())
    }
    fn report_id(&self, board: NodeId) -> Id {
        self.id(RailFunction::StateChange, board, 1)
            .unwrap_or(Id::Extended(0))
    }
    fn answer_id(&self, board: NodeId) -> Id {
        self.id(RailFunction::CommandAnswer, board, 1)
            .unwrap_or(Id::Extended(0))
    }
    fn decode(&self, id: Id, kind: Kind, bytes: &[u8]) -> Option<(u16, u8)> {
        let p = Payload::decode_bytes(id, bytes).ok()?;
        match (p.index() == kind.object() && p.sub() == 1, p.data()) {
            (true, [code, lo, hi]) => Some((u16::from_le_bytes([*lo, *hi]), *code)),
            _ => None,
        }
    }
    fn layout(&self) -> &'static [(u8, DataType)] {
        &[(64, DataType::Unsigned64)]
    }
    fn channels(&self) -> fn(NodeId) -> Channel {
        match self.address(NodeId::must(1)).map(|a| a.row()) {
            Some(2) => channel::<2>,
            _ => channel::<3>,
        }
    }
    fn sync_id(&self) -> Id {
        RailwayProfile::SYNC
    }
    fn fit_dictionary(&self, od: &mut DynamicDictionary, node: NodeId) {
        if let Some(a) = self.address(node) {
            for def in RailwayProfile::comm_objects(a) {
                od.upsert(def);
            }
        }
    }
}

trait Message {
    fn message(&self, f: RailFunction, board: NodeId, kind: Kind, seq: u16, code: u8) -> Frame;
}

impl Message for RailwayProfile {
    fn message(&self, f: RailFunction, board: NodeId, kind: Kind, seq: u16, code: u8) -> Frame {
        let id = self.id(f, board, 1).unwrap_or(Id::Extended(0));
        // Three data bytes always fit the payload.
        Payload::new(kind.object(), 1, &three(seq, code))
            .map(|p| p.encode(id))
            .unwrap_or_else(|_| Frame::from_array(id, [0u8; 0]))
    }
}
