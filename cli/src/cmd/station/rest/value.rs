//! Typed values in JSON, by the CiA 309 data-type names the ASCII gateway takes
//! ([`gateway::value`](crate::cmd::gateway::value), whose parser and encoder these are): a
//! number for `b`, `i8`…`i64`, `u8`…`u64` and `r32`/`r64`, a string for the others (`vs` the
//! text itself; `x8`…`x64` as `0x…`; `os`, `us`, `d` base64; `t`, `td` "DAYS MS"; `hex`
//! bytes as hex pairs). A value written may also be given as a string (`"0x1234"`).

use crate::cmd::gateway::value::{encode_value, show_value, DataType, Word};
use serde_json::Value;

/// The type named `name`, or why it is none.
pub fn data_type(name: &str) -> Result<DataType, String> {
    DataType::parse(name).ok_or_else(|| {
        format!(
            "type {name:?} is not a CiA 309 data type: b, i8…i64, u8…u64, x8…x64, r32, r64, vs, \
             os, us, d, t, td or hex"
        )
    })
}

/// The CiA 309 name of a dictionary data type (`hex` for those 309 names none of: DOMAIN is
/// `d`, as base64).
#[must_use]
pub fn type_of(t: duocan::od::DataType) -> &'static str {
    use duocan::od::DataType as T;
    match t {
        T::Boolean => "b",
        T::Integer8 => "i8",
        T::Integer16 => "i16",
        T::Integer24 => "i24",
        T::Integer32 => "i32",
        T::Integer40 => "i40",
        T::Integer48 => "i48",
        T::Integer56 => "i56",
        T::Integer64 => "i64",
        T::Unsigned8 => "u8",
        T::Unsigned16 => "u16",
        T::Unsigned24 => "u24",
        T::Unsigned32 => "u32",
        T::Unsigned40 => "u40",
        T::Unsigned48 => "u48",
        T::Unsigned56 => "u56",
        T::Unsigned64 => "u64",
        T::Real32 => "r32",
        T::Real64 => "r64",
        T::VisibleString => "vs",
        T::OctetString => "os",
        T::UnicodeString => "us",
        T::TimeOfDay => "t",
        T::TimeDifference => "td",
        T::Domain => "d",
        #[allow(unreachable_patterns)]
        _ => "hex",
    }
}

fn bare(text: &str) -> Word {
    Word {
        text: text.to_string(),
        quoted: false,
    }
}

/// The bytes to write for the JSON value `v` as `ty`, or what is wrong with it.
pub fn to_bytes(ty: DataType, v: &Value) -> Result<Vec<u8>, String> {
    let words = match (ty, v) {
        (DataType::Visible, Value::String(s)) => vec![Word {
            text: s.clone(),
            quoted: true,
        }],
        (DataType::Visible, _) => return Err("value: a vs value is a JSON string".into()),
        (DataType::Time | DataType::Bytes, Value::String(s)) => {
            s.split_whitespace().map(bare).collect()
        }
        (DataType::Bool, Value::Bool(b)) => vec![bare(if *b { "1" } else { "0" })],
        (_, Value::Number(n)) => vec![bare(&n.to_string())],
        (_, Value::String(s)) => vec![bare(s.trim())],
        _ => return Err("value: a JSON number or string".into()),
    };
    encode_value(ty, &words).map_err(|why| format!("value: {why}"))
}

