//! Entry definitions: data types, access, limits, defaults, hooks. All `const`-constructible so a
//! dictionary's definitions can live in flash as a compile-time table.

use crate::od::abort::AbortCode;

/// CiA 301 data types (the numbers are the type indices of 0x0001–0x001B; `as u16` gives
/// them; one byte each in a definition).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum DataType {
    /// BOOLEAN (1 byte on the wire, 0 or 1).
    Boolean = 0x0001,
    /// INTEGER8.
    Integer8 = 0x0002,
    /// INTEGER16.
    Integer16 = 0x0003,
    /// INTEGER32.
    Integer32 = 0x0004,
    /// UNSIGNED8.
    Unsigned8 = 0x0005,
    /// UNSIGNED16.
    Unsigned16 = 0x0006,
    /// UNSIGNED32.
    Unsigned32 = 0x0007,
    /// REAL32.
    Real32 = 0x0008,
    /// VISIBLE_STRING.
    VisibleString = 0x0009,
    /// OCTET_STRING.
    OctetString = 0x000A,
    /// UNICODE_STRING (UTF-16, little-endian code units on the wire).
    UnicodeString = 0x000B,
    /// TIME_OF_DAY: milliseconds after midnight (28 bits) and days since 1984-01-01 (16 bits),
    /// six bytes on the wire.
    TimeOfDay = 0x000C,
    /// TIME_DIFFERENCE: milliseconds and days as in TIME_OF_DAY, six bytes.
    TimeDifference = 0x000D,
    /// DOMAIN.
    Domain = 0x000F,
    /// INTEGER24.
    Integer24 = 0x0010,
    /// REAL64.
    Real64 = 0x0011,
    /// INTEGER40.
    Integer40 = 0x0012,
    /// INTEGER48.
    Integer48 = 0x0013,
    /// INTEGER56.
    Integer56 = 0x0014,
    /// INTEGER64.
    Integer64 = 0x0015,
    /// UNSIGNED24.
    Unsigned24 = 0x0016,
    /// UNSIGNED40.
    Unsigned40 = 0x0018,
    /// UNSIGNED48.
    Unsigned48 = 0x0019,
    /// UNSIGNED56.
    Unsigned56 = 0x001A,
    /// UNSIGNED64.
    Unsigned64 = 0x001B,
}

impl DataType {
    /// Every data type, in the order of their type indices.
    pub const ALL: [DataType; 25] = {
        use DataType::*;
        [
            Boolean,
            Integer8,
            Integer16,
            Integer32,
            Unsigned8,
            Unsigned16,
            Unsigned32,
            Real32,
            VisibleString,
            OctetString,
            UnicodeString,
            TimeOfDay,
            TimeDifference,
            Domain,
            Integer24,
            Real64,
            Integer40,
            Integer48,
            Integer56,
            Integer64,
            Unsigned24,
            Unsigned40,
            Unsigned48,
            Unsigned56,
            Unsigned64,
        ]
    };

    /// Size in bytes of fixed-size types; `None` for strings and domains.
    pub const fn fixed_size(self) -> Option<usize> {
        use DataType::*;
        match self {
            Boolean | Integer8 | Unsigned8 => Some(1),
            Integer16 | Unsigned16 => Some(2),
            Integer24 | Unsigned24 => Some(3),
            Integer32 | Unsigned32 | Real32 => Some(4),
            Integer40 | Unsigned40 => Some(5),
            Integer48 | Unsigned48 | TimeOfDay | TimeDifference => Some(6),
            Integer56 | Unsigned56 => Some(7),
            Integer64 | Unsigned64 | Real64 => Some(8),
            VisibleString | OctetString | UnicodeString | Domain => None,
        }
    }
    /// Size in bits, as a PDO mapping entry states it; `None` for variable-size types.
    pub const fn bit_size(self) -> Option<u32> {
        match self {
            DataType::Boolean => Some(1),
            _ => match self.fixed_size() {
                Some(n) => Some(n as u32 * 8),
                None => None,
            },
        }
    }
    /// The data type with CiA 301 type index `code`, if it is one this stack supports.
    pub const fn from_code(code: u16) -> Option<DataType> {
        let mut i = 0;
        while i < Self::ALL.len() {
            if Self::ALL[i] as u16 == code {
                return Some(Self::ALL[i]);
            }
            i += 1;
        }
        None
    }
    /// True for the signed integer types (INTEGER8 to INTEGER64).
    pub const fn is_signed(self) -> bool {
        use DataType::*;
        matches!(
            self,
            Integer8
                | Integer16
                | Integer24
                | Integer32
                | Integer40
                | Integer48
                | Integer56
                | Integer64
        )
    }
    /// True for REAL32 and REAL64.
    pub const fn is_real(self) -> bool {
        matches!(self, DataType::Real32 | DataType::Real64)
    }
}

