//! The frame decoder: every frame as one CANopen-aware line, as `candump` with Wireshark's
//! CANopen dissector would print it ("node 5 SDO upload 0x1018:01 = 0x00000123").
//!
//! [`Decoder::decode`] takes one frame and gives a [`DecodedFrame`]: a typed value whose fields
//! are public (for a tool that writes JSON or filters by [`Kind`] and node) and whose `Display`
//! is the one-line human text.
//!
//! # The rule
//!
//! An identifier is read in this order:
//!
//! 1. a PDO layout the decoder was given ([`Decoder::add_pdo`], [`Decoder::describe`]): that
//!    PDO, its values by name and type;
//! 2. an 11-bit identifier: NMT (0x000), SYNC (0x080), TIME (0x100), the CiA 302-2
//!    flying-master frames (0x71–0x76), LSS (0x7E4 from a slave, 0x7E5 from the master), then
//!    the predefined connection set: EMCY, TPDO1–4 and RPDO1–4 (raw bytes), SDO (0x580+n from
//!    the server, 0x600+n from the client), heartbeat, boot-up and guarding (0x700+n);
//! 3. a 29-bit identifier by the railway profile's layout (a 9-bit function code above a
//!    20-bit row · cabinet · layer · board · port address, see
//!    [`profile::railway`](crate::profile::railway)); the node comes from a profile table given
//!    with [`Decoder::with_railway`]. Every 29-bit identifier whose function code is a railway
//!    one is read so: on a network that mixes another 29-bit scheme in, those frames print as
//!    railway frames;
//! 4. anything else is [`DecodedFrame::Unknown`]: `unknown 0x123 [3] 01 02 03`.
//!
//! A frame too short (or too long) for its kind, a remote frame where data belongs, a value the
//! standard does not define: a [`DecodedFrame::Malformed`] line that says so. Nothing panics.
//!
//! SDO frames carry their object (index:sub) only in the initiate frames; segments, block
//! sub-blocks and the end frames belong to the transfer started on that node's channel. The
//! decoder keeps, per node, the transfer in progress, so a segment prints as
//! `node 5 SDO upload 0x1008:00 segment 3 (7 bytes)` and the last one with the total. A block
//! segment carries no command specifier at all, so whether a frame is one is only known from
//! that context. Without it (a capture that starts mid-transfer) the command specifier is
//! decoded as it stands, and the line says the transfer is unknown.
//!
//! # Memory
//!
//! Bounded by construction: one small record per node-ID (127 of them, at most 4 KiB in all)
//! for the SDO transfers, replaced by the next initiate frame. The PDO layouts grow only with what
//! the caller gives ([`Decoder::add_pdo`], [`Decoder::describe`]), never with the traffic; a
//! decoded line owns its bytes (at most 8; 64 for a PDO in a CAN FD frame,
//! [`Decoder::decode_fd`]) and names.
//!
//! # Order
//!
//! Frames are decoded in the order given; the per-node SDO context assumes that order is the
//! bus's (a capture of one bus, or the merged logical bus). Two buses' captures interleaved
//! copy by copy show each SDO frame twice, and the second copy of a segment counts as the next
//! segment: decode one bus or the merged stream.
//!
//! ```
//! use duocan::capture::decode::{Decoder, DecodedFrame, Kind};
//! use duocan::{Frame, Id};
//!
//! let mut dec = Decoder::new();
//! let lines: Vec<String> = [
//!     Frame::from_array(Id::Standard(0x000), [0x01, 0x05]),
//!     Frame::from_array(Id::Standard(0x705), [0x05]),
//!     Frame::from_array(Id::Standard(0x605), [0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0]),
//!     Frame::from_array(Id::Standard(0x585), [0x43, 0x18, 0x10, 0x01, 0x23, 0x01, 0, 0]),
//!     Frame::from_array(Id::Standard(0x085), [0x30, 0x81, 0x11, 0, 0, 0, 0, 0]),
//!     Frame::from_array(Id::Standard(0x123), [1, 2, 3]),
//! ]
//! .iter()
//! .map(|f| dec.decode(f).to_string())
//! .collect();
//! assert_eq!(
//!     lines,
//!     [
//!         "NMT start node 5",
//!         "node 5 heartbeat operational",
//!         "node 5 SDO upload 0x1018:01 request",
//!         "node 5 SDO upload 0x1018:01 = 0x00000123",
//!         "node 5 EMCY 0x8130 life guard or heartbeat error, register 0x11, data 00 00 00 00 00",
//!         "unknown 0x123 [3] 01 02 03",
//!     ]
//! );
//! // A heartbeat of two bytes: said, not guessed.
//! let bad = dec.decode(&Frame::from_array(Id::Standard(0x705), [0x05, 0x00]));
//! assert_eq!(bad.kind(), Kind::Heartbeat);
//! assert_eq!(bad.to_string(), "node 5 heartbeat: 2 bytes, a heartbeat has 1 (05 00)");
//! assert!(matches!(bad, DecodedFrame::Malformed { .. }));
//! ```

