//! The stored image: every stored parameter with its value, in one checked byte string.
//!
//! ```text
//! offset 0   "DCP1"                 magic and format version
//!        4   count       u32 LE     number of entries
//!        8   entries     count ×    index u16 LE, sub-index u8, length u32 LE, value bytes
//!        end−4 CRC-32    u32 LE     IEEE 802.3 CRC of every byte before it
//! ```
//!
//! Reading never trusts the bytes: the length, the magic, the CRC and every entry's extent are
//! checked before a single value reaches the dictionary ([`validate`]), and a value is applied
//! only if its entry still exists, is still a parameter and the value passes the entry's checks.

use super::{bytes, is_parameter, LoadReport, ParameterGroup, StorageError};
use crate::od::{check_value, ObjectDictionary};
use core::fmt;
use core::ops::RangeInclusive;

const MAGIC: [u8; 4] = *b"DCP1";
const HEADER: usize = 8;
const CRC_LEN: usize = 4;

/// Bytes an image spends besides its entries: magic, count, CRC.
pub const IMAGE_OVERHEAD: usize = HEADER + CRC_LEN;
/// Bytes each entry spends besides its value: index, sub-index, length.
pub const ENTRY_OVERHEAD: usize = 7;

/// The largest image a dictionary of `entries` entries holding `value_bytes` bytes of values
/// can produce: the buffer size that always suffices. For a
/// [`StaticDictionary<N, BYTES>`](crate::od::StaticDictionary), `image_capacity(N, BYTES)`.
pub const fn image_capacity(entries: usize, value_bytes: usize) -> usize {
    IMAGE_OVERHEAD + entries * ENTRY_OVERHEAD + value_bytes
}

/// The largest image `od`'s parameters can produce (every parameter at its largest size): the
/// exact bound for this dictionary, where [`image_capacity`] is the bound for its capacities.
pub fn image_size<D: ObjectDictionary + ?Sized>(od: &D) -> usize {
    let mut n = IMAGE_OVERHEAD;
    od.for_each(&mut |e| {
        if is_parameter(e.def) {
            n += ENTRY_OVERHEAD + e.def.storage_size();
        }
    });
    n
}

/// Why bytes read from a medium are not a stored image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum ImageError {
    /// Shorter than an empty image.
    TooShort {
        /// Bytes read.
        len: u32,
    },
    /// The first four bytes are not `DCP1` (not an image, or a format this version does not
    /// read).
    BadMagic,
    /// The CRC does not match: a torn or damaged write.
    Crc {
        /// The CRC the image carries.
        stored: u32,
        /// The CRC of its bytes.
        computed: u32,
    },
    /// Entry `entry` (0-based) at byte `offset` runs past the end of the image.
    Truncated {
        /// The entry.
        entry: u32,
        /// Where it starts.
        offset: u32,
    },
    /// The image holds bytes after its last entry, at `offset`.
    TrailingBytes {
        /// Where the extra bytes start.
        offset: u32,
    },
}

impl fmt::Display for ImageError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ImageError::TooShort { len } => write!(
                f,
                "{len} bytes is shorter than an empty image ({IMAGE_OVERHEAD} bytes)"
            ),
            ImageError::BadMagic => f.write_str("the image does not start with \"DCP1\""),
            ImageError::Crc { stored, computed } => write!(
                f,
                "CRC mismatch: the image says {stored:#010x}, its bytes give {computed:#010x}"
            ),
            ImageError::Truncated { entry, offset } => write!(
                f,
                "entry {entry} at byte {offset} runs past the end of the image"
            ),
            ImageError::TrailingBytes { offset } => {
                write!(f, "unexpected bytes after the last entry, at byte {offset}")
            }
        }
    }
}

impl core::error::Error for ImageError {}

