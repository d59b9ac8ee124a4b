//! The object dictionary: one interface ([`ObjectDictionary`]) over a static dictionary
//! (compile-time definitions, fixed capacity, no heap) and a dynamic one (`alloc`: entries added
//! and removed at run time, as a master grows its dictionary when slaves join).
//!
//! Values are stored as the little-endian bytes that travel on the bus, so SDO and PDO copy them
//! without conversion. Lookup is a hash on `index << 8 | sub`, independent of dictionary size.
//!
//! ```
//! use duocan_core::od::{Access, Limit, ObjectDef, ObjectDictionary, StaticDictionary};
//! use duocan_core::AbortCode;
//!
//! // A compile-time table: a speed limit (0..=250) and a read-only serial number.
//! static APP: [ObjectDef; 2] = [
//!     ObjectDef::u16(0x2000, 0, Access::Rw, 80)
//!         .limits(Limit::Unsigned(0), Limit::Unsigned(250))
//!         .named("Speed limit"),
//!     ObjectDef::u32(0x2001, 0, Access::Ro, 0x0042_0017).named("Serial number"),
//! ];
//! let mut od = StaticDictionary::<8, 32>::new(); // room for 8 entries, 32 bytes of values
//! od.load(5, &[&APP])?;
//!
//! // Writes as an SDO download would (bytes as on the bus), reads typed.
//! od.write(0x2000, 0, &120u16.to_le_bytes())?;
//! assert_eq!(od.get_value::<u16>(0x2000, 0), Ok(120));
//! assert_eq!(od.get(0x2000, 0)?.name, "Speed limit");
//! // A bad write is refused with the abort code an SDO server would send; the value stays.
//! assert_eq!(od.write(0x2000, 0, &300u16.to_le_bytes()), Err(AbortCode::VALUE_TOO_HIGH));
//! assert_eq!(od.write(0x2001, 0, &[0; 4]), Err(AbortCode::READ_ONLY));
//! assert_eq!(od.read(0x2002, 0), Err(AbortCode::NO_OBJECT));
//! assert_eq!(od.get_value::<u16>(0x2000, 0), Ok(120));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod abort;
mod access;
pub mod comm;
mod def;
#[cfg(feature = "alloc")]
mod dynamic;
pub mod parameters;
mod perfect_index;
mod static_dict;
mod value;

pub use access::ObjectAccess;
pub use def::{key, Access, DataType, DefaultValue, Limit, ObjectDef, ObjectType, WriteHook};
#[cfg(feature = "alloc")]
pub use dynamic::DynamicDictionary;
pub use static_dict::StaticDictionary;
pub use value::{check_value, OdValue};
// Device descriptions write defaults exactly as the dictionary makes them.
#[cfg(feature = "std")]
pub(crate) use value::default_vec;

use crate::od::abort::AbortCode;
use core::fmt;
use core::hash::Hasher;
use core::ops::RangeInclusive;
use parameters::{LoadReport, ParameterGroup, StorageError};

/// Why a dictionary could not be built or extended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BuildError {
    /// The same (index, sub-index) was defined twice.
    Duplicate {
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
    },
    /// The static dictionary's entry capacity is exhausted.
    TooManyEntries {
        /// The capacity.
        capacity: usize,
    },
    /// The static dictionary's value storage is exhausted.
    OutOfStorage {
        /// Index of the entry that did not fit.
        index: u16,
        /// Sub-index of the entry that did not fit.
        sub: u8,
        /// Bytes of storage the dictionary has.
        capacity: usize,
    },
}

impl fmt::Display for BuildError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BuildError::Duplicate { index, sub } => {
                write!(f, "entry {index:#06x}sub{sub} is defined twice")
            }
            BuildError::TooManyEntries { capacity } => write!(
                f,
                "dictionary holds at most {capacity} entries: raise the entry capacity parameter"
            ),
            BuildError::OutOfStorage { index, sub, capacity } => write!(
                f,
                "entry {index:#06x}sub{sub} does not fit the {capacity}-byte value storage: raise the storage parameter"
            ),
        }
    }
}

impl core::error::Error for BuildError {}

/// An entry as found: its definition and its current value bytes.
#[derive(Clone, Copy, Debug)]
pub struct Entry<'a> {
    /// The definition.
    pub def: &'a ObjectDef,
    /// Current value, little-endian.
    pub data: &'a [u8],
    /// The entry's name: the definition's, or the one a [`DynamicDictionary`] holds for an
    /// entry built at run time (from a device description, whose names are not `'static`).
    pub name: &'a str,
    /// The default value's bytes when the dictionary holds them itself (a string or domain
    /// default of an entry built at run time); `None`: the definition's
    /// [`default`](ObjectDef::default) applies.
    pub default_bytes: Option<&'a [u8]>,
}

