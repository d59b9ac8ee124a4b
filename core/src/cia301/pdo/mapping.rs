//! PDO mapping: the entries of 0x16xx/0x1Axx, their validation against the dictionary, and the
//! bit-granular packing of values into (and out of) the at most 64 bits of a classic CAN frame.
//!
//! Bits are numbered as CiA 301 numbers them: bit 0 is the least significant bit of data byte 0,
//! bit 8 the least significant bit of byte 1, and an entry's value occupies consecutive bits from
//! its least significant bit up. Because a whole PDO is at most 64 bits, the frame is handled as
//! one little-endian `u64` and every entry is a shift and a mask.

use crate::od::abort::AbortCode;
use crate::od::{DataType, ObjectDictionary};

/// Largest number of bits (and entries) one PDO carries.
pub const MAX_BITS: u32 = 64;
/// Largest number of mapping entries (sub 0 of a mapping parameter).
pub const MAX_ENTRIES: u8 = 64;
/// Entries cached inside the engine per PDO; longer (bit-granular) mappings are read from the
/// dictionary at use, which is correct but slower.
pub(crate) const CACHED: usize = 8;

/// Which side of a PDO: it decides which accesses a mapped entry needs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Dir {
    /// RPDO: received, written into the dictionary (entries must be writable).
    Receive,
    /// TPDO: read from the dictionary, transmitted (entries must be readable).
    Transmit,
}

/// One mapping entry as 0x16xx/0x1Axx sub 1.. hold it: `index << 16 | sub << 8 | bits`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct MapEntry {
    /// Object index (0x0001–0x001B with sub 0: dummy entry of that data type).
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// Length in bits.
    pub bits: u8,
}

impl MapEntry {
    /// An entry mapping `bits` bits of (index, sub).
    #[must_use]
    pub const fn new(index: u16, sub: u8, bits: u8) -> MapEntry {
        MapEntry { index, sub, bits }
    }
    /// A dummy entry of `bits` bits of data type `t` (placeholder in an RPDO).
    #[must_use]
    pub const fn dummy(t: DataType, bits: u8) -> MapEntry {
        MapEntry::new(t as u16, 0, bits)
    }
    /// Decodes the 32-bit dictionary value.
    #[must_use]
    pub const fn from_raw(raw: u32) -> MapEntry {
        MapEntry {
            index: (raw >> 16) as u16,
            sub: (raw >> 8) as u8,
            bits: raw as u8,
        }
    }
    /// The 32-bit dictionary value.
    pub const fn raw(self) -> u32 {
        ((self.index as u32) << 16) | ((self.sub as u32) << 8) | self.bits as u32
    }
    /// True for a reference to a data-type index (0x0001–0x001F, sub 0): a placeholder whose
    /// bits are skipped on reception and sent as zeros.
    pub const fn is_dummy(self) -> bool {
        self.index >= 1 && self.index < 0x20 && self.sub == 0
    }
}

/// Checks one entry against the dictionary: the object exists (0x06020000 / 0x06090011), may be
/// mapped in this direction (0x06040041: flag, access right), and the length fits the object
/// (0x06040041). Dummy entries need a fixed-size data type this stack supports and a length up to
/// that type's size. A zero-length entry is 0x06090030.
pub fn check_entry<D: ObjectDictionary + ?Sized>(
    od: &D,
    dir: Dir,
    e: MapEntry,
) -> Result<(), AbortCode> {
    if e.bits == 0 {
        return Err(AbortCode::VALUE_RANGE);
    }
    if e.is_dummy() {
        return match DataType::from_code(e.index).and_then(DataType::bit_size) {
            Some(n) if e.bits as u32 <= n => Ok(()),
            _ => Err(AbortCode::NOT_MAPPABLE),
        };
    }
    let entry = od.get(e.index, e.sub)?;
    let def = entry.def;
    let access_ok = match dir {
        Dir::Receive => def.access.writable(),
        Dir::Transmit => def.access.readable(),
    };
    if !def.pdo_mappable || !access_ok {
        return Err(AbortCode::NOT_MAPPABLE);
    }
    let fits = match def.data_type.bit_size() {
        Some(n) => e.bits as u32 <= n,
        // Strings and domains: whole bytes, at most their capacity.
        None => e.bits.is_multiple_of(8) && (e.bits / 8) as u32 <= def.capacity,
    };
    if fits {
        Ok(())
    } else {
        Err(AbortCode::NOT_MAPPABLE)
    }
}

