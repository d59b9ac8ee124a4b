//! The master's own end of a remote PDO: a slave's TPDO becomes one of the master's RPDOs (its
//! values land in typed entries of the master's dictionary), a slave's RPDO one of the master's
//! TPDOs (the application writes typed entries, the master sends them).

use super::PdoConfig;
use crate::cia301::pdo::mapping::{Dir, MapEntry};
use crate::cia301::pdo::params::{self, sub};
use crate::frame::instant::Instant;
use crate::frame::storage::Storage;
use crate::node::Node;
use crate::od::abort::AbortCode;
use crate::od::{DataType, DefaultValue, DynamicDictionary, ObjectDef, ObjectDictionary};
use crate::profile::IdProfile;
use alloc::vec::Vec;
use core::fmt;

/// Where one remote mapped value lives in the master's dictionary.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Local {
    /// Index.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// Its type; must hold the mapped length.
    pub data_type: DataType,
}

impl Local {
    /// An entry (index, sub) of type `data_type`.
    #[must_use]
    pub const fn new(index: u16, sub: u8, data_type: DataType) -> Local {
        Local {
            index,
            sub,
            data_type,
        }
    }
}

/// How the master's PDO mirrors the remote one.
#[derive(Clone, Copy, Debug)]
pub struct Mirror<'a> {
    /// The master's own PDO number (an RPDO for a remote TPDO, a TPDO for a remote RPDO).
    pub pdo: u16,
    /// The master's transmission type (RPDO: 0–240 apply at SYNC, 254/255 at once).
    pub transmission_type: u8,
    /// RPDO: reception timeout; TPDO: event timer (ms, 0 = none).
    pub event_timer_ms: u16,
    /// TPDO: inhibit time (100 µs).
    pub inhibit_100us: u16,
    /// One per remote mapping entry, in order; `None` skips the value (a dummy entry).
    pub locals: &'a [Option<Local>],
}

/// Why a mirror could not be set up; the master's PDO is left invalid.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MirrorError {
    /// The remote configuration has no mapping to mirror.
    NoMapping,
    /// `locals` does not have one element per remote mapping entry.
    EntryCount {
        /// Remote mapping entries.
        mapped: usize,
        /// Local entries given.
        locals: usize,
    },
    /// The master has no such PDO (number 0 or beyond its capacity).
    NoSuchPdo {
        /// The number asked for.
        pdo: u16,
        /// The master's capacity in that direction.
        capacity: usize,
    },
    /// A local entry's type cannot hold the mapped length.
    TooShort {
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// Mapped bits.
        bits: u8,
    },
    /// A local entry exists already with another type, or is not mappable in that direction.
    Conflict {
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
    },
    /// The master's dictionary refused a parameter write.
    Write {
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// Why.
        code: AbortCode,
    },
}

impl fmt::Display for MirrorError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            MirrorError::NoMapping => {
                write!(f, "the remote PDO configuration has no mapping to mirror")
            }
            MirrorError::EntryCount { mapped, locals } => write!(
                f,
                "the remote PDO maps {mapped} entries but {locals} local entries were given"
            ),
            MirrorError::NoSuchPdo { pdo, capacity } => write!(
                f,
                "the master has {capacity} PDOs in that direction, not {pdo}: raise its capacity"
            ),
            MirrorError::TooShort { index, sub, bits } => write!(
                f,
                "local entry {index:#06x}sub{sub} cannot hold {bits} mapped bits: choose a wider type"
            ),
            MirrorError::Conflict { index, sub } => write!(
                f,
                "local entry {index:#06x}sub{sub} exists with another type or is not mappable"
            ),
            MirrorError::Write { index, sub, code } => {
                write!(f, "writing {index:#06x}sub{sub} of the master failed: {code}")
            }
        }
    }
}

impl core::error::Error for MirrorError {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        match self {
            MirrorError::Write { code, .. } => Some(code),
            _ => None,
        }
    }
}

/// The smallest unsigned type a dummy entry of `bits` can name.
fn dummy_type(bits: u8) -> DataType {
    match bits {
        0..=8 => DataType::Unsigned8,
        9..=16 => DataType::Unsigned16,
        17..=32 => DataType::Unsigned32,
        _ => DataType::Unsigned64,
    }
}

/// Sets up the master's PDO `m.pdo` as the other end of a remote PDO configured as `remote`
/// (`remote_dir` is the remote side: [`Dir::Transmit`] for a slave's TPDO). Local entries are
/// created where missing (read-write, mappable); parameter objects too. The parameters are then
/// written through the node in the CiA 301 order (invalidate, type, timer, mapping, validate), so
/// the engine picks the PDO up as from any configuration write.
pub fn mirror<
    P: IdProfile,
    const GUARDED: usize,
    const TPDOS: usize,
    const RPDOS: usize,
    S: Storage,