mod frames;
mod kind;
mod pdo;
mod railway;
mod sdo;
mod services;

pub use frames::{DecodedFrame, RailPayload};
pub use kind::{FlyingMasterFrame, Kind};
pub use pdo::{FieldValue, PdoField, PdoFieldDef, PdoInfo, PdoLayout};
pub use sdo::{SdoInfo, SdoService, SdoSide, SdoStep};

use crate::cia301::pdo::Dir;
use crate::eds::Description;
use crate::frame::cob_id::{predefined, NodeId};
use crate::frame::{FdFrame, Frame, Id};
use crate::profile::railway::RailwayProfile;
use std::collections::BTreeMap;

/// LSS frames from a slave (CiA 305).
pub const LSS_RESPONSE: u16 = 0x7E4;
/// LSS frames from the master (CiA 305).
pub const LSS_REQUEST: u16 = 0x7E5;

/// Turns frames into [`DecodedFrame`]s, keeping the SDO transfer in progress per node.
#[derive(Clone, Debug)]
pub struct Decoder {
    sdo: sdo::Tracks,
    pdos: BTreeMap<Id, PdoLayout>,
    railway: RailwayProfile,
}

impl Default for Decoder {
    fn default() -> Self {
        Self::new()
    }
}

impl Decoder {
    /// A decoder without PDO layouts and with an empty railway table.
    #[must_use]
    pub fn new() -> Self {
        Decoder {
            sdo: sdo::Tracks::new(),
            pdos: BTreeMap::new(),
            railway: RailwayProfile::new(),
        }
    }

    /// The railway table that names the node at each board address of 29-bit frames.
    #[must_use]
    pub fn with_railway(mut self, profile: RailwayProfile) -> Self {
        self.railway = profile;
        self
    }

    /// Decodes frames with identifier `id` as the PDO `layout` (replacing a layout `id` had).
    pub fn add_pdo(&mut self, id: Id, layout: PdoLayout) {
        self.pdos.insert(id, layout);
    }

    /// The PDO layout frames with identifier `id` are decoded with.
    #[must_use]
    pub fn pdo(&self, id: Id) -> Option<&PdoLayout> {
        self.pdos.get(&id)
    }

    /// Learns node `node`'s PDOs from its description: each TPDO (0x1800.. COB-ID, 0x1A00..
    /// mapping) and RPDO (0x1400.., 0x1600..) with a non-empty mapping, from the DCF's values
    /// or the EDS defaults, with the mapped entries' names and types. A PDO without a COB-ID
    /// entry gets its predefined one (PDOs 1–4). Returns how many PDOs it learned.
    pub fn describe(&mut self, node: NodeId, desc: &Description) -> usize {
        let layouts = pdo::from_description(node, desc);
        let n = layouts.len();
        for (id, layout) in layouts {
            self.add_pdo(id, layout);
        }
        n
    }