impl<'a> Entry<'a> {
    /// An entry whose name and default are its definition's.
    #[must_use]
    pub const fn of(def: &'a ObjectDef, data: &'a [u8]) -> Entry<'a> {
        Entry {
            def,
            data,
            name: def.name,
            default_bytes: None,
        }
    }
}

/// What every dictionary provides. Required methods are the storage; the provided ones are the
/// CiA 301 semantics (access rights, type/length/limit checks, hooks) shared by all of them.
pub trait ObjectDictionary {
    /// Looks up (index, sub-index) without any access check. Errors: [`AbortCode::NO_OBJECT`] if
    /// the index is absent, [`AbortCode::NO_SUB_INDEX`] if only the sub-index is.
    fn get(&self, index: u16, sub: u8) -> Result<Entry<'_>, AbortCode>;

    /// Replaces the stored value without any check but capacity (the caller checked).
    fn store(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode>;

    /// Restores the power-on value of every entry whose index is in `range` (reset node / reset
    /// communication): the value it held at the last [`capture_power_on`](Self::capture_power_on),
    /// or its default if there was none (or the entry came later).
    fn reset_range(&mut self, range: RangeInclusive<u16>);

    /// Takes every entry's current value as its power-on value, the one
    /// [`reset_range`](Self::reset_range) restores. A node calls it when it boots, so that what
    /// the application configured before boot survives the NMT resets (CiA 301: the values
    /// after a reset are the power-on values, not the compile-time table).
    ///
    /// All or nothing: a dictionary with bounded room for the image
    /// ([`StaticDictionary`]'s `POWER_ON`) refuses with [`StorageError::TooLarge`] and keeps the
    /// previous image.
    fn capture_power_on(&mut self) -> Result<(), StorageError>;

    /// The node-ID used for `$NODEID`-relative defaults.
    fn node_id(&self) -> u8;

    /// Calls `f` for every entry, in no particular order.
    fn for_each(&self, f: &mut dyn FnMut(Entry<'_>));

    /// Number of entries.
    fn len(&self) -> usize;

    /// True when empty.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// What a read of 0x1010/0x1011 sub 1–4 gives: the [`parameters::capability`] bits. Zero unless
    /// the dictionary has a medium ([`parameters::StoredDictionary`]).
    fn storage_capabilities(&self) -> u32 {
        0
    }

    /// Stores the current values of `group`'s parameters (0x1010 `"save"`), all or nothing.
    fn store_parameters(&mut self, group: ParameterGroup) -> Result<(), StorageError> {
        let _ = group;
        Err(StorageError::Unsupported)
    }

    /// Removes `group` from the stored parameters (0x1011 `"load"`): its defaults apply from
    /// the next reset that reloads it.
    fn restore_defaults(&mut self, group: ParameterGroup) -> Result<(), StorageError> {
        let _ = group;
        Err(StorageError::Unsupported)
    }

    /// Writes the stored values of the entries in `range` into the dictionary (power-on and
    /// resets, after [`reset_range`](Self::reset_range)). Nothing stored is not an error.
    fn load_parameters(&mut self, range: RangeInclusive<u16>) -> Result<LoadReport, StorageError> {
        let _ = range;
        Ok(LoadReport::default())
    }

    /// Reads as an SDO upload would: refuses write-only entries.
    fn read(&self, index: u16, sub: u8) -> Result<&[u8], AbortCode> {
        let e = self.get(index, sub)?;
        if !e.def.access.readable() {
            return Err(AbortCode::WRITE_ONLY);
        }
        Ok(e.data)
    }

    /// Writes as an SDO download would: access right, type, length, limits, hook.
    fn write(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        let e = self.get(index, sub)?;
        if !e.def.access.writable() {
            return Err(AbortCode::READ_ONLY);
        }
        check_value(e.def, data)?;
        self.store(index, sub, data)
    }

    /// Writes as the device itself would: read-only entries may change, but type, length and
    /// limits still hold (a `const` entry never changes).
    fn write_local(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        let e = self.get(index, sub)?;
        if e.def.access == Access::Const {
            return Err(AbortCode::READ_ONLY);
        }
        check_value(e.def, data)?;
        self.store(index, sub, data)
    }

    /// Reads a fixed-size value as `T` (no access check: the device reading its own entry).
    /// [`AbortCode::TYPE_MISMATCH`] if `T` is not the entry's type.
    fn get_value<T: OdValue>(&self, index: u16, sub: u8) -> Result<T, AbortCode>
    where
        Self: Sized,
    {
        let e = self.get(index, sub)?;
        if !value::compatible(e.def.data_type, T::TYPE) {
            return Err(AbortCode::TYPE_MISMATCH);
        }
        T::decode(e.data).ok_or(AbortCode::TYPE_MISMATCH)
    }

    /// Writes a fixed-size value as the device itself (see [`ObjectDictionary::write_local`]).
    fn set_value<T: OdValue>(&mut self, index: u16, sub: u8, v: T) -> Result<(), AbortCode>
    where
        Self: Sized,
    {
        let e = self.get(index, sub)?;
        if !value::compatible(e.def.data_type, T::TYPE) {
            return Err(AbortCode::TYPE_MISMATCH);
        }
        let mut buf = [0u8; 8];
        let n = v.encode(&mut buf);
        self.write_local(index, sub, &buf[..n])
    }

    /// Reads an entry of any unsigned integer type up to 32 bits, widened; for the stack's own
    /// configuration reads (COB-IDs, times), which tolerate U8/U16/U32 variations.
    fn get_u32(&self, index: u16, sub: u8) -> Option<u32> {
        let e = self.get(index, sub).ok()?;
        let mut b = [0u8; 4];
        let n = e.data.len().min(4);
        b[..n].copy_from_slice(&e.data[..n]);
        Some(u32::from_le_bytes(b))
    }
}

/// A dictionary kept somewhere else and lent to its node: on a microcontroller the dictionary
/// of a CiA 302-2 master is tens of kilobytes (an index entry for every node-ID of its arrays),
/// and a node that owns it carries it through every constructor it is moved through, each move a
/// copy on the stack. Kept in a `static` of its own (a [`StaticDictionary`] is `const`-built and
/// loaded in place) and lent as `&'static mut`, it is built once where it lives and the node
/// holds a pointer. Every method is the dictionary's own.
impl<D: ObjectDictionary + ?Sized> ObjectDictionary for &mut D {
    #[inline]
    fn get(&self, index: u16, sub: u8) -> Result<Entry<'_>, AbortCode> {
        (**self).get(index, sub)
    }
    #[inline]
    fn store(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        (**self).store(index, sub, data)
    }
    fn reset_range(&mut self, range: RangeInclusive<u16>) {
        (**self).reset_range(range);
    }
    fn capture_power_on(&mut self) -> Result<(), StorageError> {
        (**self).capture_power_on()
    }
    fn node_id(&self) -> u8 {
        (**self).node_id()
    }
    fn for_each(&self, f: &mut dyn FnMut(Entry<'_>)) {
        (**self).for_each(f);
    }
    fn len(&self) -> usize {
        (**self).len()
    }
    fn is_empty(&self) -> bool {
        (**self).is_empty()
    }
    fn storage_capabilities(&self) -> u32 {
        (**self).storage_capabilities()
    }
    fn store_parameters(&mut self, group: ParameterGroup) -> Result<(), StorageError> {
        (**self).store_parameters(group)
    }
    fn restore_defaults(&mut self, group: ParameterGroup) -> Result<(), StorageError> {
        (**self).restore_defaults(group)
    }
    fn load_parameters(&mut self, range: RangeInclusive<u16>) -> Result<LoadReport, StorageError> {
        (**self).load_parameters(range)
    }
    #[inline]
    fn read(&self, index: u16, sub: u8) -> Result<&[u8], AbortCode> {
        (**self).read(index, sub)
    }
    fn write(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        (**self).write(index, sub, data)
    }
    fn write_local(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        (**self).write_local(index, sub, data)
    }
    #[inline]
    fn get_u32(&self, index: u16, sub: u8) -> Option<u32> {
        (**self).get_u32(index, sub)
    }
}

/// Shared lookup-miss logic: which abort code a missing (index, sub) deserves.
pub(crate) fn miss(has_index: bool) -> AbortCode {
    if has_index {
        AbortCode::NO_SUB_INDEX
    } else {
        AbortCode::NO_OBJECT
    }
}

/// A multiplicative hasher for the 32-bit keys: one multiply, no per-lookup salt. The keys are
/// dictionary addresses chosen by the application, not attacker input, so DoS resistance buys
/// nothing here and costs a third of the lookup time.
#[derive(Default, Clone, Copy)]
pub struct KeyHasher(u64);

impl Hasher for KeyHasher {
    fn finish(&self) -> u64 {
        // Fold the well-mixed high half into the low bits hash tables index with.
        self.0 ^ (self.0 >> 32)
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0.rotate_left(8) ^ b as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
        }
    }
    fn write_u32(&mut self, k: u32) {
        // Fibonacci hashing; hashbrown takes its control byte from the top bits.
        self.0 = (k as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    }
}

impl hash32::Hasher for KeyHasher {
    fn finish32(&self) -> u32 {
        (self.0 >> 32) as u32
    }
}
