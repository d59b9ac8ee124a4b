//! The railway identifier profile: the 29-bit scheme (CAN 2.0B) of a published redundant railway-depot network as an [`IdProfile`].
//!
//! An identifier is a 9-bit [`RailFunction`] code above a 20-bit [`DeviceAddress`] (row · cabinet ·
//! layer · board · port). A node is a board; [`RailwayProfile`] holds the bounded table that
//! says which node-ID sits at which board address, and maps the services whose identifiers
//! CiA 301 fixes:
//!
//! | service | identifier |
//! |---|---|
//! | NMT module control | [`RailFunction::Nmt`] · address 0 |
//! | boot-up, heartbeat | [`RailFunction::Heartbeat`] · the node's address |
//! | node guarding (request and answer) | [`RailFunction::NodeGuarding`] · the node's address |
//! | default EMCY | [`RailFunction::FaultReport`] · the node's address |
//!
//! Their payloads stay CiA 301's, so the stack runs unchanged. The identifiers the dictionary
//! holds (SYNC, SDO server, EMCY after reset) come from [`RailwayProfile::comm_objects`]; PDO
//! COB-IDs are 29-bit ones like `CobId::from_id(railway::id(RailFunction::StateChange, port))`.
//!
//! Process frames (command, command answer, state change, state query, state answer) carry the
//! railway [`payload`]: index, sub-index, data and a CRC over the identifier and content. Safety
//! states in them use the asymmetric codes of [`safety`].
//!
//! ```
//! use duocan_core::profile::railway::{DeviceAddress, RailFunction, RailwayProfile};
//! use duocan_core::profile::{IdProfile, ProfileFrame};
//! use duocan_core::{Id, NodeId};
//!
//! let mut profile = RailwayProfile::new();
//! let turnout_a = NodeId::must(10);
//! profile.add(turnout_a, DeviceAddress::board_at(1, 2, 3, 4))?;
//! // Heartbeats of node 10 go on function 0x008 at row 1, cabinet 2, layer 3, board 4, port 0.
//! assert_eq!(profile.heartbeat(turnout_a), Id::Extended(0x0081_2340));
//! assert_eq!(
//!     profile.classify(Id::Extended(0x0081_2340), false),
//!     Some(ProfileFrame::Heartbeat(turnout_a))
//! );
//! // Its point machine on I/O port 2 reports state changes on 0x0201_2342.
//! let port2 = profile.address(turnout_a).unwrap().with_port(2);
//! assert_eq!(duocan_core::profile::railway::id(RailFunction::StateChange, port2).raw(), 0x0201_2342);
//! # Ok::<(), duocan_core::profile::railway::TableError>(())
//! ```

mod address;
mod function;
pub mod payload;
pub mod safety;
mod table;

pub use address::{
    compose, split, AddressError, DeviceAddress, ADDRESS_MAX, FIELD_MAX, FUNCTION_MAX,
};
pub use function::RailFunction;
pub use payload::{Payload, PayloadError};
pub use table::TableError;

use super::{IdProfile, ProfileFrame};
use crate::cia301::sdo::Channel;
use crate::frame::cob_id::{CobId, NodeId};
use crate::frame::Id;
use crate::od::{comm, ObjectDef, ObjectType};
use table::Table;

/// The identifier of `function` at `address`.
pub const fn id(function: RailFunction, address: DeviceAddress) -> Id {
    compose(function.code(), address)
}

/// What a railway identifier names.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Decoded {
    /// The function code.
    pub function: RailFunction,
    /// The full address (port included).
    pub address: DeviceAddress,
    /// The node at the address's board, if the table has one.
    pub node: Option<NodeId>,
}

/// The railway scheme with its node-ID ↔ board-address table (bounded, no heap; about 1 KiB).
///
/// Clone it into each machine that needs it, or share one `&'static RailwayProfile`: both
/// [`IdProfile`] and the redundancy crate's frame classifier are implemented for references.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RailwayProfile {
    table: Table,
}

impl Default for RailwayProfile {
    fn default() -> Self {
        Self::new()
    }
}

impl RailwayProfile {
    /// NMT module control: function 0x000, address 0 (the highest priority on the bus).
    pub const NMT: Id = id(RailFunction::Nmt, DeviceAddress::board_at(0, 0, 0, 0));
    /// SYNC: function 0x002, address 0.
    pub const SYNC: Id = id(RailFunction::Sync, DeviceAddress::board_at(0, 0, 0, 0));

