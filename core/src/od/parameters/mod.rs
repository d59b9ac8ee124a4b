//! Parameter storage: 0x1010 store parameters and 0x1011 restore default parameters.
//!
//! # The model (CiA 301)
//!
//! Three sets of values meet here:
//!
//! - **The power-on image**: what the application configured before [`Node::boot`] (a board
//!   setting 0x1017 = 1000 ms in its start-up code), on top of the compile-time defaults of the
//!   definition tables. The dictionary keeps it ([`ObjectDictionary::capture_power_on`]); from
//!   the bus's point of view it is the device's *default* configuration.
//! - **The stored image**: the parameters a client (or the application) stored with the
//!   signature `"save"` (0x65766173, written as UNSIGNED32) to 0x1010. It lives on a
//!   [`ParameterStorage`] medium and survives power cycles.
//! - **The current values**: what the dictionary holds now. A value written later over SDO is
//!   volatile: the next reset that covers its index forgets it unless it was stored.
//!
//! Each reset reloads its area from the power-on image and then from the stored image:
//! reset-communication the communication area (0x1000–0x1FFF), reset-node every area
//! (0x1000–0xFFFF), power-on ([`Node::boot`]) likewise. Restoring defaults (the signature
//! `"load"`, 0x64616F6C, to 0x1011) removes a group from the stored image; as CiA 301 says, the
//! defaults take effect at the next reset that reloads the group (reset-node for every group,
//! reset-communication for the communication group), not at once.
//!
//! The sub-indices of both objects name the groups ([`ParameterGroup`]): 1 all parameters,
//! 2 communication (0x1000–0x1FFF), 3 application (0x6000–0x9FFF), 4 this stack's
//! manufacturer-specific group, the manufacturer-specific profile area (0x2000–0x5FFF), which
//! CiA 301 leaves to the manufacturer (sub-indices 4–0x7F). A parameter is an entry the bus may
//! write ([`is_parameter`]), not the error history nor the two command objects themselves.
//!
//! Reading a sub-index gives the capability bits: bit 0 ([`capability::ON_COMMAND`]) the
//! device stores (or restores) on command, bit 1 ([`capability::AUTONOMOUS`]) it stores by
//! itself; this stack stores only on command, and only when the dictionary has a medium
//! ([`StoredDictionary`]).
//!
//! # Abort codes
//!
//! A wrong signature, or a group this stack does not define, is refused with 0x08000020 and
//! changes nothing. A dictionary without a medium refuses with 0x08000020 too (it cannot store).
//! A store or restore that fails on the medium, or whose image does not fit the buffer,
//! answers 0x06060000 (access failed due to a hardware error): CiA 301 names that code for a
//! failed store or restore; 0x08000021 (local control) and 0x08000022 (device state) would
//! tell the client to retry later or in another state, which does not help a medium that
//! refused.
//!
//! # All or nothing
//!
//! The medium holds one image of every stored parameter, written whole: storing a group reads
//! the image, replaces that group's entries with the current values and writes the result in
//! one [`ParameterStorage::store`], which a medium does atomically (the file backend writes a
//! temporary file, syncs it and renames it over the old one; a flash driver writes the other of
//! two sectors and switches over). So a failed store leaves the previous image intact and
//! overlapping groups (all versus communication) never disagree. Memory is bounded: the image
//! of a dictionary is at most [`image_capacity`] of its entries and value bytes, and
//! [`StoredDictionary`] holds it in a fixed buffer.
//!
//! [`Node::boot`]: crate::node::Node::boot
//! [`ObjectDictionary::capture_power_on`]: super::ObjectDictionary::capture_power_on

#[cfg(feature = "std")]
mod file;
mod image;
mod memory;
mod stored;

#[cfg(feature = "std")]
pub use file::{FileStorage, FileStorageError, FileStorageOp};
pub use image::{crc32, image_capacity, image_size, ImageError, ENTRY_OVERHEAD, IMAGE_OVERHEAD};
pub use memory::{MemoryStorage, MemoryStorageError};
pub use stored::StoredDictionary;

use super::comm;
use super::def::ObjectDef;
use crate::od::abort::AbortCode;
use core::fmt;
use core::ops::RangeInclusive;

/// The signature that stores parameters when written to 0x1010: `"save"` read as a
/// little-endian UNSIGNED32.
pub const SAVE: u32 = u32::from_le_bytes(*b"save");
/// The signature that restores defaults when written to 0x1011: `"load"`.
pub const LOAD: u32 = u32::from_le_bytes(*b"load");

/// The bits a read of a 0x1010/0x1011 sub-index gives.
pub mod capability {
    /// The device stores (restores) this group on command.
    pub const ON_COMMAND: u32 = 0x01;
    /// The device stores this group by itself (0x1010 only; this stack never does).
    pub const AUTONOMOUS: u32 = 0x02;
}

/// A group of parameters, as the sub-indices of 0x1010 and 0x1011 name them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ParameterGroup {
    /// Sub-index 1: every parameter (0x1000–0xFFFF).
    All,
    /// Sub-index 2: the communication parameters (0x1000–0x1FFF).
    Communication,
    /// Sub-index 3: the application parameters of the standardised profile area
    /// (0x6000–0x9FFF).
    Application,
    /// Sub-index 4: this stack's manufacturer-specific group, the manufacturer-specific profile
    /// area (0x2000–0x5FFF).
    Manufacturer,
}

impl ParameterGroup {
    /// Every group, by sub-index.
    pub const ALL: [ParameterGroup; 4] = [
        ParameterGroup::All,
        ParameterGroup::Communication,
        ParameterGroup::Application,
        ParameterGroup::Manufacturer,
    ];