/// Access right of an entry, as seen from the bus (SDO). The stack itself may update read-only
/// entries (error register, error history) through the dictionary's local write.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Access {
    /// Read only; may change at run time (e.g. 0x1001).
    Ro,
    /// Write only.
    Wo,
    /// Read and write.
    Rw,
    /// Read only and never changes.
    Const,
}

impl Access {
    /// True if an SDO upload may read it.
    pub const fn readable(self) -> bool {
        !matches!(self, Access::Wo)
    }
    /// True if an SDO download may write it.
    pub const fn writable(self) -> bool {
        matches!(self, Access::Wo | Access::Rw)
    }
}

/// The object an entry belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ObjectType {
    /// A single value at sub-index 0.
    Var,
    /// Sub 0 holds the count; subs 1.. share one type.
    Array,
    /// Sub 0 holds the highest sub-index; subs 1.. have their own types.
    Record,
}

/// A default value. `NodeIdPlus(x)` is `x + node-ID`, the CiA 306 `$NODEID+x` form, so one
/// compile-time table serves every node.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DefaultValue {
    /// All-zero bytes (empty for strings and domains).
    Zero,
    /// An unsigned number (also booleans).
    Unsigned(u64),
    /// A signed number.
    Signed(i64),
    /// A floating-point number.
    Real(f64),
    /// Raw bytes (strings, domains).
    Bytes(&'static [u8]),
    /// `x + node-ID`.
    NodeIdPlus(u32),
}

/// A value limit, compared in the entry's own type.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Limit {
    /// For unsigned types.
    Unsigned(u64),
    /// For signed types.
    Signed(i64),
    /// For real types.
    Real(f64),
}

