//! The concise DCF (CiA 302-3, object 0x1F22): a slave's configuration as bytes, the form a
//! configuration tool downloads into the master and the master applies at the slave's boot.
//!
//! # The format
//!
//! All little endian: an UNSIGNED32 number of entries, then per entry an UNSIGNED16 index, an
//! UNSIGNED8 sub-index, an UNSIGNED32 data size in bytes and the data. Nothing may follow the
//! last entry.
//!
//! # The rule
//!
//! A concise DCF is a list of SDO writes, applied in the order it gives. Built from a
//! configuration ([`ConciseDcf::from_config`]) it holds that configuration's writes in their
//! order (a DCF's: only the values that differ from the device's defaults, PDOs invalid while
//! they change), then the producer heartbeat time (0x1017) last. Applied
//! ([`SlaveConfig::with_concise`]) a write to 0x1017 becomes the heartbeat the master writes
//! after every other step, as a DCF's does, so a slave configured either way sees the same
//! writes. A refused write is reported per object and the others are still written.
//!
//! # Memory and overflow
//!
//! Parsing is bounded: at most [`MAX_CONCISE_BYTES`] of input and [`MAX_CONCISE_ENTRIES`]
//! entries; beyond either, or on any malformed input, the error names the entry (the first is
//! entry 1) and the byte offset where reading stopped ([`ConciseError`]), and nothing is
//! returned.
//! [`validate`] checks bytes without allocating: the master's 0x1F22 entries refuse a malformed
//! download with an abort code, so the dictionary never holds half a configuration.
//!
//! ```
//! use duocan_core::master::{ConciseDcf, SlaveConfig};
//! use duocan_core::NodeId;
//!
//! let cfg = SlaveConfig::new(NodeId::must(5)).write_u16(0x2000, 1, 500).heartbeat(100, 0);
//! let bytes = ConciseDcf::from_config(&cfg).unwrap().to_bytes();
//! assert_eq!(bytes.len(), 4 + (7 + 2) + (7 + 2));
//! let back = ConciseDcf::parse(&bytes).unwrap();
//! let applied = SlaveConfig::new(NodeId::must(5)).with_concise(&back);
//! assert_eq!(applied.steps, cfg.steps);
//! assert_eq!(applied.heartbeat_producer_ms, Some(100));
//! ```

use super::config::{ConfigStep, SlaveConfig, WriteAborts};
use crate::od::comm;
use alloc::vec::Vec;
use core::fmt;

/// Largest concise DCF accepted, in bytes (the SDO transfer limit of a master).
pub const MAX_CONCISE_BYTES: usize = 64 * 1024;
/// Most entries a concise DCF may hold.
pub const MAX_CONCISE_ENTRIES: u32 = 4096;

/// Bytes of an entry's header: index, sub-index, data size.
const ENTRY_HEADER: usize = 7;

/// One write of a concise DCF.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ConciseEntry {
    /// Index.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// The value's bytes, little endian.
    pub data: Vec<u8>,
}

/// A concise DCF: its writes, in order.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ConciseDcf {
    /// The writes.
    pub entries: Vec<ConciseEntry>,
}

/// What was wrong with a concise DCF.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum ConciseErrorKind {
    /// The input is longer than [`MAX_CONCISE_BYTES`].
    TooLarge {
        /// Its length.
        len: usize,
    },
    /// The entry count is above [`MAX_CONCISE_ENTRIES`].
    TooManyEntries {
        /// The count the input gives.
        count: u32,
    },
    /// The input ends inside the count, an entry's header or its data.
    Truncated {
        /// Bytes the field needed.
        needed: usize,
        /// Bytes left.
        left: usize,
    },
    /// Bytes follow the last entry.
    TrailingBytes {
        /// How many.
        len: usize,
    },
    /// A configuration step a concise DCF cannot say (a PDO configured by its configurator,
    /// which reads the slave before it writes): build from [`ConfigStep::Write`]s only.
    PdoStep,
}

/// A concise DCF that cannot be read or built: what and where.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ConciseError {
    /// What.
    pub kind: ConciseErrorKind,
    /// The entry being read, from 1 (0: the entry count, or the whole input).
    pub entry: u32,
    /// The byte offset where reading stopped.
    pub offset: usize,
}

