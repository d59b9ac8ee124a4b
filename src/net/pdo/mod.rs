//! PDOs through the front door, as python `canopen` users know them (`node.tpdo.read()`,
//! `tpdo[1].add_variable(..)`, `save()`): a node's PDO configuration read over SDO as a
//! [`PdoMap`], changed and saved back, received as decoded values ([`NetEvent::Pdo`]) and, for
//! its RPDOs, sent.
//!
//! The network decodes a node's TPDO once it knows its mapping: after
//! [`RemotePdo::read`] or [`RemotePdo::save`], or when told with [`RemotePdo::learn`]. With a
//! device description attached to the node, the values carry their names and are typed by
//! it; without one they are unsigned numbers of the mapped width.
//!
//! [`NetEvent::Pdo`]: super::NetEvent::Pdo

mod remote;
pub(crate) mod table;

pub use remote::RemotePdo;
pub use table::MAX_LEARNED;

use super::error::NetError;
use super::value::AnyValue;
use crate::cia301::pdo::{Dir, MapEntry, FD_MAX_BITS, MAX_BITS, MAX_ENTRIES};
use crate::eds::Description;
use crate::frame::cob_id::{CobId, NodeId};
use crate::od::DataType;
use std::sync::Arc;

/// One entry of a PDO mapping: what it maps, and what the node's description says of it.
#[derive(Clone, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub struct PdoVariable {
    /// Object index (0x0001–0x001F with sub 0: a dummy entry of that data type).
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// Length in bits.
    pub bits: u8,
    /// The entry's name in the node's description.
    pub name: Option<String>,
    /// The entry's data type (from the description; a dummy entry's own).
    pub data_type: Option<DataType>,
}

impl PdoVariable {
    fn new(index: u16, sub: u8, bits: u8, desc: Option<&Description>) -> PdoVariable {
        let e = MapEntry::new(index, sub, bits);
        let found = desc.and_then(|d| d.entry_at(index, sub));
        PdoVariable {
            index,
            sub,
            bits,
            name: found.map(|s| s.name.clone()),
            data_type: if e.is_dummy() {
                DataType::from_code(index)
            } else {
                found.map(|s| s.data_type)
            },
        }
    }
    /// True for a dummy entry (a placeholder whose bits carry nothing).
    #[must_use]
    pub fn is_dummy(&self) -> bool {
        self.entry().is_dummy()
    }
    /// The mapping entry as the node's dictionary holds it.
    #[must_use]
    pub fn entry(&self) -> MapEntry {
        MapEntry::new(self.index, self.sub, self.bits)
    }
}

/// One PDO of a node as configured there (python `canopen`'s `PdoMap`): read it with
/// [`RemotePdo::read`], change it, save it with [`RemotePdo::save`].
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub struct PdoMap {
    /// The node.
    pub node: NodeId,
    /// The node's side: [`Dir::Transmit`] for one of its TPDOs.
    pub dir: Dir,
    /// PDO number, 1–512.
    pub pdo: u16,
    /// COB-ID as the node holds it (bit 31, invalid, as read; [`PdoMap::enabled`] decides
    /// what is saved).
    pub cob_id: CobId,
    /// True if the PDO is (or is to be) valid.
    pub enabled: bool,
    /// Transmission type: 0 acyclic synchronous, 1–240 every n-th SYNC, 254/255 event-driven.
    pub transmission_type: u8,
    /// Inhibit time in 100 µs (TPDO); `None` if the node has no such entry (not written).
    pub inhibit_100us: Option<u16>,
    /// Event timer in ms (TPDO: period; RPDO: reception timeout); `None`: no such entry.
    pub event_timer_ms: Option<u16>,
    /// SYNC start value (TPDO); `None`: no such entry.
    pub sync_start: Option<u8>,
    /// The mapping, in order.
    pub entries: Vec<PdoVariable>,
    desc: Option<Arc<Description>>,
    /// The most bits the network's PDOs carry: 64, 512 on a CANopen FD network.
    max_bits: u32,
}

impl PdoMap {
    /// An empty map of a PDO on a network whose PDOs carry `fd` ? 512 : 64 bits.
    pub(crate) fn new(
        node: NodeId,
        dir: Dir,
        pdo: u16,
        desc: Option<Arc<Description>>,
        fd: bool,
    ) -> Self {
        PdoMap {
            node,
            dir,
            pdo,
            cob_id: CobId(CobId::INVALID),
            enabled: false,
            transmission_type: 255,
            inhibit_100us: None,
            event_timer_ms: None,
            sync_start: None,
            entries: Vec::new(),
            desc,
            max_bits: if fd { FD_MAX_BITS } else { MAX_BITS },
        }
    }