    /// An empty table.
    #[must_use]
    pub const fn new() -> Self {
        RailwayProfile {
            table: Table::new(),
        }
    }
    /// A table of `(node, board address)` entries.
    pub fn with(entries: &[(NodeId, DeviceAddress)]) -> Result<Self, TableError> {
        let mut p = Self::new();
        for (n, a) in entries {
            p.add(*n, *a)?;
        }
        Ok(p)
    }
    /// Puts `node` at board address `address` (port 0), moving it if it had another address.
    pub fn add(&mut self, node: NodeId, address: DeviceAddress) -> Result<(), TableError> {
        self.table.add(node, address)
    }
    /// Takes `node` out of the table; returns its address.
    pub fn remove(&mut self, node: NodeId) -> Option<DeviceAddress> {
        self.table.remove(node)
    }
    /// The board address of `node`.
    pub fn address(&self, node: NodeId) -> Option<DeviceAddress> {
        self.table.address(node)
    }
    /// The node on the board of `address` (its port is ignored).
    pub fn node_at(&self, address: DeviceAddress) -> Option<NodeId> {
        self.table.node_at(address.board_address())
    }
    /// Entries in the table.
    pub fn len(&self) -> usize {
        self.table.len()
    }
    /// True when the table is empty.
    pub fn is_empty(&self) -> bool {
        self.table.len() == 0
    }
    /// Every `(node, board address)`, by node-ID.
    pub fn iter(&self) -> impl Iterator<Item = (NodeId, DeviceAddress)> + '_ {
        self.table.iter()
    }

    /// The identifier of `function` on `node`'s I/O `port` (0: the board itself).
    pub fn id(&self, function: RailFunction, node: NodeId, port: u8) -> Option<Id> {
        Some(id(function, self.address(node)?.with_port(port)))
    }
    /// What an identifier names: `None` for 11-bit identifiers and codes the scheme does not use.
    pub fn decode(&self, frame_id: Id) -> Option<Decoded> {
        let (code, address) = split(frame_id)?;
        Some(Decoded {
            function: RailFunction::from_code(code)?,
            address,
            node: self.node_at(address),
        })
    }

    /// The SDO server COB-IDs of `node` (client → server, server → client), as 0x1200 and
    /// 0x1280 hold them: 29-bit identifiers [`RailFunction::SdoRequest`] and
    /// [`RailFunction::SdoResponse`] at the node's board address.
    pub fn sdo_cob_ids(&self, node: NodeId) -> Option<(u32, u32)> {
        let a = self.address(node)?;
        Some(sdo_cob_ids(a))
    }
    /// The SDO channel of `node` for a client (`SdoOptions::channel`).
    pub fn sdo_channel(&self, node: NodeId) -> Option<Channel> {
        let (rx, tx) = self.sdo_cob_ids(node)?;
        Channel::from_cob_ids(rx, tx)
    }

    /// The communication entries whose CiA 301 defaults are predefined-set identifiers, with
    /// the railway identifiers of the board at `address` as defaults instead: 0x1005 (SYNC,
    /// [`RailwayProfile::SYNC`]; a producer sets bit 30), 0x1014 (EMCY → fault report) and
    /// 0x1200 sub 1/2 (SDO server). Put them in the node's dictionary in place of the standard
    /// ones (`DynamicDictionary::upsert`, or a static table), so that they survive the resets
    /// NMT commands (every reset restores the defaults).
    pub const fn comm_objects(address: DeviceAddress) -> [ObjectDef; 4] {
        let board = address.board_address();
        let (rx, tx) = sdo_cob_ids(board);
        [
            ObjectDef::u32(
                comm::SYNC_COB_ID,
                0,
                crate::od::Access::Rw,
                CobId::from_id(Self::SYNC).0,
            )
            .named("COB-ID SYNC"),
            ObjectDef::u32(
                comm::EMCY_COB_ID,
                0,
                crate::od::Access::Rw,
                CobId::from_id(id(RailFunction::FaultReport, board)).0,
            )
            .named("COB-ID EMCY"),
            ObjectDef::u32(comm::SDO_SERVER, 1, crate::od::Access::Ro, rx)
                .object_type(ObjectType::Record)
                .named("COB-ID client to server"),
            ObjectDef::u32(comm::SDO_SERVER, 2, crate::od::Access::Ro, tx)
                .object_type(ObjectType::Record)
                .named("COB-ID server to client"),
        ]
    }

    /// The identifier of a service of `node`; a node missing from the table gets
    /// [`RailFunction::Unmapped`] with its node-ID as address, which nobody decodes.
    #[inline]
    fn node_id(&self, function: RailFunction, node: NodeId) -> Id {
        match self.address(node) {
            Some(a) => id(function, a),
            // A node-ID always fits the 20 address bits.
            None => compose(
                RailFunction::Unmapped.code(),
                DeviceAddress::from_raw(node.raw() as u32).unwrap_or_default(),
            ),
        }
    }
}

const fn sdo_cob_ids(board: DeviceAddress) -> (u32, u32) {
    (
        CobId::from_id(id(RailFunction::SdoRequest, board)).0,
        CobId::from_id(id(RailFunction::SdoResponse, board)).0,
    )
}

impl IdProfile for RailwayProfile {
    fn nmt(&self) -> Id {
        Self::NMT
    }
    fn heartbeat(&self, node: NodeId) -> Id {
        self.node_id(RailFunction::Heartbeat, node)
    }
    fn guarding(&self, node: NodeId) -> Id {
        self.node_id(RailFunction::NodeGuarding, node)
    }
    fn emcy(&self, node: NodeId) -> Id {
        self.node_id(RailFunction::FaultReport, node)
    }
    /// Node-level services need port 0 and an address in the table; a remote frame is only a
    /// guarding request (heartbeat, EMCY and NMT have data frames only).
    #[inline]
    fn classify(&self, frame_id: Id, remote: bool) -> Option<ProfileFrame> {
        let (code, address) = split(frame_id)?;
        match (RailFunction::from_code(code)?, remote) {
            (RailFunction::Nmt, false) if address.raw() == 0 => Some(ProfileFrame::Nmt),
            (RailFunction::Heartbeat, false) => {
                self.table.node_at(address).map(ProfileFrame::Heartbeat)
            }
            (RailFunction::NodeGuarding, _) => {
                self.table.node_at(address).map(ProfileFrame::Guarding)
            }
            (RailFunction::FaultReport, false) => {
                self.table.node_at(address).map(ProfileFrame::Emcy)
            }
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests;
