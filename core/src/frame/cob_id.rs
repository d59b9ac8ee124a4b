//! Node-IDs, COB-IDs with their CiA 301 flag bits, and the predefined connection set.

use crate::frame::{Id, EXTENDED_ID_MAX, STANDARD_ID_MAX};
use core::fmt;

/// A CANopen node-ID, 1–127 (0 is not a node; it addresses "all nodes" in NMT commands).
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct NodeId(u8);

impl NodeId {
    /// `Some` for 1–127, `None` otherwise.
    pub const fn new(raw: u8) -> Option<NodeId> {
        if raw >= 1 && raw <= 127 {
            Some(NodeId(raw))
        } else {
            None
        }
    }
    /// The number, 1–127.
    pub const fn raw(self) -> u8 {
        self.0
    }
    /// Panics at compile time when used in a const context with an invalid value; for literals.
    #[must_use]
    pub const fn must(raw: u8) -> NodeId {
        match NodeId::new(raw) {
            Some(n) => n,
            None => panic!("node-ID must be 1..=127"),
        }
    }
}

impl fmt::Display for NodeId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "node {:#04x}", self.0)
    }
}
impl fmt::Debug for NodeId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "NodeId({})", self.0)
    }
}

/// A COB-ID as stored in the dictionary (0x1005, 0x1012, 0x1014, 0x14xx/0x18xx sub 1, …):
/// bit 31 = invalid (object not used), bit 30 = RTR not allowed / producer, bit 29 = 29-bit frame.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct CobId(pub u32);

impl CobId {
    /// Bit 31: 1 = the object does not exist / is not valid.
    pub const INVALID: u32 = 1 << 31;
    /// Bit 30: for PDOs "no RTR allowed"; for SYNC/TIME "this node produces".
    pub const BIT30: u32 = 1 << 30;
    /// Bit 29: 1 = 29-bit (CAN 2.0B) identifier.
    pub const EXTENDED: u32 = 1 << 29;

    /// A valid COB-ID for an 11-bit identifier.
    #[must_use]
    pub const fn standard(id: u16) -> CobId {
        CobId((id & STANDARD_ID_MAX) as u32)
    }
    /// A valid COB-ID for a 29-bit identifier.
    #[must_use]
    pub const fn extended(id: u32) -> CobId {
        CobId((id & EXTENDED_ID_MAX) | Self::EXTENDED)
    }
    /// A COB-ID for the given CAN identifier.
    #[must_use]
    pub const fn from_id(id: Id) -> CobId {
        match id {
            Id::Standard(r) => CobId::standard(r),
            Id::Extended(r) => CobId::extended(r),
        }
    }
    /// True when bit 31 is clear.
    pub const fn is_valid(self) -> bool {
        self.0 & Self::INVALID == 0
    }
    /// Bit 30 (meaning depends on the object).
    pub const fn bit30(self) -> bool {
        self.0 & Self::BIT30 != 0
    }
    /// True when bit 29 selects a 29-bit identifier.
    pub const fn is_extended(self) -> bool {
        self.0 & Self::EXTENDED != 0
    }
    /// The same COB-ID with bit 31 set or cleared.
    #[must_use]
    pub const fn with_valid(self, valid: bool) -> CobId {
        if valid {
            CobId(self.0 & !Self::INVALID)
        } else {
            CobId(self.0 | Self::INVALID)
        }
    }
    /// The same COB-ID with bit 30 set or cleared.
    #[must_use]
    pub const fn with_bit30(self, set: bool) -> CobId {
        if set {
            CobId(self.0 | Self::BIT30)
        } else {
            CobId(self.0 & !Self::BIT30)
        }
    }
    /// The CAN identifier it selects. For 11-bit COB-IDs, bits 11–28 must be zero (CiA 301);
    /// `None` when they are not.
    pub const fn can_id(self) -> Option<Id> {
        if self.is_extended() {
            Some(Id::Extended(self.0 & EXTENDED_ID_MAX))
        } else if self.0 & (EXTENDED_ID_MAX & !(STANDARD_ID_MAX as u32)) != 0 {
            None
        } else {
            Some(Id::Standard((self.0 & STANDARD_ID_MAX as u32) as u16))
        }
    }
}