/// The CRC an image ends with: CRC-32 (IEEE 802.3, reflected, as zlib computes it) of every
/// byte before it; for tools that write or repair images. Bitwise: images are a few hundred
/// bytes, written on command, so a table would cost 1 KiB of flash for nothing.
pub fn crc32(data: &[u8]) -> u32 {
    let mut c = !0u32;
    for &b in data {
        c ^= b as u32;
        for _ in 0..8 {
            c = if c & 1 != 0 {
                (c >> 1) ^ 0xEDB8_8320
            } else {
                c >> 1
            };
        }
    }
    !c
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

/// Checks `image` whole: length, magic, CRC, and that its entries tile it exactly.
pub(crate) fn validate(image: &[u8]) -> Result<(), ImageError> {
    if image.len() < IMAGE_OVERHEAD {
        return Err(ImageError::TooShort {
            len: bytes(image.len()),
        });
    }
    if image[..4] != MAGIC {
        return Err(ImageError::BadMagic);
    }
    let body = image.len() - CRC_LEN;
    let stored = u32_at(image, body);
    let computed = crc32(&image[..body]);
    if stored != computed {
        return Err(ImageError::Crc { stored, computed });
    }
    let count = u32_at(image, 4);
    let mut at = HEADER;
    for entry in 0..count {
        let truncated = ImageError::Truncated {
            entry,
            offset: bytes(at),
        };
        if body - at < ENTRY_OVERHEAD {
            return Err(truncated);
        }
        let len = u32_at(image, at + 3) as usize;
        if body - at - ENTRY_OVERHEAD < len {
            return Err(truncated);
        }
        at += ENTRY_OVERHEAD + len;
    }
    if at != body {
        return Err(ImageError::TrailingBytes { offset: bytes(at) });
    }
    Ok(())
}

/// The entries of a validated image: (index, sub-index, value).
fn entries(image: &[u8]) -> impl Iterator<Item = (u16, u8, &[u8])> + '_ {
    let body = image.len().saturating_sub(CRC_LEN);
    let mut at = HEADER;
    core::iter::from_fn(move || {
        if at + ENTRY_OVERHEAD > body {
            return None;
        }
        let index = u16::from_le_bytes([image[at], image[at + 1]]);
        let sub = image[at + 2];
        let len = u32_at(image, at + 3) as usize;
        let start = at + ENTRY_OVERHEAD;
        let value = image.get(start..start + len)?;
        at = start + len;
        Some((index, sub, value))
    })
}

/// Writes the header and the CRC around `count` entries ending at `end`; returns the length.
fn seal(buf: &mut [u8], count: u32, end: usize) -> usize {
    buf[..4].copy_from_slice(&MAGIC);
    buf[4..HEADER].copy_from_slice(&count.to_le_bytes());
    let crc = crc32(&buf[..end]);
    buf[end..end + CRC_LEN].copy_from_slice(&crc.to_le_bytes());
    end + CRC_LEN
}

/// Moves the entries of `buf[..len]` (a validated image, or `len == 0` for none) that `keep`
/// accepts to the front of the entry area; returns where they end and how many there are.
fn compact(buf: &mut [u8], len: usize, keep: impl Fn(u16) -> bool) -> (usize, u32) {
    let mut write = HEADER;
    let mut count = 0;
    if len == 0 {
        return (write, count);
    }
    let body = len - CRC_LEN;
    let mut read = HEADER;
    while read < body {
        let index = u16::from_le_bytes([buf[read], buf[read + 1]]);
        let total = ENTRY_OVERHEAD + u32_at(buf, read + 3) as usize;
        if keep(index) {
            buf.copy_within(read..read + total, write);
            write += total;
            count += 1;
        }
        read += total;
    }
    (write, count)
}

/// Rebuilds the image in `buf` (holding a validated image of `len` bytes, or `len == 0`): the
/// entries outside `group` stay, the group's entries become `od`'s current values. Returns the
/// new length; on [`StorageError::TooLarge`] `buf` is scratch and nothing else changed.
pub(crate) fn rebuild<D: ObjectDictionary + ?Sized>(
    od: &D,
    group: ParameterGroup,
    buf: &mut [u8],
    len: usize,
) -> Result<usize, StorageError> {
    if buf.len() < IMAGE_OVERHEAD {
        return Err(StorageError::TooLarge {
            needed: bytes(IMAGE_OVERHEAD),
            capacity: bytes(buf.len()),
        });
    }
    let (mut at, mut count) = compact(buf, len, |index| !group.contains(index));
    let capacity = buf.len();
    od.for_each(&mut |e| {
        if !group.contains(e.def.index) || !is_parameter(e.def) {
            return;
        }
        let total = ENTRY_OVERHEAD + e.data.len();
        // Count what does not fit too, so that the error says how much is needed.
        if at + total + CRC_LEN <= capacity {
            buf[at..at + 2].copy_from_slice(&e.def.index.to_le_bytes());
            buf[at + 2] = e.def.sub;
            buf[at + 3..at + ENTRY_OVERHEAD].copy_from_slice(&(e.data.len() as u32).to_le_bytes());
            buf[at + ENTRY_OVERHEAD..at + total].copy_from_slice(e.data);
        }
        at += total;
        count += 1;
    });
    if at + CRC_LEN > capacity {
        return Err(StorageError::TooLarge {
            needed: bytes(at + CRC_LEN),
            capacity: bytes(capacity),
        });
    }
    Ok(seal(buf, count, at))
}