    /// Forgets every SDO transfer in progress (the next segments decode without context).
    pub fn forget_transfers(&mut self) {
        self.sdo = sdo::Tracks::new();
    }

    /// What `frame` is, as one line.
    pub fn decode(&mut self, frame: &Frame) -> DecodedFrame {
        if let Some(layout) = self.pdos.get(&frame.id()) {
            return pdo::decode(layout, frame);
        }
        match frame.id() {
            Id::Standard(raw) => self.standard(raw, frame),
            Id::Extended(_) => railway::decode(&self.railway, &mut self.sdo, frame),
        }
    }

    /// What a CAN FD `frame` is, if it is a PDO (a CANopen FD network's PDOs are up to 64
    /// bytes): by a layout the decoder was given (its values by name and type, read at their
    /// bit offsets over the whole frame), else a TPDO or RPDO on its predefined COB-ID (the
    /// bytes). `None` for any other CAN FD frame (USDO, EMCY in its FD form: not decoded here).
    ///
    /// ```
    /// use duocan::capture::decode::{Decoder, PdoFieldDef, PdoLayout};
    /// use duocan::pdo::{Dir, MapEntry};
    /// use duocan::{FdFrame, Id, NodeId};
    ///
    /// let mut dec = Decoder::new();
    /// // TPDO1 of node 5: eight UNSIGNED64, 64 bytes.
    /// let fields = (0..8).map(|k| PdoFieldDef::new(MapEntry::new(0x6100 + k, 0, 64))).collect();
    /// let layout = PdoLayout { node: Some(NodeId::must(5)), dir: Dir::Transmit, number: 1, fields };
    /// dec.add_pdo(Id::Standard(0x185), layout);
    /// let mut data = [0u8; 64];
    /// data[56] = 7;
    /// let d = dec.decode_fd(&FdFrame::new(Id::Standard(0x185), &data).unwrap()).unwrap();
    /// assert!(d.to_string().ends_with("0x6107:00 = 7"));
    /// ```
    pub fn decode_fd(&mut self, frame: &FdFrame) -> Option<DecodedFrame> {
        if let Some(layout) = self.pdos.get(&frame.id()) {
            return Some(pdo::decode_fd(layout, frame));
        }
        match predefined::classify(frame.id()) {
            predefined::Function::Tpdo(k, node) => Some(pdo::raw_fd(node, Dir::Transmit, k, frame)),
            predefined::Function::Rpdo(k, node) => Some(pdo::raw_fd(node, Dir::Receive, k, frame)),
            _ => None,
        }
    }

    fn standard(&mut self, raw: u16, frame: &Frame) -> DecodedFrame {
        match raw {
            predefined::NMT => return services::nmt(frame),
            predefined::SYNC => return services::sync(frame),
            predefined::TIME => return services::time(frame),
            LSS_RESPONSE | LSS_REQUEST => return services::lss(raw == LSS_REQUEST, frame),
            _ => {}
        }
        if let Some(fm) = FlyingMasterFrame::from_cob_id(raw) {
            return services::flying_master(fm, frame);
        }
        match predefined::classify(frame.id()) {
            predefined::Function::Emcy(node) => services::emcy(node, frame),
            predefined::Function::Tpdo(k, node) => pdo::raw(node, Dir::Transmit, k, frame),
            predefined::Function::Rpdo(k, node) => pdo::raw(node, Dir::Receive, k, frame),
            predefined::Function::SdoTx(node) => self.sdo.decode(node, SdoSide::Server, frame),
            predefined::Function::SdoRx(node) => self.sdo.decode(node, SdoSide::Client, frame),
            predefined::Function::ErrorControl(node) => services::error_control(node, frame),
            _ => DecodedFrame::Unknown(*frame),
        }
    }
}

#[cfg(test)]
mod tests;