impl fmt::Debug for CobId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "CobId({:#010x})", self.0)
    }
}

/// The CiA 301 predefined connection set. This is the only place in the stack that knows
/// "function code = identifier >> 7"; custom schemes go through [`crate::profile::IdProfile`].
pub mod predefined {
    use super::NodeId;
    use crate::frame::Id;

    /// NMT module control, 0x000.
    pub const NMT: u16 = 0x000;
    /// SYNC, 0x080.
    pub const SYNC: u16 = 0x080;
    /// TIME, 0x100.
    pub const TIME: u16 = 0x100;
    /// EMCY base; EMCY of node n = 0x080 + n.
    pub const EMCY_BASE: u16 = 0x080;
    /// TPDO1 base; TPDOn = 0x180 + (n−1)·0x100.
    pub const TPDO_BASE: u16 = 0x180;
    /// RPDO1 base; RPDOn = 0x200 + (n−1)·0x100.
    pub const RPDO_BASE: u16 = 0x200;
    /// SDO server → client, 0x580 + node.
    pub const SDO_TX_BASE: u16 = 0x580;
    /// SDO client → server, 0x600 + node.
    pub const SDO_RX_BASE: u16 = 0x600;
    /// NMT error control (heartbeat, boot-up, guarding), 0x700 + node.
    pub const ERROR_CONTROL_BASE: u16 = 0x700;

    /// EMCY of a node.
    pub const fn emcy(n: NodeId) -> Id {
        Id::Standard(EMCY_BASE + n.raw() as u16)
    }
    /// TPDO `k` (1–4) of a node.
    pub const fn tpdo(k: u8, n: NodeId) -> Id {
        Id::Standard(TPDO_BASE + (k as u16 - 1) * 0x100 + n.raw() as u16)
    }
    /// RPDO `k` (1–4) of a node.
    pub const fn rpdo(k: u8, n: NodeId) -> Id {
        Id::Standard(RPDO_BASE + (k as u16 - 1) * 0x100 + n.raw() as u16)
    }
    /// SDO server → client of a node.
    pub const fn sdo_tx(n: NodeId) -> Id {
        Id::Standard(SDO_TX_BASE + n.raw() as u16)
    }
    /// SDO client → server of a node.
    pub const fn sdo_rx(n: NodeId) -> Id {
        Id::Standard(SDO_RX_BASE + n.raw() as u16)
    }
    /// NMT error control (heartbeat / boot-up / guarding) of a node.
    pub const fn error_control(n: NodeId) -> Id {
        Id::Standard(ERROR_CONTROL_BASE + n.raw() as u16)
    }

    /// What a predefined-set identifier means.
    #[derive(Clone, Copy, Debug, PartialEq, Eq)]
    pub enum Function {
        /// NMT module control.
        Nmt,
        /// SYNC.
        Sync,
        /// TIME.
        Time,
        /// EMCY from a node.
        Emcy(NodeId),
        /// TPDO `k` of a node.
        Tpdo(u8, NodeId),
        /// RPDO `k` of a node.
        Rpdo(u8, NodeId),
        /// SDO response from a node's server.
        SdoTx(NodeId),
        /// SDO request to a node's server.
        SdoRx(NodeId),
        /// Heartbeat, boot-up or guarding of a node.
        ErrorControl(NodeId),
        /// Anything else (LSS, flying master, 302-6 indications, custom).
        Other,
    }

    /// Decodes an 11-bit identifier of the predefined connection set.
    pub fn classify(id: Id) -> Function {
        let Id::Standard(raw) = id else {
            return Function::Other;
        };
        match raw {
            NMT => return Function::Nmt,
            SYNC => return Function::Sync,
            TIME => return Function::Time,
            _ => {}
        }
        let Some(node) = NodeId::new((raw & 0x7F) as u8) else {
            return Function::Other;
        };
        // TPDOn sits at function code 2n+1, RPDOn at 2n+2.
        match raw >> 7 {
            0x1 => Function::Emcy(node),
            0x3 | 0x5 | 0x7 | 0x9 => Function::Tpdo(((raw >> 7) as u8 - 1) / 2, node),
            0x4 | 0x6 | 0x8 | 0xA => Function::Rpdo(((raw >> 7) as u8 - 2) / 2, node),
            0xB => Function::SdoTx(node),
            0xC => Function::SdoRx(node),
            0xE => Function::ErrorControl(node),
            _ => Function::Other,
        }
    }
}