/// Removes `group`'s entries from the validated image in `buf[..len]`. Returns the new length,
/// or `None` when no entry remains (the medium is then erased rather than rewritten).
pub(crate) fn remove(buf: &mut [u8], len: usize, group: ParameterGroup) -> Option<usize> {
    let (end, count) = compact(buf, len, |index| !group.contains(index));
    (count > 0).then(|| seal(buf, count, end))
}

/// Writes the values of the validated `image` whose index is in `range` into `od`.
pub(crate) fn apply<D: ObjectDictionary + ?Sized>(
    od: &mut D,
    image: &[u8],
    range: RangeInclusive<u16>,
) -> LoadReport {
    let mut report = LoadReport::default();
    for (index, sub, value) in entries(image).filter(|(i, _, _)| range.contains(i)) {
        let fits = od
            .get(index, sub)
            .is_ok_and(|e| is_parameter(e.def) && check_value(e.def, value).is_ok());
        if fits && od.store(index, sub, value).is_ok() {
            report.applied = report.applied.saturating_add(1);
        } else {
            report.skipped = report.skipped.saturating_add(1);
        }
    }
    report
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::od::{Access, DataType, ObjectDef, StaticDictionary};

    static DEFS: [ObjectDef; 5] = [
        ObjectDef::u16(0x1017, 0, Access::Rw, 0),
        ObjectDef::u8(0x1001, 0, Access::Ro, 0),
        ObjectDef::u32(0x2000, 0, Access::Rw, 7),
        ObjectDef::bytes(0x6000, 0, DataType::OctetString, 6),
        ObjectDef::u8(0x6001, 0, Access::Rw, 1),
    ];

    fn od() -> StaticDictionary<8, 32> {
        let mut od = StaticDictionary::new();
        od.load(1, &[&DEFS]).unwrap();
        od
    }

    #[test]
    fn crc_is_the_ieee_one() {
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
    }

    #[test]
    fn groups_are_replaced_and_kept_independently() {
        let mut od = od();
        let mut buf = [0u8; 128];
        od.write(0x1017, 0, &500u16.to_le_bytes()).unwrap();
        od.write(0x6000, 0, b"abc").unwrap();
        let len = rebuild(&od, ParameterGroup::Communication, &mut buf, 0).unwrap();
        assert_eq!(
            len,
            IMAGE_OVERHEAD + ENTRY_OVERHEAD + 2,
            "0x1001 is not a parameter"
        );
        let len = rebuild(&od, ParameterGroup::Application, &mut buf, len).unwrap();
        validate(&buf[..len]).unwrap();
        let got: std::vec::Vec<_> = entries(&buf[..len]).map(|(i, s, _)| (i, s)).collect();
        assert_eq!(got.len(), 3);
        assert!(got.contains(&(0x1017, 0)) && got.contains(&(0x6000, 0)));
        // Storing the communication group again keeps the application entries.
        od.write(0x1017, 0, &700u16.to_le_bytes()).unwrap();
        let len = rebuild(&od, ParameterGroup::Communication, &mut buf, len).unwrap();
        let mut fresh = self::od();
        assert_eq!(
            apply(&mut fresh, &buf[..len], 0x1000..=0xFFFF),
            LoadReport {
                applied: 3,
                skipped: 0
            }
        );
        assert_eq!(fresh.get_value::<u16>(0x1017, 0), Ok(700));
        assert_eq!(fresh.read(0x6000, 0), Ok(&b"abc"[..]));
        // Removing the application group leaves the communication one.
        let len = remove(&mut buf, len, ParameterGroup::Application).unwrap();
        assert_eq!(entries(&buf[..len]).count(), 1);
        assert_eq!(remove(&mut buf, len, ParameterGroup::All), None);
    }

    #[test]
    fn a_range_limits_what_is_applied() {
        let mut od = od();
        od.write(0x1017, 0, &500u16.to_le_bytes()).unwrap();
        od.write(0x2000, 0, &9u32.to_le_bytes()).unwrap();
        let mut buf = [0u8; 128];
        let len = rebuild(&od, ParameterGroup::All, &mut buf, 0).unwrap();
        let mut fresh = self::od();
        let r = apply(&mut fresh, &buf[..len], 0x1000..=0x1FFF);
        assert_eq!(r.applied, 1);
        assert_eq!(fresh.get_value::<u16>(0x1017, 0), Ok(500));
        assert_eq!(fresh.get_value::<u32>(0x2000, 0), Ok(7));
    }

    #[test]
    fn too_small_a_buffer_says_how_much_is_needed() {
        let od = od();
        let mut buf = [0u8; 20];
        // 0x1017 (2 bytes), 0x2000 (4), 0x6000 (empty now), 0x6001 (1).
        let needed = IMAGE_OVERHEAD + 4 * ENTRY_OVERHEAD + 2 + 4 + 1;
        assert_eq!(
            rebuild(&od, ParameterGroup::All, &mut buf, 0),
            Err(StorageError::TooLarge {
                needed: needed as u32,
                capacity: 20
            })
        );
        // The bounds hold whatever the string holds: 6 bytes at most.
        assert_eq!(image_size(&od), needed + 6);
        assert!(image_size(&od) <= image_capacity(8, 32));
        let mut buf = [0u8; 64];
        assert_eq!(
            rebuild(&od, ParameterGroup::All, &mut buf[..needed], 0),
            Ok(needed)
        );
    }

    #[test]
    fn damaged_images_are_refused_with_where() {
        let od = od();
        let mut buf = [0u8; 128];
        let len = rebuild(&od, ParameterGroup::All, &mut buf, 0).unwrap();
        validate(&buf[..len]).unwrap();
        assert_eq!(validate(&buf[..5]), Err(ImageError::TooShort { len: 5 }));
        let mut bad = buf;
        bad[0] = b'X';
        assert_eq!(validate(&bad[..len]), Err(ImageError::BadMagic));
        let mut bad = buf;
        bad[len - 6] ^= 1;
        assert!(matches!(validate(&bad[..len]), Err(ImageError::Crc { .. })));
        // A count that promises more entries than there are, with a CRC that matches.
        let mut bad = buf;
        let count = u32_at(&bad, 4);
        let end = seal(&mut bad, count + 1, len - CRC_LEN);
        assert_eq!(
            validate(&bad[..end]),
            Err(ImageError::Truncated {
                entry: count,
                offset: (len - CRC_LEN) as u32
            })
        );
        let mut bad = buf;
        let end = seal(&mut bad, count - 1, len - CRC_LEN);
        assert!(matches!(
            validate(&bad[..end]),
            Err(ImageError::TrailingBytes { .. })
        ));
    }

    #[test]
    fn values_that_no_longer_fit_are_skipped() {
        static OLD: [ObjectDef; 2] = [
            ObjectDef::u32(0x6001, 0, Access::Rw, 1),
            ObjectDef::u32(0x6002, 0, Access::Rw, 1),
        ];
        let mut old = StaticDictionary::<4, 16>::new();
        old.load(1, &[&OLD]).unwrap();
        let mut buf = [0u8; 64];
        let len = rebuild(&old, ParameterGroup::Application, &mut buf, 0).unwrap();
        // 0x6001 became a U8, 0x6002 is gone.
        let mut new = od();
        assert_eq!(
            apply(&mut new, &buf[..len], 0x1000..=0xFFFF),
            LoadReport {
                applied: 0,
                skipped: 2
            }
        );
        assert_eq!(new.get_value::<u8>(0x6001, 0), Ok(1));
    }
}
