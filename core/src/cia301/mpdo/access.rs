//! How an MPDO reaches a dictionary: the write a consumer makes (the rules of an RPDO-mapped
//! write) and the read a source-address producer makes (the rules of a TPDO-mapped read).

use super::lists;
use crate::cia301::pdo::mapping::{check_entry, Dir, MapEntry};
use crate::od::abort::AbortCode;
use crate::od::ObjectDictionary;
use core::fmt;

/// Writes an MPDO's value into (`index`, `sub`) as an RPDO mapping it would: the entry must
/// exist, be mappable into an RPDO and writable, and be of a fixed size the value covers
/// (its first bytes are taken, little-endian). A dummy entry, a string or a domain is refused
/// with 0x06040041, as is an object larger than the value (an UNSIGNED64 in a classic MPDO).
pub fn write<D: ObjectDictionary + ?Sized>(
    od: &mut D,
    index: u16,
    sub: u8,
    value: &[u8],
) -> Result<(), AbortCode> {
    let size = size(od, Dir::Receive, index, sub)?;
    if size > value.len() {
        return Err(AbortCode::NOT_MAPPABLE);
    }
    od.store(index, sub, &value[..size])
}

/// Reads (`index`, `sub`) for a source-address MPDO: it must be in the scanner list
/// ([`MpdoError::NotScanned`]), mappable into a TPDO and readable, of a fixed size of at most
/// `room` bytes. Returns the value's bytes in `out` and their number.
pub fn read<D: ObjectDictionary + ?Sized>(
    od: &D,
    index: u16,
    sub: u8,
    out: &mut [u8],
) -> Result<usize, MpdoError> {
    if !lists::scanned(od, index, sub) {
        return Err(MpdoError::NotScanned { index, sub });
    }
    let size = size(od, Dir::Transmit, index, sub).map_err(MpdoError::Object)?;
    let data = od.get(index, sub).map_err(MpdoError::Object)?.data;
    if size > out.len() || data.len() < size {
        return Err(MpdoError::Object(AbortCode::NOT_MAPPABLE));
    }
    out[..size].copy_from_slice(&data[..size]);
    Ok(size)
}

/// The fixed size of an entry a PDO in direction `dir` may map whole.
fn size<D: ObjectDictionary + ?Sized>(
    od: &D,
    dir: Dir,
    index: u16,
    sub: u8,
) -> Result<usize, AbortCode> {
    let e = MapEntry::new(index, sub, 0);
    if e.is_dummy() {
        return Err(AbortCode::NOT_MAPPABLE);
    }
    let size = od
        .get(index, sub)?
        .def
        .data_type
        .fixed_size()
        .filter(|n| *n <= 8)
        .ok_or(AbortCode::NOT_MAPPABLE)?;
    check_entry(od, dir, MapEntry::new(index, sub, (size * 8) as u8))?;
    Ok(size)
}

/// Why the application's MPDO request was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MpdoError {
    /// The node has no such TPDO (number 0 or beyond its capacity).
    NoSuchPdo {
        /// The number asked for.
        pdo: u16,
    },
    /// The TPDO is no MPDO of the mode asked for (its mapping count is not 0xFE for source-,
    /// 0xFF for destination-address mode).
    WrongMode {
        /// TPDO number.
        pdo: u16,
    },
    /// The node is not operational, or the TPDO's COB-ID is invalid.
    NotRunning {
        /// TPDO number.
        pdo: u16,
    },
    /// More data than the form carries, or a destination above 127.
    BadRequest,
    /// The object is not in the scanner list (0x1FA0–0x1FCF).
    NotScanned {
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
    },
    /// The object cannot be sent (missing, not mappable, not readable, too large).
    Object(AbortCode),
}

impl fmt::Display for MpdoError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            MpdoError::NoSuchPdo { pdo } => write!(f, "no TPDO {pdo}"),
            MpdoError::WrongMode { pdo } => write!(f, "TPDO {pdo} is no MPDO of that mode"),
            MpdoError::NotRunning { pdo } => write!(f, "TPDO {pdo} is not running"),
            MpdoError::BadRequest => f.write_str("more data than an MPDO carries, or node > 127"),
            MpdoError::NotScanned { index, sub } => {
                write!(f, "{index:#06x}/{sub} is not in the object scanner list")
            }
            MpdoError::Object(code) => write!(f, "object cannot be sent: {code}"),
        }
    }
}

/// What a node's MPDO consumer did with the MPDOs it received (saturating counters).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MpdoStats {
    /// Values written into the dictionary.
    pub written: u32,
    /// Writes the dictionary refused (reported as [`PdoEvent::MpdoRefused`](crate::pdo::PdoEvent)).
    pub refused: u32,
    /// Destination-address MPDOs for another node.
    pub other_node: u32,
    /// Source-address MPDOs no dispatcher list entry covers.
    pub not_dispatched: u32,
    /// Frames that are no MPDO (not 8 bytes, source node 0).
    pub malformed: u32,
}

pub(crate) fn bump(c: &mut u32) {
    *c = c.saturating_add(1);
}