/// Checks a whole mapping (entries 1..=n as `entries` yields them): every entry, then the total
/// length (0x06040042 beyond 64 bits, as beyond 64 entries). Returns the total bit count.
pub fn check_mapping<D: ObjectDictionary + ?Sized>(
    od: &D,
    dir: Dir,
    entries: impl IntoIterator<Item = MapEntry>,
) -> Result<u32, AbortCode> {
    let mut bits = 0u32;
    for (n, e) in entries.into_iter().enumerate() {
        if n >= MAX_ENTRIES as usize {
            return Err(AbortCode::PDO_LENGTH);
        }
        check_entry(od, dir, e)?;
        bits += e.bits as u32;
        if bits > MAX_BITS {
            return Err(AbortCode::PDO_LENGTH);
        }
    }
    Ok(bits)
}

/// A mask of the `len` low bits (`len` ≤ 64).
#[inline(always)]
pub const fn mask(len: u32) -> u64 {
    if len >= 64 {
        u64::MAX
    } else {
        (1u64 << len) - 1
    }
}

/// Reads `len` bits at bit `offset` of a PDO payload (CiA 301 bit order). Bits beyond 64 read as
/// zero; nothing panics.
#[inline]
pub fn read_bits(payload: &[u8; 8], offset: u32, len: u32) -> u64 {
    let all = u64::from_le_bytes(*payload);
    all.checked_shr(offset).unwrap_or(0) & mask(len)
}

/// Writes the `len` low bits of `value` at bit `offset` of a PDO payload (CiA 301 bit order),
/// leaving the other bits as they were. Bits that would fall beyond 64 are dropped.
#[inline]
pub fn write_bits(payload: &mut [u8; 8], offset: u32, len: u32, value: u64) {
    let m = mask(len).checked_shl(offset).unwrap_or(0);
    let v = (value & mask(len)).checked_shl(offset).unwrap_or(0);
    let all = (u64::from_le_bytes(*payload) & !m) | v;
    *payload = all.to_le_bytes();
}

/// The little-endian bytes of a stored value widened to `u64` (shorter values zero-extended,
/// longer ones truncated: mapped lengths never exceed 64 bits).
#[inline(always)]
pub(crate) fn le_u64(data: &[u8]) -> u64 {
    let mut b = [0u8; 8];
    let n = data.len().min(8);
    b[..n].copy_from_slice(&data[..n]);
    u64::from_le_bytes(b)
}

/// The cached part of a PDO's mapping: the first [`CACHED`] entries, the count and total length.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Mapping {
    entries: [MapEntry; CACHED],
    count: u8,
    bits: u8,
}

impl Mapping {
    /// No entries.
    pub(crate) const EMPTY: Mapping = Mapping {
        entries: [MapEntry::new(0, 0, 0); CACHED],
        count: 0,
        bits: 0,
    };

    /// A mapping of at most [`CACHED`] entries (more are cut), unchecked: for tests, and for
    /// the SRDO, whose two halves are at most eight entries each and checked by its own rules.
    pub(crate) fn with(entries: &[MapEntry]) -> Mapping {
        let entries = &entries[..entries.len().min(CACHED)];
        let mut m = Mapping::EMPTY;
        for (slot, e) in m.entries.iter_mut().zip(entries) {
            *slot = *e;
        }
        m.count = entries.len() as u8;
        m.bits = entries.iter().fold(0u8, |a, e| a.saturating_add(e.bits));
        m
    }

    /// Reads and checks the mapping stored at `map_index`. `Ok` with an empty mapping when the
    /// object does not exist.
    pub(crate) fn load<D: ObjectDictionary + ?Sized>(
        od: &D,
        dir: Dir,
        map_index: u16,
    ) -> Result<Mapping, AbortCode> {
        let Some(count) = od.get_u32(map_index, 0) else {
            return Ok(Mapping::default());
        };
        if count > MAX_ENTRIES as u32 {
            return Err(AbortCode::PDO_LENGTH);
        }
        let count = count as u8;
        let mut m = Mapping {
            count,
            ..Mapping::default()
        };
        let mut bits = 0u32;
        for s in 1..=count {
            let raw = od.get_u32(map_index, s).ok_or(AbortCode::NO_SUB_INDEX)?;
            let e = MapEntry::from_raw(raw);
            check_entry(od, dir, e)?;
            bits += e.bits as u32;
            if bits > MAX_BITS {
                return Err(AbortCode::PDO_LENGTH);
            }
            if let Some(slot) = m.entries.get_mut(s as usize - 1) {
                *slot = e;
            }
        }
        m.bits = bits as u8;
        Ok(m)
    }

