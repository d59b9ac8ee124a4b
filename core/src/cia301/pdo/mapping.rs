//! PDO mapping: the entries of 0x16xx/0x1Axx, their validation against the dictionary, and the
//! bit-granular packing of values into (and out of) the at most 64 bits of a classic CAN frame,
//! or (feature `fd`) the at most 64 bytes of a CAN FD frame.
//!
//! Bits are numbered as CiA 301 numbers them: bit 0 is the least significant bit of data byte 0,
//! bit 8 the least significant bit of byte 1, and an entry's value occupies consecutive bits from
//! its least significant bit up. Because a classic PDO is at most 64 bits, its frame is handled
//! as one little-endian `u64` and every entry is a shift and a mask.
//!
//! **CAN FD (feature `fd`).** On a CANopen FD network a PDO carries up to 64 bytes
//! ([`FD_MAX_BITS`] = 512 bits) in up to 64 entries, still bit-granular: an entry has any length
//! its object allows and starts at any bit. A mapping of at most 64 bits still takes the `u64`
//! path above (so a short PDO costs what it did); a longer one is packed entry by entry into a
//! fixed 64-byte buffer ([`read_bits_wide`], [`write_bits_wide`]): no allocation, every index
//! checked, bits beyond the buffer read as zero and are dropped on writing. Without `fd` none of
//! this is built, and a mapping beyond 64 bits is refused (0x06040042) as before.

use crate::od::abort::AbortCode;
use crate::od::{DataType, ObjectDictionary};

/// Largest number of bits one classic PDO carries (8 bytes).
pub const MAX_BITS: u32 = 64;
/// Largest number of bits one PDO carries on a CANopen FD network (64 bytes).
#[cfg(feature = "fd")]
pub const FD_MAX_BITS: u32 = 512;
/// The type of a mapping's total length: it fits 64 bits in a `u8`, 512 bits need a `u16`.
#[cfg(not(feature = "fd"))]
type Bits = u8;
#[cfg(feature = "fd")]
type Bits = u16;
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
    check_mapping_within(od, dir, entries, MAX_BITS)
}

