//! Encoding of values (little-endian, as on the wire) and the checks every write goes through.

use super::def::{DataType, DefaultValue, Limit, ObjectDef};
use crate::od::abort::AbortCode;

mod real_bits;

/// A Rust type that maps onto a fixed-size CiA 301 data type.
pub trait OdValue: Sized + Copy {
    /// The data type it corresponds to.
    const TYPE: DataType;
    /// Decodes from exactly `size_of` little-endian bytes.
    fn decode(bytes: &[u8]) -> Option<Self>;
    /// Encodes into `out`, returning the byte count.
    fn encode(self, out: &mut [u8; 8]) -> usize;
}

macro_rules! od_value {
    ($t:ty, $dt:ident) => {
        impl OdValue for $t {
            const TYPE: DataType = DataType::$dt;
            fn decode(bytes: &[u8]) -> Option<Self> {
                Some(<$t>::from_le_bytes(bytes.try_into().ok()?))
            }
            fn encode(self, out: &mut [u8; 8]) -> usize {
                let b = self.to_le_bytes();
                out[..b.len()].copy_from_slice(&b);
                b.len()
            }
        }
    };
}
od_value!(u8, Unsigned8);
od_value!(u16, Unsigned16);
od_value!(u32, Unsigned32);
od_value!(u64, Unsigned64);
od_value!(i8, Integer8);
od_value!(i16, Integer16);
od_value!(i32, Integer32);
od_value!(i64, Integer64);
od_value!(f32, Real32);
od_value!(f64, Real64);

impl OdValue for bool {
    const TYPE: DataType = DataType::Boolean;
    fn decode(bytes: &[u8]) -> Option<Self> {
        match bytes {
            [0] => Some(false),
            [1] => Some(true),
            _ => None,
        }
    }
    fn encode(self, out: &mut [u8; 8]) -> usize {
        out[0] = self as u8;
        1
    }
}

/// True when a value of type `have` may be stored in an entry of type `want` through the typed
/// API (same size and signedness class; booleans and U8 are interchangeable on the wire).
pub(crate) fn compatible(want: DataType, have: DataType) -> bool {
    want == have
        || (want.fixed_size() == have.fixed_size()
            && want.is_signed() == have.is_signed()
            && want.is_real() == have.is_real())
}

/// Writes the default of `def` for a node into `out`, returning the length.
pub(crate) fn encode_default(def: &ObjectDef, node_id: u8, out: &mut [u8]) -> usize {
    let size = def.data_type.fixed_size();
    let n = match def.default_value() {
        DefaultValue::Zero => size.unwrap_or(0),
        DefaultValue::Unsigned(v) => put_int(v, size, out),
        DefaultValue::Signed(v) => put_int(v as u64, size, out),
        DefaultValue::NodeIdPlus(v) => put_int(v as u64 + node_id as u64, size, out),
        DefaultValue::Real(v) => match def.data_type {
            DataType::Real32 => copy(&real_bits::f64_to_f32(v.to_bits()).to_le_bytes(), out),
            _ => copy(&v.to_le_bytes(), out),
        },
        DefaultValue::Bytes(b) => copy(b, out),
    };
    if matches!(def.default_value(), DefaultValue::Zero) {
        let n = n.min(out.len());
        out[..n].fill(0);
        return n;
    }
    n
}

/// True if `data` is what [`encode_default`] gives for `def` (without a buffer of the entry's
/// size: power-on captures compare every entry).
pub(crate) fn is_default(def: &ObjectDef, node_id: u8, data: &[u8]) -> bool {
    let size = def.storage_size();
    match def.default_value() {
        DefaultValue::Bytes(b) => data == &b[..b.len().min(size)],
        DefaultValue::Zero if def.data_type.fixed_size().is_none() => data.is_empty(),
        // Numbers: at most eight bytes, whatever the type.
        _ => {
            let mut tmp = [0u8; 8];
            let n = encode_default(def, node_id, &mut tmp[..size.min(8)]);
            data == &tmp[..n]
        }
    }
}

/// The default of `def` for a node, as the bytes a dictionary holds after reset.
#[cfg(feature = "alloc")]
pub(crate) fn default_vec(def: &ObjectDef, node_id: u8) -> alloc::vec::Vec<u8> {
    // Strings and domains: only what the default needs, not the whole capacity (a DOMAIN of a
    // megabyte with an empty default costs nothing until written).
    let size = match def.data_type.fixed_size() {
        Some(n) => n,
        None => match def.default_value() {
            DefaultValue::Bytes(b) => b.len(),
            DefaultValue::Zero => 0,
            _ => 8,
        }
        .min(def.capacity as usize),
    };
    let mut data = alloc::vec![0u8; size];
    let n = encode_default(def, node_id, &mut data);
    data.truncate(n);
    data
}

fn put_int(v: u64, size: Option<usize>, out: &mut [u8]) -> usize {
    let n = size.unwrap_or(8).min(out.len());
    out[..n].copy_from_slice(&v.to_le_bytes()[..n]);
    n
}

fn copy(src: &[u8], out: &mut [u8]) -> usize {
    let n = src.len().min(out.len());
    out[..n].copy_from_slice(&src[..n]);
    n
}

/// The checks of a write whose access right was already checked: length against the type,
/// boolean range, limits, then the entry's hook. Returns the CiA 301 abort code on refusal.
pub fn check_value(def: &ObjectDef, data: &[u8]) -> Result<(), AbortCode> {
    match def.data_type.fixed_size() {
        Some(n) if data.len() > n => return Err(AbortCode::LENGTH_TOO_HIGH),
        Some(n) if data.len() < n => return Err(AbortCode::LENGTH_TOO_LOW),
        None if data.len() > def.capacity as usize => return Err(AbortCode::LENGTH_TOO_HIGH),
        _ => {}
    }
    if def.data_type == DataType::Boolean && data[0] > 1 {
        return Err(AbortCode::VALUE_RANGE);
    }
    if def.low().is_some() || def.high().is_some() {
        check_limits(def, data)?;
    }
    if let Some(hook) = def.hook {
        hook(def.index, def.sub, data)?;
    }
    Ok(())
}