    /// `"TPDO 1"`, `"RPDO 2"`: how errors name it.
    #[must_use]
    pub fn label(&self) -> String {
        label(self.dir, self.pdo)
    }

    /// The mapped length in bits.
    #[must_use]
    pub fn bits(&self) -> u32 {
        self.entries.iter().map(|e| u32::from(e.bits)).sum()
    }

    /// Empties the mapping (python `clear()`).
    pub fn clear(&mut self) -> &mut Self {
        self.entries.clear();
        self
    }

    /// Maps `bits` bits of (`index`, `sub`) next, named from the description if it has the
    /// entry. More than 64 entries, or more bits than the network's PDOs carry, is
    /// [`NetError::Pdo`]: 64 bits on a classic network, 512 (64 bytes, in CAN FD frames) on a
    /// CANopen FD one.
    pub fn add(&mut self, index: u16, sub: u8, bits: u8) -> Result<&mut Self, NetError> {
        let v = PdoVariable::new(index, sub, bits, self.desc.as_deref());
        if bits == 0 {
            return Err(self.error("an entry of 0 bits maps nothing: give its length in bits"));
        }
        if self.entries.len() >= usize::from(MAX_ENTRIES)
            || self.bits() + u32::from(bits) > self.max_bits
        {
            return Err(self.error(&format!(
                "{} more bits do not fit: a PDO carries at most {} bits (it has {}){}",
                bits,
                self.max_bits,
                self.bits(),
                if self.max_bits < FD_MAX_BITS {
                    "; on a CANopen FD network 512"
                } else {
                    ""
                }
            )));
        }
        self.entries.push(v);
        Ok(self)
    }

    /// Maps the entry `name` names in the node's description next (python
    /// `add_variable`), its whole width. An unknown or ambiguous name is [`NetError::Name`],
    /// a node without a description [`NetError::NoDescription`], a string or domain (whose
    /// length the type does not give) [`NetError::Pdo`]: map it with [`PdoMap::add`].
    pub fn add_variable(&mut self, name: &str) -> Result<&mut Self, NetError> {
        let node = self.node;
        let desc = self.desc.clone().ok_or(NetError::NoDescription { node })?;
        let e = desc
            .entry(name)
            .map_err(|error| NetError::Name { node, error })?;
        let Some(bits) = e.data_type.bit_size().and_then(|b| u8::try_from(b).ok()) else {
            return Err(self.error(&format!(
                "{name:?} has no fixed length: map it with add(index, sub, bits)"
            )));
        };
        self.add(e.index, e.sub, bits)
    }

    pub(crate) fn error(&self, why: &str) -> NetError {
        NetError::Pdo {
            node: self.node,
            pdo: self.label(),
            why: why.into(),
        }
    }
}

pub(crate) fn label(dir: Dir, pdo: u16) -> String {
    match dir {
        Dir::Transmit => format!("TPDO {pdo}"),
        Dir::Receive => format!("RPDO {pdo}"),
    }
}

/// One value of a received PDO.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub struct PdoValue {
    /// Object index on the node.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// Its name in the node's description, if one is attached.
    pub name: Option<Arc<str>>,
    /// The value, typed by the description (unsigned without one).
    pub value: AnyValue,
}

/// The values of one received PDO, in mapping order (dummy entries left out). Cheap to clone.
#[derive(Clone, Debug, PartialEq)]
pub struct PdoValues(pub(crate) Arc<[PdoValue]>);

impl PdoValues {
    /// The value of the entry named `name` (without regard to case).
    #[must_use]
    pub fn get(&self, name: &str) -> Option<&AnyValue> {
        self.0
            .iter()
            .find(|v| {
                v.name
                    .as_deref()
                    .is_some_and(|n| n.eq_ignore_ascii_case(name))
            })
            .map(|v| &v.value)
    }
    /// The value of entry (`index`, `sub`).
    #[must_use]
    pub fn at(&self, index: u16, sub: u8) -> Option<&AnyValue> {
        self.0
            .iter()
            .find(|v| (v.index, v.sub) == (index, sub))
            .map(|v| &v.value)
    }
}

impl std::ops::Deref for PdoValues {
    type Target = [PdoValue];
    fn deref(&self) -> &[PdoValue] {
        &self.0
    }
}