/// [`check_mapping`] against a frame of `max_bits`: [`MAX_BITS`] for a classic PDO,
/// [`FD_MAX_BITS`] (feature `fd`) for one on a CANopen FD network (0x06040042 beyond it).
pub fn check_mapping_within<D: ObjectDictionary + ?Sized>(
    od: &D,
    dir: Dir,
    entries: impl IntoIterator<Item = MapEntry>,
    max_bits: u32,
) -> Result<u32, AbortCode> {
    let mut bits = 0u32;
    for (n, e) in entries.into_iter().enumerate() {
        if n >= MAX_ENTRIES as usize {
            return Err(AbortCode::PDO_LENGTH);
        }
        check_entry(od, dir, e)?;
        bits += e.bits as u32;
        if bits > max_bits {
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

/// Reads `len` bits (at most 64) at bit `offset` of a payload of any length (CiA 301 bit order):
/// the wide counterpart of [`read_bits`] for CAN FD PDOs (feature `fd`). Bits beyond the payload
/// read as zero; nothing panics.
#[cfg(feature = "fd")]
#[inline]
pub fn read_bits_wide(payload: &[u8], offset: u32, len: u32) -> u64 {
    let first = (offset / 8) as usize;
    let shift = offset % 8;
    // `len` ≤ 64 plus a shift ≤ 7 spans at most 9 bytes.
    let mut acc = 0u128;
    for (i, b) in payload.iter().skip(first).take(9).enumerate() {
        acc |= (*b as u128) << (8 * i);
    }
    (acc >> shift) as u64 & mask(len)
}

/// Writes the `len` (at most 64) low bits of `value` at bit `offset` of a payload of any length
/// (CiA 301 bit order), leaving the other bits as they were: the wide counterpart of
/// [`write_bits`] (feature `fd`). Bits that would fall beyond the payload are dropped.
#[cfg(feature = "fd")]
#[inline]
pub fn write_bits_wide(payload: &mut [u8], offset: u32, len: u32, value: u64) {
    let first = (offset / 8) as usize;
    let shift = offset % 8;
    let m = (mask(len) as u128) << shift;
    let v = ((value & mask(len)) as u128) << shift;
    for (i, b) in payload.iter_mut().skip(first).take(9).enumerate() {
        let (mb, vb) = ((m >> (8 * i)) as u8, (v >> (8 * i)) as u8);
        *b = (*b & !mb) | vb;
    }
}

/// Copies the `len` low bits of the little-endian `src` (missing bytes read as zero) to bit
/// `offset` of `out`, 64 bits at a time.
#[cfg(feature = "fd")]
fn copy_in(out: &mut [u8], offset: u32, len: u32, src: &[u8]) {
    let mut done = 0u32;
    while done < len {
        let n = (len - done).min(64);
        let from = src.get((done / 8) as usize..).unwrap_or(&[]);
        write_bits_wide(out, offset + done, n, le_u64(from));
        done += n;
    }
}

/// Copies `len` bits at bit `offset` of `payload` into the little-endian `dst` (as many bytes
/// as it has), 64 bits at a time.
#[cfg(feature = "fd")]
fn copy_out(payload: &[u8], offset: u32, len: u32, dst: &mut [u8]) {
    let mut done = 0u32;
    while done < len {
        let n = (len - done).min(64);
        let v = read_bits_wide(payload, offset + done, n).to_le_bytes();
        let at = (done / 8) as usize;
        for (d, b) in dst
            .iter_mut()
            .skip(at)
            .zip(v.iter().take(n.div_ceil(8) as usize))
        {
            *d = *b;
        }
        done += n;
    }
}

/// The cached part of a PDO's mapping: the first [`CACHED`] entries, the count and total length.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Mapping {
    entries: [MapEntry; CACHED],
    count: u8,
    bits: Bits,
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
        #[allow(clippy::unnecessary_cast)] // `Bits` is `u8` without `fd`
        let bits = entries
            .iter()
            .fold(0, |a: Bits, e| a.saturating_add(e.bits as Bits));
        m.bits = bits;
        m
    }

    /// Reads and checks the mapping stored at `map_index` against a frame of `max_bits`
    /// (0x06040042 beyond). `Ok` with an empty mapping when the object does not exist.
    pub(crate) fn load<D: ObjectDictionary + ?Sized>(
        od: &D,
        dir: Dir,
        map_index: u16,
        max_bits: u32,
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
            if bits > max_bits {
                return Err(AbortCode::PDO_LENGTH);
            }
            if let Some(slot) = m.entries.get_mut(s as usize - 1) {
                *slot = e;
            }
        }
        m.bits = bits as Bits;
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
    #[allow(clippy::unnecessary_cast)] // `Bits` is `u8` without `fd`
    pub(crate) fn bytes(&self) -> u8 {
        self.bits.div_ceil(8) as u8
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

/// The CAN FD side of a mapping (feature `fd`): up to 64 bytes.
#[cfg(feature = "fd")]
impl Mapping {
    /// Builds a payload of up to 64 bytes from the current dictionary values; the bytes beyond
    /// the mapping are zeros. Returns the mapped byte count. A mapping of at most 64 bits takes
    /// the classic `u64` path.
    pub(crate) fn pack_wide<D: ObjectDictionary + ?Sized>(
        &self,
        od: &D,
        map_index: u16,
        out: &mut [u8; 64],
    ) -> u8 {
        *out = [0; 64];
        if self.bits() <= MAX_BITS {
            let mut b = [0u8; 8];
            let n = self.pack(od, map_index, &mut b);
            out[..8].copy_from_slice(&b);
            return n;
        }
        let mut off = 0u32;
        for k in 0..self.count {
            let e = self.entry(od, map_index, k);
            let len = e.bits as u32;
            if !e.is_dummy() {
                if let Ok(en) = od.get(e.index, e.sub) {
                    copy_in(out, off, len, en.data);
                }
            }
            off += len;
        }
        self.bytes()
    }

    /// Writes a received payload of up to 64 bytes into the dictionary, as
    /// [`Mapping::unpack`] does (zero- or sign-extension, `written` per entry stored). A
    /// mapping of at most 64 bits takes the classic `u64` path.
    pub(crate) fn unpack_wide<D: ObjectDictionary + ?Sized>(
        &self,
        od: &mut D,
        map_index: u16,
        payload: &[u8; 64],
        mut written: impl FnMut(u16, u8),
    ) {
        if self.bits() <= MAX_BITS {
            let mut b = [0u8; 8];
            b.copy_from_slice(&payload[..8]);
            return self.unpack(od, map_index, &b, written);
        }
        let mut off = 0u32;
        for k in 0..self.count {
            let e = self.entry(od, map_index, k);
            let len = e.bits as u32;
            let at = off;
            off += len;
            if e.is_dummy() {
                continue;
            }
            let Ok(en) = od.get(e.index, e.sub) else {
                continue;
            };
            let t = en.def.data_type;
            // An entry is at most 255 bits: 32 bytes hold it.
            let mut buf = [0u8; 32];
            let size = match t.fixed_size() {
                Some(n) => n,
                None => (len / 8) as usize,
            }
            .min(buf.len());
            if len <= 64 {
                let raw = read_bits_wide(payload, at, len);
                let v = if t.is_signed() && len < 64 && len > 0 && raw >> (len - 1) & 1 == 1 {
                    raw | !mask(len)
                } else {
                    raw
                };
                let n = size.min(8);
                buf[..n].copy_from_slice(&v.to_le_bytes()[..n]);
            } else {
                copy_out(payload, at, len, &mut buf);
            }
            if od.store(e.index, e.sub, &buf[..size]).is_ok() {
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

/// The wide (CAN FD) packing: odd offsets and lengths, the 512-bit limit, and a property.
#[cfg(all(test, feature = "fd"))]
mod wide_tests {
    use super::*;
    use crate::od::{Access, DynamicDictionary, ObjectDef};
    use proptest::prelude::*;

    /// Objects 0x2100 + i (UNSIGNED64, or INTEGER16 where `signed` says), and the mapping of
    /// `bits[i]` bits of each at 0x1600 (receive) and 0x1A00 (transmit).
    fn od(bits: &[u8], signed: &[usize]) -> DynamicDictionary {
        let mut defs = std::vec::Vec::new();
        for (i, b) in bits.iter().enumerate() {
            let t = if signed.contains(&i) {
                DataType::Integer16
            } else {
                DataType::Unsigned64
            };
            defs.push(
                ObjectDef::new(0x2100 + i as u16, 0, t)
                    .mappable()
                    .access(Access::Rw),
            );
            for m in [0x1600u16, 0x1A00] {
                let raw = MapEntry::new(0x2100 + i as u16, 0, *b).raw();
                defs.push(ObjectDef::u32(m, i as u8 + 1, Access::Rw, raw));
            }
        }
        for m in [0x1600u16, 0x1A00] {
            defs.push(ObjectDef::u8(m, 0, Access::Rw, bits.len() as u8));
        }
        DynamicDictionary::from_tables(1, &[&defs]).unwrap()
    }

    fn set(od: &mut DynamicDictionary, i: usize, v: u64) {
        let n = od
            .get(0x2100 + i as u16, 0)
            .unwrap()
            .def
            .data_type
            .fixed_size()
            .unwrap();
        od.store(0x2100 + i as u16, 0, &v.to_le_bytes()[..n])
            .unwrap();
    }

    fn get(od: &DynamicDictionary, i: usize) -> u64 {
        le_u64(od.get(0x2100 + i as u16, 0).unwrap().data)
    }

    /// The payload bit by bit, as CiA 301 numbers the bits.
    fn reference(bits: &[u8], values: &[u64]) -> [u8; 64] {
        let mut out = [0u8; 64];
        let mut off = 0usize;
        for (b, v) in bits.iter().zip(values) {
            for k in 0..*b as usize {
                if v >> k & 1 == 1 {
                    out[(off + k) / 8] |= 1 << ((off + k) % 8);
                }
            }
            off += *b as usize;
        }
        out
    }

    /// 3-, 13- and 64-bit entries across byte boundaries, 512 bits in all.
    const ODD: [u8; 15] = [3, 13, 64, 64, 64, 64, 64, 64, 64, 13, 13, 13, 3, 3, 3];

    #[test]
    fn odd_lengths_at_odd_offsets_fill_64_bytes_and_come_back() {
        assert_eq!(ODD.iter().map(|b| *b as u32).sum::<u32>(), FD_MAX_BITS);
        let mut tx = od(&ODD, &[]);
        let values: std::vec::Vec<u64> = (0..ODD.len())
            .map(|i| 0x0123_4567_89AB_CDEFu64.rotate_left(7 * i as u32) ^ i as u64)
            .collect();
        for (i, v) in values.iter().enumerate() {
            set(&mut tx, i, *v);
        }
        let m = Mapping::load(&tx, Dir::Transmit, 0x1A00, FD_MAX_BITS).unwrap();
        assert_eq!((m.count(), m.bits(), m.bytes()), (15, 512, 64));
        let mut out = [0u8; 64];
        assert_eq!(m.pack_wide(&tx, 0x1A00, &mut out), 64);
        assert_eq!(out, reference(&ODD, &values));
        // The 13-bit entry starts at bit 3: bits 3..16.
        assert_eq!(read_bits_wide(&out, 3, 13), values[1] & mask(13));
        // A 64-bit entry at bit 16 spans bytes 2..10.
        assert_eq!(read_bits_wide(&out, 16, 64), values[2]);

        let mut rx = od(&ODD, &[]);
        let m = Mapping::load(&rx, Dir::Receive, 0x1600, FD_MAX_BITS).unwrap();
        let mut seen = 0;
        m.unpack_wide(&mut rx, 0x1600, &out, |_, _| seen += 1);
        assert_eq!(seen, 15);
        for (i, (b, v)) in ODD.iter().zip(&values).enumerate() {
            assert_eq!(get(&rx, i), v & mask(*b as u32), "entry {i}");
        }
    }

    #[test]
    fn short_signed_entries_are_sign_extended_on_the_wide_path() {
        // 61 bits of filler, then a 13-bit INTEGER16 crossing bytes 7..9: beyond 64 bits.
        let bits = [61u8, 13];
        let mut rx = od(&bits, &[1]);
        let mut p = [0u8; 64];
        write_bits_wide(&mut p, 61, 13, 0x1FFE); // -2 in 13 bits
        let m = Mapping::load(&rx, Dir::Receive, 0x1600, FD_MAX_BITS).unwrap();
        m.unpack_wide(&mut rx, 0x1600, &p, |_, _| {});
        assert_eq!(rx.get_value::<i16>(0x2101, 0), Ok(-2));
    }

    #[test]
    fn beyond_the_frame_is_0x06040042() {
        let mut bits = ODD.to_vec();
        bits.push(1); // 513 bits
        let od = od(&bits, &[]);
        assert_eq!(
            Mapping::load(&od, Dir::Transmit, 0x1A00, FD_MAX_BITS),
            Err(AbortCode::PDO_LENGTH)
        );
        let entries = bits
            .iter()
            .enumerate()
            .map(|(i, b)| MapEntry::new(0x2100 + i as u16, 0, *b));
        assert_eq!(
            check_mapping_within(&od, Dir::Transmit, entries.clone(), FD_MAX_BITS),
            Err(AbortCode::PDO_LENGTH)
        );
        assert_eq!(
            check_mapping_within(&od, Dir::Transmit, entries.clone().take(15), FD_MAX_BITS),
            Ok(512)
        );
        // The classic limit stays 64 bits.
        assert_eq!(
            check_mapping(&od, Dir::Transmit, entries.take(3)),
            Err(AbortCode::PDO_LENGTH)
        );
        assert_eq!(
            Mapping::load(&od, Dir::Transmit, 0x1A00, MAX_BITS),
            Err(AbortCode::PDO_LENGTH)
        );
    }

    #[test]
    fn wide_bits_beyond_the_payload_read_zero_and_are_dropped() {
        let mut p = [0xFFu8; 4];
        assert_eq!(read_bits_wide(&p, 28, 8), 0x0F);
        assert_eq!(read_bits_wide(&p, 1000, 64), 0);
        write_bits_wide(&mut p, 28, 8, 0);
        assert_eq!(p, [0xFF, 0xFF, 0xFF, 0x0F]);
        write_bits_wide(&mut p, u32::MAX, 64, 0); // nothing, no panic
        assert_eq!(read_bits_wide(&[], 0, 64), 0);
    }

    proptest! {
        /// Any mapping of up to 64 entries of 1–64 bits and at most 512 bits in all: packing
        /// gives the bit-by-bit payload, and unpacking it gives every value back (masked to
        /// its length).
        #[test]
        fn pack_then_unpack_returns_the_values(
            entries in proptest::collection::vec((1u8..=64, any::<u64>()), 1..=64),
        ) {
            let mut total = 0u32;
            let entries: std::vec::Vec<(u8, u64)> = entries
                .into_iter()
                .take_while(|(b, _)| {
                    total += *b as u32;
                    total <= FD_MAX_BITS
                })
                .collect();
            prop_assume!(!entries.is_empty());
            let bits: std::vec::Vec<u8> = entries.iter().map(|(b, _)| *b).collect();
            let values: std::vec::Vec<u64> = entries.iter().map(|(_, v)| *v).collect();
            let mut tx = od(&bits, &[]);
            for (i, v) in values.iter().enumerate() {
                set(&mut tx, i, *v);
            }
            let m = Mapping::load(&tx, Dir::Transmit, 0x1A00, FD_MAX_BITS).unwrap();
            let mut out = [0u8; 64];
            let n = m.pack_wide(&tx, 0x1A00, &mut out);
            let sum: u32 = bits.iter().map(|b| *b as u32).sum();
            prop_assert_eq!(n as u32, sum.div_ceil(8));
            prop_assert_eq!(out, reference(&bits, &values));
            let mut rx = od(&bits, &[]);
            let m = Mapping::load(&rx, Dir::Receive, 0x1600, FD_MAX_BITS).unwrap();
            m.unpack_wide(&mut rx, 0x1600, &out, |_, _| {});
            for (i, (b, v)) in bits.iter().zip(&values).enumerate() {
                prop_assert_eq!(get(&rx, i), v & mask(*b as u32));
            }
        }
    }
}