/// A set of node-IDs (1–127).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct NodeSet(pub u128);

impl NodeSet {
    /// The empty set.
    pub const EMPTY: NodeSet = NodeSet(0);
    /// Adds a node.
    pub fn insert(&mut self, n: NodeId) {
        self.0 |= 1u128 << n.raw();
    }
    /// With a node added.
    #[must_use]
    pub const fn with(self, n: NodeId) -> NodeSet {
        NodeSet(self.0 | 1u128 << n.raw())
    }
    /// True if `n` is in the set.
    pub const fn contains(&self, n: NodeId) -> bool {
        self.0 & (1u128 << n.raw()) != 0
    }
    /// Number of nodes.
    pub const fn len(&self) -> usize {
        self.0.count_ones() as usize
    }
    /// True when empty.
    pub const fn is_empty(&self) -> bool {
        self.0 == 0
    }
    /// Members in ascending order.
    pub fn iter(&self) -> impl Iterator<Item = NodeId> + '_ {
        (1..=127u8).filter_map(|n| NodeId::new(n).filter(|id| self.contains(*id)))
    }
}

impl FromIterator<NodeId> for NodeSet {
    fn from_iter<T: IntoIterator<Item = NodeId>>(iter: T) -> Self {
        let mut s = NodeSet::EMPTY;
        for n in iter {
            s.insert(n);
        }
        s
    }
}

impl fmt::Display for NodeSet {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("{")?;
        for (i, n) in self.iter().enumerate() {
            if i > 0 {
                f.write_str(", ")?;
            }
            write!(f, "{}", n.raw())?;
        }
        f.write_str("}")
    }
}

#[cfg(test)]
mod tests {
    use super::predefined::*;
    use super::*;

    #[test]
    fn flag_bits() {
        let c = CobId(0x8000_0181);
        assert!(!c.is_valid());
        assert_eq!(c.with_valid(true), CobId(0x181));
        assert!(CobId(0x4000_0080).bit30());
        assert_eq!(
            CobId::extended(0x1234567).can_id(),
            Some(Id::Extended(0x1234567))
        );
        assert_eq!(
            CobId(0x0000_0800).can_id(),
            None,
            "11-bit COB-ID with bit 11 set"
        );
    }

    #[test]
    fn predefined_set_round_trips() {
        let n = NodeId::must(0x12);
        assert_eq!(classify(tpdo(1, n)), Function::Tpdo(1, n));
        assert_eq!(classify(tpdo(4, n)), Function::Tpdo(4, n));
        assert_eq!(classify(rpdo(1, n)), Function::Rpdo(1, n));
        assert_eq!(classify(rpdo(4, n)), Function::Rpdo(4, n));
        assert_eq!(classify(sdo_tx(n)), Function::SdoTx(n));
        assert_eq!(classify(sdo_rx(n)), Function::SdoRx(n));
        assert_eq!(classify(error_control(n)), Function::ErrorControl(n));
        assert_eq!(classify(emcy(n)), Function::Emcy(n));
        assert_eq!(classify(Id::Standard(0x80)), Function::Sync);
        assert_eq!(classify(Id::Standard(0x71)), Function::Other);
        assert_eq!(
            classify(Id::Standard(0x700)),
            Function::Other,
            "node 0 is not a node"
        );
        assert_eq!(tpdo(2, n), Id::Standard(0x292));
        assert_eq!(rpdo(3, n), Id::Standard(0x412));
    }

    #[test]
    fn node_id_range() {
        assert!(NodeId::new(0).is_none());
        assert!(NodeId::new(128).is_none());
        assert_eq!(NodeId::new(127).map(NodeId::raw), Some(127));
    }
}