impl fmt::Display for ConciseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "concise DCF, ")?;
        if self.entry > 0 {
            write!(f, "entry {} ", self.entry)?;
        }
        write!(f, "at byte {}: ", self.offset)?;
        match self.kind {
            ConciseErrorKind::TooLarge { len } => write!(
                f,
                "{len} bytes, more than the {MAX_CONCISE_BYTES} accepted"
            ),
            ConciseErrorKind::TooManyEntries { count } => write!(
                f,
                "{count} entries, more than the {MAX_CONCISE_ENTRIES} accepted"
            ),
            ConciseErrorKind::Truncated { needed, left } => {
                write!(f, "needs {needed} more bytes, {left} left")
            }
            ConciseErrorKind::TrailingBytes { len } => {
                write!(f, "{len} bytes follow the last entry")
            }
            ConciseErrorKind::PdoStep => f.write_str(
                "a PDO step cannot be expressed as concise DCF writes: configure the PDO with writes",
            ),
        }
    }
}

impl core::error::Error for ConciseError {}

/// Walks `bytes`, calling `each` with every entry (index, sub, data); the checks of
/// [`ConciseDcf::parse`] without allocating.
fn walk(bytes: &[u8], mut each: impl FnMut(u16, u8, &[u8])) -> Result<u32, ConciseError> {
    let err = |kind, entry, offset| ConciseError {
        kind,
        entry,
        offset,
    };
    if bytes.len() > MAX_CONCISE_BYTES {
        return Err(err(
            ConciseErrorKind::TooLarge { len: bytes.len() },
            0,
            MAX_CONCISE_BYTES,
        ));
    }
    let take = |at: usize, n: usize, entry: u32| -> Result<&[u8], ConciseError> {
        let left = bytes.len() - at;
        bytes.get(at..at + n).ok_or(err(
            ConciseErrorKind::Truncated { needed: n, left },
            entry,
            at,
        ))
    };
    let count = u32::from_le_bytes(take(0, 4, 0)?.try_into().unwrap_or_default());
    if count > MAX_CONCISE_ENTRIES {
        return Err(err(ConciseErrorKind::TooManyEntries { count }, 0, 0));
    }
    let mut at = 4;
    for entry in 1..=count {
        let h = take(at, ENTRY_HEADER, entry)?;
        let index = u16::from_le_bytes([h[0], h[1]]);
        let size = u32::from_le_bytes([h[3], h[4], h[5], h[6]]);
        at += ENTRY_HEADER;
        // A size beyond the input is truncation, whatever its value (no usize overflow: the
        // input is at most MAX_CONCISE_BYTES).
        let size = usize::try_from(size)
            .unwrap_or(usize::MAX)
            .min(bytes.len() + 1);
        let data = take(at, size, entry)?;
        each(index, h[2], data);
        at += size;
    }
    if at < bytes.len() {
        return Err(err(
            ConciseErrorKind::TrailingBytes {
                len: bytes.len() - at,
            },
            count,
            at,
        ));
    }
    Ok(count)
}

/// Checks a concise DCF without keeping it; gives its number of entries.
pub fn validate(bytes: &[u8]) -> Result<u32, ConciseError> {
    walk(bytes, |_, _, _| {})
}

impl ConciseDcf {
    /// Reads a concise DCF (bounded: see the module docs).
    pub fn parse(bytes: &[u8]) -> Result<ConciseDcf, ConciseError> {
        // Validated first, so that a huge count with little data allocates nothing.
        let count = validate(bytes)?;
        let mut entries = Vec::with_capacity(count as usize);
        walk(bytes, |index, sub, data| {
            entries.push(ConciseEntry {
                index,
                sub,
                data: data.to_vec(),
            });
        })?;
        Ok(ConciseDcf { entries })
    }

    /// The bytes of the concise DCF.
    #[must_use]
    pub fn to_bytes(&self) -> Vec<u8> {
        let len = 4 + self
            .entries
            .iter()
            .map(|e| ENTRY_HEADER + e.data.len())
            .sum::<usize>();
        let mut out = Vec::with_capacity(len);
        out.extend_from_slice(&(self.entries.len() as u32).to_le_bytes());
        for e in &self.entries {
            out.extend_from_slice(&e.index.to_le_bytes());
            out.push(e.sub);
            out.extend_from_slice(&(e.data.len() as u32).to_le_bytes());
            out.extend_from_slice(&e.data);
        }
        out
    }