/// The bytes `data` read as `ty`, in JSON, and the type they are shown as: `hex` when their
/// size is not the type's (the bytes the node sent, never a number guessed from them).
pub fn from_bytes(ty: DataType, data: &[u8]) -> (Option<&'static str>, Value) {
    if ty.size().is_some_and(|n| n != data.len()) {
        return (
            Some("hex"),
            Value::String(show_value(DataType::Bytes, data)),
        );
    }
    let unsigned = || {
        let mut b = [0u8; 8];
        let n = data.len().min(8);
        b[..n].copy_from_slice(&data[..n]);
        u64::from_le_bytes(b)
    };
    let real = |v: f64| {
        serde_json::Number::from_f64(v)
            .map_or_else(|| Value::String(show_value(ty, data)), Value::Number)
    };
    let v = match ty {
        DataType::Bool | DataType::Uint(_) => Value::from(unsigned()),
        DataType::Int(n) => {
            let shift = 64 - 8 * u32::from(n);
            Value::from(((unsigned() << shift) as i64) >> shift)
        }
        DataType::Real32 => real(f64::from(f32::from_bits(unsigned() as u32))),
        DataType::Real64 => real(f64::from_bits(unsigned())),
        DataType::Visible => {
            let kept: Vec<u8> = data.iter().copied().filter(|b| *b != 0).collect();
            Value::String(String::from_utf8_lossy(&kept).into_owned())
        }
        _ => Value::String(show_value(ty, data)),
    };
    (None, v)
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn every_dictionary_type_has_a_309_name_the_gateway_takes() {
        for code in 0..=0x30u16 {
            if let Some(t) = duocan::od::DataType::from_code(code) {
                let name = type_of(t);
                assert!(data_type(name).is_ok(), "{t:?} as {name}");
            }
        }
        assert_eq!(type_of(duocan::od::DataType::Unsigned16), "u16");
        assert_eq!(type_of(duocan::od::DataType::VisibleString), "vs");
    }

    #[test]
    fn values_go_both_ways() {
        let t = |n| data_type(n).unwrap();
        for (ty, v, bytes) in [
            ("u32", json!(13_683_200), vec![0x00, 0xCA, 0xD0, 0x00]),
            ("i16", json!(-2), vec![0xFE, 0xFF]),
            ("u16", json!(1234), vec![0xD2, 0x04]),
            ("b", json!(1), vec![1]),
            ("r32", json!(1.5), 1.5f32.to_le_bytes().to_vec()),
            ("vs", json!("say \"hi\""), b"say \"hi\"".to_vec()),
            ("x16", json!("0x04D2"), vec![0xD2, 0x04]),
            ("os", json!("AQI="), vec![1, 2]),
            ("hex", json!("01 02"), vec![1, 2]),
        ] {
            assert_eq!(to_bytes(t(ty), &v), Ok(bytes.clone()), "{ty}");
            assert_eq!(from_bytes(t(ty), &bytes), (None, v), "{ty}");
        }
        // Written as a string too.
        assert_eq!(to_bytes(t("u16"), &json!("0x10")), Ok(vec![0x10, 0]));
        assert_eq!(to_bytes(t("b"), &json!(true)), Ok(vec![1]));
        // A size that is not the type's: the bytes.
        assert_eq!(
            from_bytes(t("u32"), &[0xE8, 0x03]),
            (Some("hex"), json!("E8 03"))
        );
    }

    /// Whatever a node sends and whatever a client writes: an answer or an error, never a
    /// panic.
    #[test]
    fn any_bytes_and_any_value_are_taken_without_panicking() {
        use proptest::prelude::*;
        const TYPES: [&str; 14] = [
            "b", "i8", "i24", "i64", "u8", "u56", "u64", "x64", "r32", "r64", "vs", "os", "t",
            "hex",
        ];
        proptest!(|(t in 0..TYPES.len(), bytes in proptest::collection::vec(any::<u8>(), 0..12),
                    text in "[0-9a-zA-Z +=.\"-]{0,24}", n in any::<i64>(), f in any::<f64>())| {
            let ty = data_type(TYPES[t]).unwrap();
            let _ = from_bytes(ty, &bytes);
            let _ = to_bytes(ty, &json!(text));
            let _ = to_bytes(ty, &json!(n));
            let _ = to_bytes(ty, &json!(f));
        });
    }

    #[test]
    fn bad_values_say_what_is_wrong() {
        let t = |n| data_type(n).unwrap();
        let e = to_bytes(t("u8"), &json!(300)).unwrap_err();
        assert!(e.starts_with("value: 300: not a u8"), "{e}");
        let e = to_bytes(t("u8"), &json!(-1)).unwrap_err();
        assert!(e.starts_with("value: -1: not a u8"), "{e}");
        let e = to_bytes(t("vs"), &json!(5)).unwrap_err();
        assert!(e.contains("JSON string"), "{e}");
        let e = to_bytes(t("u8"), &json!([1])).unwrap_err();
        assert!(e.contains("number or string"), "{e}");
        assert!(data_type("u33").unwrap_err().contains("\"u33\""));
    }
}