    /// The group sub-index `sub` of 0x1010/0x1011 names; `None` for 0 and for sub-indices this
    /// stack does not define (5–0xFE).
    pub const fn from_sub(sub: u8) -> Option<ParameterGroup> {
        Some(match sub {
            1 => ParameterGroup::All,
            2 => ParameterGroup::Communication,
            3 => ParameterGroup::Application,
            4 => ParameterGroup::Manufacturer,
            _ => return None,
        })
    }

    /// Its sub-index in 0x1010/0x1011.
    pub const fn sub(self) -> u8 {
        match self {
            ParameterGroup::All => 1,
            ParameterGroup::Communication => 2,
            ParameterGroup::Application => 3,
            ParameterGroup::Manufacturer => 4,
        }
    }

    /// The indices it covers.
    pub const fn range(self) -> RangeInclusive<u16> {
        match self {
            ParameterGroup::All => 0x1000..=0xFFFF,
            ParameterGroup::Communication => 0x1000..=0x1FFF,
            ParameterGroup::Application => 0x6000..=0x9FFF,
            ParameterGroup::Manufacturer => 0x2000..=0x5FFF,
        }
    }

    /// True if `index` belongs to the group.
    pub const fn contains(self, index: u16) -> bool {
        let r = self.range();
        index >= *r.start() && index <= *r.end()
    }
}

impl fmt::Display for ParameterGroup {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            ParameterGroup::All => "all parameters",
            ParameterGroup::Communication => "communication parameters (0x1000-0x1FFF)",
            ParameterGroup::Application => "application parameters (0x6000-0x9FFF)",
            ParameterGroup::Manufacturer => "manufacturer parameters (0x2000-0x5FFF)",
        })
    }
}

/// True if the entry is a parameter that storing keeps: one the bus may write, except the error
/// history (0x1003, a record of events) and 0x1010/0x1011 (commands, not configuration).
pub const fn is_parameter(def: &ObjectDef) -> bool {
    def.access.writable()
        && !matches!(
            def.index,
            comm::ERROR_HISTORY | comm::STORE_PARAMETERS | comm::RESTORE_DEFAULTS
        )
}

/// A non-volatile medium for the stored image (a flash sector pair, an EEPROM, a file).
///
/// The node never calls it on the frame path except for the three operations below, each on a
/// 0x1010/0x1011 command or a reset. It sees one opaque image (a few hundred bytes for a
/// typical slave); what the bytes mean is [`StoredDictionary`]'s business.
pub trait ParameterStorage {
    /// What went wrong, in the medium's own words.
    type Error: core::error::Error;

    /// Reads the stored image into `buf`: `Ok(None)` when nothing is stored, `Ok(Some(n))` for
    /// an image of `n` bytes. An image longer than `buf` is an error (the medium says so).
    fn load(&mut self, buf: &mut [u8]) -> Result<Option<usize>, Self::Error>;

    /// Replaces the stored image with `image`, all or nothing: when this returns an error, the
    /// previous image (or none) is what [`load`](Self::load) gives, never a mix or a torn
    /// write.
    fn store(&mut self, image: &[u8]) -> Result<(), Self::Error>;

    /// Removes the stored image; afterwards [`load`](Self::load) gives `Ok(None)`.
    fn erase(&mut self) -> Result<(), Self::Error>;
}

/// Why a store, restore or load of parameters did not happen.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum StorageError {
    /// The dictionary has no medium to store on.
    Unsupported,
    /// The image does not fit the buffer (or the medium) it must pass through.
    TooLarge {
        /// Bytes the image needs.
        needed: u32,
        /// Bytes there are.
        capacity: u32,
    },
    /// The medium refused to read, write or erase (its own error says why:
    /// [`StoredDictionary::last_error`]).
    Medium,
    /// What the medium holds is not a stored image this stack can read.
    Corrupt(ImageError),
}

impl StorageError {
    /// The SDO abort code a 0x1010/0x1011 write that failed this way answers.
    pub const fn abort_code(self) -> AbortCode {
        match self {
            // Nothing to store on: the data cannot be stored (no retry helps).
            StorageError::Unsupported => AbortCode::CANNOT_STORE,
            // CiA 301: a store or restore that failed is answered with a hardware error.
            _ => AbortCode::HARDWARE_ERROR,
        }
    }
}

impl fmt::Display for StorageError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            StorageError::Unsupported => f.write_str("the dictionary has no parameter storage"),
            StorageError::TooLarge { needed, capacity } => write!(
                f,
                "the image needs {needed} bytes, there is room for {capacity}: raise the capacity"
            ),
            StorageError::Medium => f.write_str("the storage medium failed"),
            StorageError::Corrupt(e) => write!(f, "the stored image is unreadable: {e}"),
        }
    }
}

impl core::error::Error for StorageError {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        match self {
            StorageError::Corrupt(e) => Some(e),
            _ => None,
        }
    }
}

/// A byte count as the errors carry it: 32 bits keep the node's events small, and no image
/// comes near 4 GiB (saturates if one did).
pub(crate) fn bytes(n: usize) -> u32 {
    u32::try_from(n).unwrap_or(u32::MAX)
}

/// What loading the stored image did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LoadReport {
    /// Stored values written into the dictionary.
    pub applied: u16,
    /// Stored values left out: the entry no longer exists, is no longer a parameter, or the
    /// value no longer fits its definition (a firmware update changed the dictionary).
    pub skipped: u16,
}