/// A hook that may veto a write: it sees the new value (already type- and limit-checked) and
/// answers with the abort code to refuse it. Plain function pointers keep the table `const` and
/// `no_std`; reactions to accepted writes are events ([`crate::node::NodeEvent`]), not callbacks.
pub type WriteHook = fn(index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode>;

/// A number's 64 bits as two halves: a `u64` in a definition would make every definition
/// 8-aligned and pad it (a dictionary of a thousand entries is that many definitions in flash).
#[derive(Clone, Copy, PartialEq)]
struct Bits([u32; 2]);

impl Bits {
    const ZERO: Bits = Bits([0; 2]);
    const fn of(v: u64) -> Bits {
        Bits([v as u32, (v >> 32) as u32])
    }
    const fn get(self) -> u64 {
        self.0[0] as u64 | (self.0[1] as u64) << 32
    }
}

/// A [`DefaultValue`] as a definition holds it: 4-aligned, 12 bytes instead of 16.
#[derive(Clone, Copy)]
enum StoredDefault {
    Zero,
    Unsigned(Bits),
    Signed(Bits),
    Real(Bits),
    Bytes(&'static [u8]),
    NodeIdPlus(u32),
}

/// The kind of a limit in [`ObjectDef::limit_kinds`]: two bits each, low then high.
const NO_LIMIT: u8 = 0;
const UNSIGNED: u8 = 1;
const SIGNED: u8 = 2;
const REAL: u8 = 3;

const fn limit_parts(l: Option<Limit>) -> (u8, Bits) {
    match l {
        None => (NO_LIMIT, Bits::ZERO),
        Some(Limit::Unsigned(v)) => (UNSIGNED, Bits::of(v)),
        Some(Limit::Signed(v)) => (SIGNED, Bits::of(v as u64)),
        Some(Limit::Real(v)) => (REAL, Bits::of(v.to_bits())),
    }
}

const fn limit_of(kind: u8, bits: Bits) -> Option<Limit> {
    match kind & 3 {
        UNSIGNED => Some(Limit::Unsigned(bits.get())),
        SIGNED => Some(Limit::Signed(bits.get() as i64)),
        REAL => Some(Limit::Real(f64::from_bits(bits.get()))),
        _ => None,
    }
}

/// The definition of one dictionary entry (index, sub-index).
///
/// Built with `const` constructors and builders ([`ObjectDef::u32`], [`ObjectDef::new`],
/// [`access`](ObjectDef::access), [`default`](ObjectDef::default),
/// [`limits`](ObjectDef::limits), …), so that a table of them lives in flash. The default and
/// the limits are kept compactly (no 8-byte alignment: 52 bytes a definition on a 32-bit
/// target) and read through [`default_value`](ObjectDef::default_value),
/// [`low`](ObjectDef::low) and [`high`](ObjectDef::high).
#[derive(Clone, Copy)]
pub struct ObjectDef {
    /// Object index.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// The kind of object the entry belongs to.
    pub object_type: ObjectType,
    /// Data type.
    pub data_type: DataType,
    /// Access right from the bus.
    pub access: Access,
    /// May be mapped into a PDO.
    pub pdo_mappable: bool,
    /// The kinds of the low (bits 0–1) and high (bits 2–3) limits.
    limit_kinds: u8,
    /// Value after reset.
    default: StoredDefault,
    /// Lowest accepted value (numeric types), as its kind says.
    low: Bits,
    /// Highest accepted value (numeric types), as its kind says.
    high: Bits,
    /// Largest size in bytes for strings and domains (fixed types ignore it).
    pub capacity: u32,
    /// Human-readable name (EDS `ParameterName`).
    pub name: &'static str,
    /// Optional veto on writes.
    pub hook: Option<WriteHook>,
}

impl core::fmt::Debug for ObjectDef {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("ObjectDef")
            .field("index", &self.index)
            .field("sub", &self.sub)
            .field("object_type", &self.object_type)
            .field("data_type", &self.data_type)
            .field("access", &self.access)
            .field("pdo_mappable", &self.pdo_mappable)
            .field("default", &self.default_value())
            .field("low", &self.low())
            .field("high", &self.high())
            .field("capacity", &self.capacity)
            .field("name", &self.name)
            .field("hook", &self.hook)
            .finish()
    }
}

impl ObjectDef {
    /// A VAR entry with a zero default, read-write, not mappable.
    #[must_use]
    pub const fn new(index: u16, sub: u8, data_type: DataType) -> ObjectDef {
        ObjectDef {
            index,
            sub,
            object_type: ObjectType::Var,
            data_type,
            access: Access::Rw,
            pdo_mappable: false,
            limit_kinds: 0,
            default: StoredDefault::Zero,
            low: Bits::ZERO,
            high: Bits::ZERO,
            capacity: 0,
            name: "",
            hook: None,
        }
    }
    /// UNSIGNED8 entry with a default.
    #[must_use]
    pub const fn u8(index: u16, sub: u8, access: Access, default: u8) -> ObjectDef {
        ObjectDef::new(index, sub, DataType::Unsigned8)
            .access(access)
            .default(DefaultValue::Unsigned(default as u64))
    }
    /// UNSIGNED16 entry with a default.
    #[must_use]
    pub const fn u16(index: u16, sub: u8, access: Access, default: u16) -> ObjectDef {
        ObjectDef::new(index, sub, DataType::Unsigned16)
            .access(access)
            .default(DefaultValue::Unsigned(default as u64))
    }
    /// UNSIGNED32 entry with a default.
    #[must_use]
    pub const fn u32(index: u16, sub: u8, access: Access, default: u32) -> ObjectDef {
        ObjectDef::new(index, sub, DataType::Unsigned32)
            .access(access)
            .default(DefaultValue::Unsigned(default as u64))
    }
    /// A string or domain entry holding at most `capacity` bytes.
    #[must_use]
    pub const fn bytes(index: u16, sub: u8, data_type: DataType, capacity: u32) -> ObjectDef {
        ObjectDef::new(index, sub, data_type).capacity(capacity)
    }
    /// Sets the access right.
    #[must_use]
    pub const fn access(mut self, access: Access) -> ObjectDef {
        self.access = access;
        self
    }
    /// Sets the default value.
    #[must_use]
    pub const fn default(mut self, default: DefaultValue) -> ObjectDef {
        self.default = match default {
            DefaultValue::Zero => StoredDefault::Zero,
            DefaultValue::Unsigned(v) => StoredDefault::Unsigned(Bits::of(v)),
            DefaultValue::Signed(v) => StoredDefault::Signed(Bits::of(v as u64)),
            DefaultValue::Real(v) => StoredDefault::Real(Bits::of(v.to_bits())),
            DefaultValue::Bytes(b) => StoredDefault::Bytes(b),
            DefaultValue::NodeIdPlus(v) => StoredDefault::NodeIdPlus(v),
        };
        self
    }
    /// Marks the entry PDO-mappable.
    #[must_use]
    pub const fn mappable(mut self) -> ObjectDef {
        self.pdo_mappable = true;
        self
    }
    /// Sets the object type (for sub-entries of arrays and records).
    #[must_use]
    pub const fn object_type(mut self, t: ObjectType) -> ObjectDef {
        self.object_type = t;
        self
    }
    /// Sets the accepted range.
    #[must_use]
    pub const fn limits(self, low: Limit, high: Limit) -> ObjectDef {
        self.bounds(Some(low), Some(high))
    }
    /// Sets the lowest and the highest accepted value, each optional (`None`: no limit).
    #[must_use]
    pub const fn bounds(mut self, low: Option<Limit>, high: Option<Limit>) -> ObjectDef {
        let (lk, lb) = limit_parts(low);
        let (hk, hb) = limit_parts(high);
        self.limit_kinds = lk | hk << 2;
        self.low = lb;
        self.high = hb;
        self
    }
    /// Sets the largest size in bytes of a string or domain value.
    #[must_use]
    pub const fn capacity(mut self, capacity: u32) -> ObjectDef {
        self.capacity = capacity;
        self
    }
    /// Sets the name.
    #[must_use]
    pub const fn named(mut self, name: &'static str) -> ObjectDef {
        self.name = name;
        self
    }
    /// Installs a write veto hook.
    #[must_use]
    pub const fn hook(mut self, hook: WriteHook) -> ObjectDef {
        self.hook = Some(hook);
        self
    }
    /// Installs or removes a write veto hook.
    #[must_use]
    pub const fn with_hook(mut self, hook: Option<WriteHook>) -> ObjectDef {
        self.hook = hook;
        self
    }
    /// The value after reset.
    pub const fn default_value(&self) -> DefaultValue {
        match self.default {
            StoredDefault::Zero => DefaultValue::Zero,
            StoredDefault::Unsigned(b) => DefaultValue::Unsigned(b.get()),
            StoredDefault::Signed(b) => DefaultValue::Signed(b.get() as i64),
            StoredDefault::Real(b) => DefaultValue::Real(f64::from_bits(b.get())),
            StoredDefault::Bytes(b) => DefaultValue::Bytes(b),
            StoredDefault::NodeIdPlus(v) => DefaultValue::NodeIdPlus(v),
        }
    }
    /// The lowest accepted value (numeric types), if limited.
    pub const fn low(&self) -> Option<Limit> {
        limit_of(self.limit_kinds, self.low)
    }
    /// The highest accepted value (numeric types), if limited.
    pub const fn high(&self) -> Option<Limit> {
        limit_of(self.limit_kinds >> 2, self.high)
    }
    /// True if the entry has a low or a high limit.
    pub const fn is_limited(&self) -> bool {
        self.limit_kinds != 0
    }
    /// The dictionary key: `index << 8 | sub`.
    pub const fn key(&self) -> u32 {
        key(self.index, self.sub)
    }
    /// Bytes needed to hold the value: the fixed size or the capacity.
    pub const fn storage_size(&self) -> usize {
        match self.data_type.fixed_size() {
            Some(n) => n,
            None => self.capacity as usize,
        }
    }
}

/// The dictionary key of (index, sub-index).
#[inline(always)]
pub const fn key(index: u16, sub: u8) -> u32 {
    ((index as u32) << 8) | sub as u32
}

// What keeps a thousand-entry dictionary in flash small: a definition stays 52 bytes on a
// 32-bit target (it was 72 with 8-aligned defaults and limits).
#[cfg(target_pointer_width = "32")]
const _: () = assert!(core::mem::size_of::<ObjectDef>() <= 52);

#[cfg(test)]
#[path = "def_tests.rs"]
mod tests;