    /// Number of mapped entries.
    pub(crate) fn count(&self) -> u8 {
        self.count
    }
    /// Total mapped bits.
    pub(crate) fn bits(&self) -> u32 {
        self.bits as u32
    }
    /// Bytes a frame must carry.
    pub(crate) fn bytes(&self) -> u8 {
        self.bits.div_ceil(8)
    }

    /// Entry `k` (0-based): from the cache, or from the dictionary for long mappings.
    #[inline]
    pub(crate) fn entry<D: ObjectDictionary + ?Sized>(
        &self,
        od: &D,
        map_index: u16,
        k: u8,
    ) -> MapEntry {
        match self.entries.get(k as usize) {
            Some(e) => *e,
            None => MapEntry::from_raw(od.get_u32(map_index, k + 1).unwrap_or(0)),
        }
    }

    /// Builds a payload from the current dictionary values. Returns the byte count. An entry
    /// removed from a dynamic dictionary since validation sends zeros.
    pub(crate) fn pack<D: ObjectDictionary + ?Sized>(
        &self,
        od: &D,
        map_index: u16,
        out: &mut [u8; 8],
    ) -> u8 {
        let mut acc = 0u64;
        let mut off = 0u32;
        for k in 0..self.count {
            let e = self.entry(od, map_index, k);
            let len = e.bits as u32;
            if !e.is_dummy() {
                if let Ok(en) = od.get(e.index, e.sub) {
                    acc |= (le_u64(en.data) & mask(len)).checked_shl(off).unwrap_or(0);
                }
            }
            off += len;
        }
        *out = acc.to_le_bytes();
        self.bytes()
    }