fn check_limits(def: &ObjectDef, data: &[u8]) -> Result<(), AbortCode> {
    let t = def.data_type;
    let mut buf = [0u8; 8];
    let n = data.len().min(8);
    buf[..n].copy_from_slice(&data[..n]);
    let raw = u64::from_le_bytes(buf);
    // Real numbers are compared on their bits (`real_bits`): the results of `as f64`,
    // `partial_cmp` and `as i64`/`as u64`, exactly, without software double precision.
    let cmp = |lim: Limit| -> core::cmp::Ordering {
        if t.is_real() {
            let v = if t == DataType::Real32 {
                real_bits::f32_to_f64(u32::from_le_bytes([buf[0], buf[1], buf[2], buf[3]]))
            } else {
                raw
            };
            let l = match lim {
                Limit::Real(x) => x.to_bits(),
                Limit::Signed(x) => real_bits::i64_to_f64(x),
                Limit::Unsigned(x) => real_bits::u64_to_f64(x),
            };
            real_bits::cmp(v, l).unwrap_or(core::cmp::Ordering::Greater)
        } else if t.is_signed() {
            let shift = 64 - 8 * n as u32;
            let v = ((raw << shift) as i64) >> shift;
            let l = match lim {
                Limit::Signed(x) => x,
                Limit::Unsigned(x) => i64::try_from(x).unwrap_or(i64::MAX),
                Limit::Real(x) => real_bits::f64_to_i64(x.to_bits()),
            };
            v.cmp(&l)
        } else {
            let l = match lim {
                Limit::Unsigned(x) => x,
                Limit::Signed(x) => u64::try_from(x).unwrap_or(0),
                Limit::Real(x) => real_bits::f64_to_u64(x.to_bits()),
            };
            raw.cmp(&l)
        }
    };
    if let Some(low) = def.low() {
        if cmp(low).is_lt() {
            return Err(AbortCode::VALUE_TOO_LOW);
        }
    }
    if let Some(high) = def.high() {
        if cmp(high).is_gt() {
            return Err(AbortCode::VALUE_TOO_HIGH);
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::od::def::{Access, ObjectDef};

    #[test]
    fn length_and_range_checks_give_the_cia_codes() {
        let d = ObjectDef::u16(0x2000, 0, Access::Rw, 0)
            .limits(Limit::Unsigned(10), Limit::Unsigned(1000));
        assert_eq!(check_value(&d, &[1]), Err(AbortCode::LENGTH_TOO_LOW));
        assert_eq!(check_value(&d, &[1, 0, 0]), Err(AbortCode::LENGTH_TOO_HIGH));
        assert_eq!(
            check_value(&d, &5u16.to_le_bytes()),
            Err(AbortCode::VALUE_TOO_LOW)
        );
        assert_eq!(
            check_value(&d, &1001u16.to_le_bytes()),
            Err(AbortCode::VALUE_TOO_HIGH)
        );
        assert_eq!(check_value(&d, &1000u16.to_le_bytes()), Ok(()));

        let s = ObjectDef::new(0x2001, 0, DataType::Integer16)
            .limits(Limit::Signed(-5), Limit::Signed(5));
        assert_eq!(
            check_value(&s, &(-6i16).to_le_bytes()),
            Err(AbortCode::VALUE_TOO_LOW)
        );
        assert_eq!(check_value(&s, &(-5i16).to_le_bytes()), Ok(()));

        let r =
            ObjectDef::new(0x2002, 0, DataType::Real32).limits(Limit::Real(-1.0), Limit::Real(1.0));
        assert_eq!(
            check_value(&r, &1.5f32.to_le_bytes()),
            Err(AbortCode::VALUE_TOO_HIGH)
        );
        assert_eq!(
            check_value(&r, &f32::NAN.to_le_bytes()),
            Err(AbortCode::VALUE_TOO_HIGH)
        );

        let b = ObjectDef::new(0x2003, 0, DataType::Boolean);
        assert_eq!(check_value(&b, &[2]), Err(AbortCode::VALUE_RANGE));

        let st = ObjectDef::bytes(0x2004, 0, DataType::VisibleString, 4);
        assert_eq!(check_value(&st, b"abcde"), Err(AbortCode::LENGTH_TOO_HIGH));
        assert_eq!(check_value(&st, b""), Ok(()));
    }

    #[test]
    fn hooks_can_veto() {
        fn only_even(_: u16, _: u8, d: &[u8]) -> Result<(), AbortCode> {
            if d[0].is_multiple_of(2) {
                Ok(())
            } else {
                Err(AbortCode::LOCAL_CONTROL)
            }
        }
        let d = ObjectDef::u8(0x2000, 0, Access::Rw, 0).hook(only_even);
        assert_eq!(check_value(&d, &[3]), Err(AbortCode::LOCAL_CONTROL));
        assert_eq!(check_value(&d, &[4]), Ok(()));
    }

    #[test]
    fn defaults_encode_node_relative_values() {
        let d = ObjectDef::u32(0x1014, 0, Access::Rw, 0).default(DefaultValue::NodeIdPlus(0x80));
        let mut out = [0u8; 8];
        assert_eq!(encode_default(&d, 5, &mut out), 4);
        assert_eq!(&out[..4], &0x85u32.to_le_bytes());
    }
}
