//! What an LSS slave keeps across power cycles: its node-ID and bit timing, as a 12-byte image
//! on any [`ParameterStorage`] medium (the same trait 0x1010 stores the dictionary through; a
//! board gives LSS its own sector or file, so the two images never overwrite each other).
//!
//! The image is `"LSS1"`, the node-ID, a flag and the two bytes of the bit timing, and a CRC-32
//! of those eight bytes: a torn or foreign image is [`LssStoreError::Corrupt`], never a node-ID
//! taken from noise.

use super::codec::{BitTiming, UNCONFIGURED};
use crate::od::parameters::{crc32, ParameterStorage};
use core::convert::Infallible;
use core::fmt;

const MAGIC: [u8; 4] = *b"LSS1";
/// Bytes of the stored image.
pub const IMAGE_LEN: usize = 12;

/// The configuration an LSS slave stores.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StoredLss {
    /// The node-ID (0xFF: none).
    pub node_id: u8,
    /// The bit timing, if one was configured.
    pub bit_timing: Option<BitTiming>,
}

impl StoredLss {
    pub(super) fn image(&self) -> [u8; IMAGE_LEN] {
        let mut b = [0u8; IMAGE_LEN];
        b[..4].copy_from_slice(&MAGIC);
        b[4] = self.node_id;
        if let Some(t) = self.bit_timing {
            b[5] = 1;
            b[6] = t.table;
            b[7] = t.index;
        }
        let crc = crc32(&b[..8]);
        b[8..].copy_from_slice(&crc.to_le_bytes());
        b
    }

    pub(super) fn parse(b: &[u8]) -> Result<StoredLss, LssStoreError> {
        let b: &[u8; IMAGE_LEN] = b.try_into().map_err(|_| LssStoreError::Corrupt)?;
        let crc = u32::from_le_bytes([b[8], b[9], b[10], b[11]]);
        let node_ok = b[4] == UNCONFIGURED || (1..=127).contains(&b[4]);
        if b[..4] != MAGIC || crc != crc32(&b[..8]) || !node_ok || b[5] > 1 {
            return Err(LssStoreError::Corrupt);
        }
        Ok(StoredLss {
            node_id: b[4],
            bit_timing: (b[5] == 1).then_some(BitTiming {
                table: b[6],
                index: b[7],
            }),
        })
    }
}

/// Why the LSS configuration could not be stored or loaded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum LssStoreError {
    /// The slave has no medium.
    Unsupported,
    /// The medium refused (its own error is the slave's to keep).
    Medium,
    /// What the medium holds is not an LSS image.
    Corrupt,
}

impl fmt::Display for LssStoreError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            LssStoreError::Unsupported => "the LSS slave has no storage medium",
            LssStoreError::Medium => "the storage medium refused the LSS configuration",
            LssStoreError::Corrupt => "the stored LSS configuration is unreadable",
        })
    }
}

impl core::error::Error for LssStoreError {}

/// The medium of a slave that stores nothing: store configuration answers "not supported".
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct NoMedium;

impl ParameterStorage for NoMedium {
    type Error = Infallible;
    fn load(&mut self, _: &mut [u8]) -> Result<Option<usize>, Infallible> {
        Ok(None)
    }
    fn store(&mut self, _: &[u8]) -> Result<(), Infallible> {
        Ok(())
    }
    fn erase(&mut self) -> Result<(), Infallible> {
        Ok(())
    }
}