>(
    node: &mut Node<DynamicDictionary, P, GUARDED, TPDOS, RPDOS, S>,
    now: Instant,
    remote_dir: Dir,
    remote: &PdoConfig,
    m: &Mirror<'_>,
) -> Result<(), MirrorError> {
    let mapping = remote.mapping.as_ref().ok_or(MirrorError::NoMapping)?;
    if mapping.len() != m.locals.len() {
        return Err(MirrorError::EntryCount {
            mapped: mapping.len(),
            locals: m.locals.len(),
        });
    }
    let dir = match remote_dir {
        Dir::Transmit => Dir::Receive,
        Dir::Receive => Dir::Transmit,
    };
    let capacity = if dir == Dir::Receive {
        node.rpdo_capacity()
    } else {
        node.tpdo_capacity()
    };
    if m.pdo == 0 || m.pdo as usize > capacity {
        return Err(MirrorError::NoSuchPdo {
            pdo: m.pdo,
            capacity,
        });
    }
    let mut entries: Vec<MapEntry> = Vec::with_capacity(mapping.len());
    for (remote_entry, local) in mapping.iter().zip(m.locals) {
        let bits = remote_entry.bits;
        let Some(l) = local else {
            entries.push(MapEntry::dummy(dummy_type(bits), bits));
            continue;
        };
        let (index, sub) = (l.index, l.sub);
        if l.data_type.bit_size().is_none_or(|n| (bits as u32) > n) {
            return Err(MirrorError::TooShort { index, sub, bits });
        }
        match node.od().get(index, sub) {
            Ok(e) => {
                let usable = match dir {
                    Dir::Receive => e.def.access.writable(),
                    Dir::Transmit => e.def.access.readable(),
                };
                if e.def.data_type != l.data_type || !e.def.pdo_mappable || !usable {
                    return Err(MirrorError::Conflict { index, sub });
                }
            }
            Err(_) => {
                let def = ObjectDef::new(index, sub, l.data_type).mappable();
                node.od_mut()
                    .insert(def)
                    .map_err(|_| MirrorError::Conflict { index, sub })?;
            }
        }
        entries.push(MapEntry::new(index, sub, bits));
    }

    let (comm, map) = match dir {
        Dir::Receive => (params::RPDO_COMM, params::RPDO_MAPPING),
        Dir::Transmit => (params::TPDO_COMM, params::TPDO_MAPPING),
    };
    let (comm, map) = (comm + m.pdo - 1, map + m.pdo - 1);
    let invalid = DefaultValue::Unsigned(0x8000_0000);
    if node.od().get(comm, sub::COB_ID).is_err() {
        node.od_mut().remove_object(comm);
        let defs: &[ObjectDef] = match dir {
            Dir::Receive => &params::rpdo_comm(m.pdo, invalid, 255, 0),
            Dir::Transmit => &params::tpdo_comm(m.pdo, invalid, 255, 0, 0),
        };
        let _ = node.od_mut().insert_all(defs);
    }
    let write = |node: &mut Node<DynamicDictionary, P, GUARDED, TPDOS, RPDOS, S>,
                 index,
                 sub,
                 v: u32,
                 len| {
        node.write(now, index, sub, &v.to_le_bytes()[..len])
            .map_err(|code| MirrorError::Write { index, sub, code })
    };
    let cob = node.od().get_u32(comm, sub::COB_ID).unwrap_or(0x8000_0000);
    write(node, comm, sub::COB_ID, cob | 0x8000_0000, 4)?;
    let n = entries.len() as u8;
    if node.od().get(map, n).is_err() || node.od().get(map, 0).is_err() {
        // Room for the mapping: the full 64-entry record, trimmed to what is needed.
        node.od_mut().remove_object(map);
        let full: [ObjectDef; 65] = match dir {
            Dir::Receive => params::rpdo_mapping::<65>(m.pdo, &[]),
            Dir::Transmit => params::tpdo_mapping::<65>(m.pdo, &[]),
        };
        let _ = node.od_mut().insert_all(&full[..=n as usize]);
    }
    write(
        node,
        comm,
        sub::TRANSMISSION_TYPE,
        m.transmission_type as u32,
        1,
    )?;
    write(node, comm, sub::EVENT_TIMER, m.event_timer_ms as u32, 2)?;
    if dir == Dir::Transmit {
        write(node, comm, sub::INHIBIT_TIME, m.inhibit_100us as u32, 2)?;
    }
    write(node, map, 0, 0, 1)?;
    for (k, e) in entries.iter().enumerate() {
        write(node, map, k as u8 + 1, e.raw(), 4)?;
    }
    write(node, map, 0, n as u32, 1)?;
    write(node, comm, sub::COB_ID, remote.cob_id.0, 4)
}