    /// The writes of a slave's configuration as a concise DCF: its write steps in order, then
    /// its producer heartbeat time (0x1017) if it has one. A PDO step is an error
    /// ([`ConciseErrorKind::PdoStep`], `entry` the step's number from 1).
    pub fn from_config(cfg: &SlaveConfig) -> Result<ConciseDcf, ConciseError> {
        let mut entries = Vec::with_capacity(cfg.steps.len() + 1);
        for (i, step) in cfg.steps.iter().enumerate() {
            let ConfigStep::Write { index, sub, data } = step else {
                return Err(ConciseError {
                    kind: ConciseErrorKind::PdoStep,
                    entry: i as u32 + 1,
                    offset: 0,
                });
            };
            entries.push(ConciseEntry {
                index: *index,
                sub: *sub,
                data: data.clone(),
            });
        }
        if let Some(ms) = cfg.heartbeat_producer_ms {
            entries.push(ConciseEntry {
                index: comm::HEARTBEAT_PRODUCER,
                sub: 0,
                data: ms.to_le_bytes().to_vec(),
            });
        }
        Ok(ConciseDcf { entries })
    }
}

impl SlaveConfig {
    /// Adds the writes of a concise DCF, in its order. A two-byte write to 0x1017 sets the
    /// producer heartbeat time (written after every other step) unless one is set already. A
    /// refused write is reported and the others are still written ([`WriteAborts::Continue`]).
    #[must_use]
    pub fn with_concise(mut self, dcf: &ConciseDcf) -> SlaveConfig {
        self.write_aborts = WriteAborts::Continue;
        for e in &dcf.entries {
            let heartbeat = (e.index, e.sub) == (comm::HEARTBEAT_PRODUCER, 0);
            if heartbeat && self.heartbeat_producer_ms.is_none() {
                if let Ok(b) = <[u8; 2]>::try_from(e.data.as_slice()) {
                    self.heartbeat_producer_ms = Some(u16::from_le_bytes(b));
                    continue;
                }
            }
            self.steps.push(ConfigStep::Write {
                index: e.index,
                sub: e.sub,
                data: e.data.clone(),
            });
        }
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entry(index: u16, sub: u8, data: &[u8]) -> Vec<u8> {
        let mut v = index.to_le_bytes().to_vec();
        v.push(sub);
        v.extend_from_slice(&(data.len() as u32).to_le_bytes());
        v.extend_from_slice(data);
        v
    }

    #[test]
    fn malformed_input_names_the_entry_and_offset() {
        let mut ok = 2u32.to_le_bytes().to_vec();
        ok.extend(entry(0x2000, 1, &[1, 2]));
        ok.extend(entry(0x2000, 2, &[3]));
        assert_eq!(validate(&ok), Ok(2));
        let cases: [(&[u8], ConciseErrorKind, u32, usize); 5] = [
            (
                &ok[..2],
                ConciseErrorKind::Truncated { needed: 4, left: 2 },
                0,
                0,
            ),
            (
                &ok[..8],
                ConciseErrorKind::Truncated { needed: 7, left: 4 },
                1,
                4,
            ),
            (
                &ok[..ok.len() - 1],
                ConciseErrorKind::Truncated { needed: 1, left: 0 },
                2,
                ok.len() - 1,
            ),
            (
                &[0xFF, 0xFF, 0xFF, 0xFF],
                ConciseErrorKind::TooManyEntries { count: u32::MAX },
                0,
                0,
            ),
            (
                &[0, 0, 0, 0, 9],
                ConciseErrorKind::TrailingBytes { len: 1 },
                0,
                4,
            ),
        ];
        for (bytes, kind, entry, offset) in cases {
            assert_eq!(
                ConciseDcf::parse(bytes),
                Err(ConciseError {
                    kind,
                    entry,
                    offset
                })
            );
        }
        // A data size far beyond the input is truncation, not an allocation.
        let mut huge = 1u32.to_le_bytes().to_vec();
        huge.extend_from_slice(&[0, 0x20, 0, 0xFF, 0xFF, 0xFF, 0xFF]);
        assert!(matches!(
            validate(&huge),
            Err(ConciseError {
                kind: ConciseErrorKind::Truncated { left: 0, .. },
                entry: 1,
                offset: 11
            })
        ));
        let big = alloc::vec![0u8; MAX_CONCISE_BYTES + 1];
        assert!(matches!(
            validate(&big).map_err(|e| e.kind),
            Err(ConciseErrorKind::TooLarge { .. })
        ));
    }

    #[test]
    fn a_pdo_step_is_not_a_concise_write() {
        let cfg = SlaveConfig::new(crate::NodeId::must(3))
            .write_u8(0x2000, 0, 1)
            .tpdo(
                1,
                crate::cia302::pdo_config::PdoConfig::new(
                    crate::frame::cob_id::CobId::standard(0x183),
                    254,
                ),
            );
        assert_eq!(
            ConciseDcf::from_config(&cfg).map_err(|e| (e.kind, e.entry)),
            Err((ConciseErrorKind::PdoStep, 2))
        );
    }
}