    /// Writes a received payload into the dictionary, calling `written` for every entry stored.
    /// Values shorter than their object are zero-extended, or sign-extended for signed integers.
    pub(crate) fn unpack<D: ObjectDictionary + ?Sized>(
        &self,
        od: &mut D,
        map_index: u16,
        payload: &[u8; 8],
        mut written: impl FnMut(u16, u8),
    ) {
        let all = u64::from_le_bytes(*payload);
        let mut off = 0u32;
        for k in 0..self.count {
            let e = self.entry(od, map_index, k);
            let len = e.bits as u32;
            let raw = all.checked_shr(off).unwrap_or(0) & mask(len);
            off += len;
            if e.is_dummy() {
                continue;
            }
            let Ok(en) = od.get(e.index, e.sub) else {
                continue;
            };
            let t = en.def.data_type;
            let size = match t.fixed_size() {
                Some(n) => n,
                None => (len / 8) as usize,
            };
            let v = if t.is_signed() && len < 64 && len > 0 && raw >> (len - 1) & 1 == 1 {
                raw | !mask(len)
            } else {
                raw
            };
            let bytes = v.to_le_bytes();
            if od.store(e.index, e.sub, &bytes[..size.min(8)]).is_ok() {
                written(e.index, e.sub);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::od::{Access, DynamicDictionary, ObjectDef};

    fn od() -> DynamicDictionary {
        DynamicDictionary::from_tables(
            1,
            &[&[
                ObjectDef::u8(0x2000, 0, Access::Rw, 0).mappable(),
                ObjectDef::u16(0x2001, 0, Access::Ro, 0).mappable(),
                ObjectDef::u32(0x2002, 0, Access::Rw, 0),
                ObjectDef::new(0x2003, 0, DataType::Integer16)
                    .mappable()
                    .access(Access::Rw),
                ObjectDef::bytes(0x2004, 0, DataType::VisibleString, 4).mappable(),
            ]],
        )
        .unwrap()
    }

    #[test]
    fn raw_round_trip_and_dummy_detection() {
        let e = MapEntry::from_raw(0x6000_0108);
        assert_eq!(e, MapEntry::new(0x6000, 1, 8));
        assert_eq!(e.raw(), 0x6000_0108);
        assert!(MapEntry::from_raw(0x0005_0008).is_dummy());
        assert!(!MapEntry::from_raw(0x0005_0108).is_dummy());
        assert!(!MapEntry::from_raw(0x2000_0008).is_dummy());
    }

    #[test]
    fn entry_checks_give_the_cia_codes() {
        let od = od();
        let rx = Dir::Receive;
        assert_eq!(check_entry(&od, rx, MapEntry::new(0x2000, 0, 8)), Ok(()));
        assert_eq!(check_entry(&od, rx, MapEntry::new(0x2000, 0, 3)), Ok(()));
        assert_eq!(
            check_entry(&od, rx, MapEntry::new(0x2000, 0, 9)),
            Err(AbortCode::NOT_MAPPABLE)
        );
        assert_eq!(
            check_entry(&od, rx, MapEntry::new(0x3000, 0, 8)),
            Err(AbortCode::NO_OBJECT)
        );
        assert_eq!(
            check_entry(&od, rx, MapEntry::new(0x2002, 0, 32)),
            Err(AbortCode::NOT_MAPPABLE),
            "not flagged mappable"
        );
        assert_eq!(
            check_entry(&od, rx, MapEntry::new(0x2001, 0, 16)),
            Err(AbortCode::NOT_MAPPABLE),
            "read-only cannot be received"
        );
        assert_eq!(
            check_entry(&od, Dir::Transmit, MapEntry::new(0x2001, 0, 16)),
            Ok(())
        );
        assert_eq!(check_entry(&od, rx, MapEntry::new(0x2004, 0, 32)), Ok(()));
        assert_eq!(
            check_entry(&od, rx, MapEntry::new(0x2004, 0, 12)),
            Err(AbortCode::NOT_MAPPABLE)
        );
        assert_eq!(
            check_entry(&od, rx, MapEntry::dummy(DataType::Unsigned16, 16)),
            Ok(())
        );
        assert_eq!(
            check_entry(&od, rx, MapEntry::dummy(DataType::Unsigned16, 17)),
            Err(AbortCode::NOT_MAPPABLE)
        );
        assert_eq!(
            check_entry(&od, rx, MapEntry::new(0x0010, 0, 24)),
            Ok(()),
            "INTEGER24 is a 24-bit dummy"
        );
        assert_eq!(
            check_entry(&od, rx, MapEntry::new(0x0017, 0, 8)),
            Err(AbortCode::NOT_MAPPABLE),
            "0x0017 is no data type"
        );
        assert_eq!(
            check_entry(&od, rx, MapEntry::new(0x2000, 0, 0)),
            Err(AbortCode::VALUE_RANGE)
        );
        let nine_bytes = [MapEntry::new(0x2000, 0, 8); 9];
        assert_eq!(
            check_mapping(&od, rx, nine_bytes),
            Err(AbortCode::PDO_LENGTH)
        );
        assert_eq!(
            check_mapping(&od, rx, [MapEntry::new(0x2000, 0, 8); 8]),
            Ok(64)
        );
    }

    #[test]
    fn bits_straddle_bytes() {
        let mut p = [0u8; 8];
        write_bits(&mut p, 4, 12, 0xABC);
        assert_eq!(p[..2], [0xC0, 0xAB]);
        assert_eq!(read_bits(&p, 4, 12), 0xABC);
        write_bits(&mut p, 0, 64, u64::MAX);
        assert_eq!(p, [0xFF; 8]);
        write_bits(&mut p, 63, 1, 0);
        assert_eq!(p[7], 0x7F);
        assert_eq!(read_bits(&p, 64, 8), 0, "beyond the frame reads zero");
        write_bits(&mut p, 70, 8, 0xFF); // ignored, no panic
        assert_eq!(p[7], 0x7F);
    }

    #[test]
    fn unpack_sign_extends_short_signed_values() {
        let mut od = od();
        let m = Mapping {
            entries: [
                MapEntry::new(0x2003, 0, 4),
                MapEntry::new(0x2000, 0, 4),
                MapEntry::default(),
                MapEntry::default(),
                MapEntry::default(),
                MapEntry::default(),
                MapEntry::default(),
                MapEntry::default(),
            ],
            count: 2,
            bits: 8,
        };
        let mut got = vec![];
        m.unpack(&mut od, 0x1600, &[0xFE, 0, 0, 0, 0, 0, 0, 0], |i, s| {
            got.push((i, s))
        });
        assert_eq!(od.get_value::<i16>(0x2003, 0), Ok(-2));
        assert_eq!(od.get_value::<u8>(0x2000, 0), Ok(0x0F));
        assert_eq!(got, [(0x2003, 0), (0x2000, 0)]);
        let mut out = [0u8; 8];
        assert_eq!(m.pack(&od, 0x1A00, &mut out), 1);
        assert_eq!(out[0], 0xFE);
    }
}
