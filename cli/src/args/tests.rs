//! The tool's parsers: the inputs that panicked or were misread before, the exact errors, and
//! property tests that no string panics and every valid number reads back.

use crate::args::*;
use clap::ValueEnum;
use proptest::prelude::*;

fn err<T: std::fmt::Debug>(r: Result<T, String>) -> String {
    r.expect_err("parsed")
}

#[test]
fn inputs_that_panicked_or_were_misread_are_errors() {
    // Negation overflow in the old parser.
    assert_eq!(
        err(parse_node("--170141183460469231731687303715884105728")),
        "\"--170141183460469231731687303715884105728\" is not a number: no sign allowed here"
    );
    // Was read as node 5.
    assert_eq!(
        err(parse_node("-0x-5")),
        "\"-0x-5\" is not a number: no sign allowed here"
    );
    assert_eq!(
        err(parse_signed::<i32>("-0x-5", "i32")),
        "\"-0x-5\" is not a number: '-' is not a hex digit"
    );
    assert_eq!(
        err(parse_signed::<i64>("--5", "i64")),
        "\"--5\" is not a number: '-' is not a decimal digit (hex needs 0x)"
    );
    // Byte slicing through a multi-byte character.
    assert_eq!(
        err(encode(Type::Hex, "0é")),
        "\"0é\" is not hex (digits 0-9, a-f)"
    );
    assert_eq!(
        err(encode(Type::Hex, "éé")),
        "\"éé\" is not hex (digits 0-9, a-f)"
    );
    assert_eq!(
        err(parse_index("0x1é")),
        "\"0x1é\" is not a number: 'é' is not a hex digit"
    );
}

#[test]
fn numbers_are_decimal_or_0x_hex_and_nothing_else() {
    assert_eq!(parse_index("0x1018"), Ok(0x1018));
    assert_eq!(parse_index("0X1018"), Ok(0x1018));
    assert_eq!(parse_index("4120"), Ok(4120));
    assert_eq!(parse_sub("007"), Ok(7));
    assert_eq!(parse_node("0x7f").map(|n| n.raw()), Ok(127));
    assert_eq!(parse_signed::<i8>("-128", "i8"), Ok(-128));
    assert_eq!(
        parse_signed::<i64>("-0x8000000000000000", "i64"),
        Ok(i64::MIN)
    );
    assert_eq!(
        parse_unsigned::<u64>("18446744073709551615", "u64"),
        Ok(u64::MAX)
    );
    for bad in [
        "", "+5", " 5", "5 ", "5\n", "0x", "-", "-0x", "0x-5", "1_000", "1e3", "٣", "５", "0b101",
        "0o7", "x10", "10x", "0x+5", "- 5",
    ] {
        assert!(parse_sub(bad).is_err(), "{bad:?} parsed");
        assert!(
            parse_signed::<i64>(bad, "i64").is_err(),
            "{bad:?} parsed signed"
        );
    }
    assert_eq!(err(parse_node("0")), "node-ID 0: a node-ID is 1-127");
    assert_eq!(err(parse_node("128")), "node-ID 128: a node-ID is 1-127");
    assert_eq!(err(parse_node("256")), "256 does not fit a node-ID (1-127)");
    assert_eq!(
        err(parse_node("-5")),
        "\"-5\" is not a number: no sign allowed here"
    );
    assert_eq!(
        err(parse_index("0x10000")),
        "0x10000 does not fit an object index (0-0xFFFF)"
    );
    assert_eq!(
        err(parse_sub("256")),
        "256 does not fit a sub-index (0-255)"
    );
    assert_eq!(
        err(parse_signed::<i8>("-129", "i8")),
        "-129 does not fit i8"
    );
    assert_eq!(
        err(parse_unsigned::<u64>("18446744073709551616", "u64")),
        "\"18446744073709551616\" is not a number: too large"
    );
    assert_eq!(
        err(parse_unsigned::<u64>(&"9".repeat(500), "u64")),
        format!("{:?} is not a number: too large", "9".repeat(500))
    );
    assert_eq!(parse_timeout_ms("200"), Ok(200));
    assert_eq!(
        err(parse_timeout_ms("0")),
        "timeout 0 ms: give 1 to 3600000 (an hour)"
    );
    assert!(parse_timeout_ms("3600001").is_err());
}

#[test]
fn values_to_write() {
    assert_eq!(encode(Type::U16, "100"), Ok(vec![100, 0]));
    assert_eq!(encode(Type::I16, "-2"), Ok(vec![0xFE, 0xFF]));
    assert_eq!(encode(Type::U32, "0xA5A50001"), Ok(vec![1, 0, 0xA5, 0xA5]));
    assert_eq!(err(encode(Type::U8, "300")), "300 does not fit u8");
    assert_eq!(
        err(encode(Type::U8, "-1")),
        "\"-1\" is not a number: no sign allowed here"
    );
    assert_eq!(encode(Type::F32, "1.5"), Ok(1.5f32.to_le_bytes().to_vec()));
    assert_eq!(
        encode(Type::F32, "-2.5e-3"),
        Ok((-2.5e-3f32).to_le_bytes().to_vec())
    );
    assert_eq!(encode(Type::F32, "1e+2"), Ok(100f32.to_le_bytes().to_vec()));
    for bad in [
        "+1.5", "inf", "NaN", "1.5.", "--1", "1-", "1e40", " 1", "1,5", "",
    ] {
        assert!(encode(Type::F32, bad).is_err(), "{bad:?} parsed as f32");
    }
    assert_eq!(encode(Type::Hex, "01 02 0a ff"), Ok(vec![1, 2, 0x0A, 0xFF]));
    assert_eq!(encode(Type::Hex, "0x0102"), Ok(vec![1, 2]));
    assert_eq!(
        err(encode(Type::Hex, "012")),
        "\"012\": give whole bytes in hex, like 01020a"
    );
    assert!(encode(Type::Hex, "+1").is_err());
    assert_eq!(encode(Type::Str, "héllo"), Ok("héllo".as_bytes().to_vec()));
}

#[test]
fn udp_ports() {
    assert_eq!(parse_udp("udp"), Some(Ok(UdpSpec::Default)));
    assert_eq!(parse_udp("udp:3"), Some(Ok(UdpSpec::Numbered(3))));
    assert_eq!(
        parse_udp("udp:239.0.0.1:5000"),
        Some(Ok(UdpSpec::Group([239, 0, 0, 1].into(), 5000)))
    );
    assert_eq!(parse_udp("vcan0"), None);
    assert_eq!(parse_udp("udpcan0"), None);
    for bad in [
        "udp:+5",
        "udp:256",
        "udp:x",
        "udp:",
        "udp:1:2:3",
        "udp:239.0.0.1:+80",
        "udp:1.2.3:80",
    ] {
        assert!(matches!(parse_udp(bad), Some(Err(_))), "{bad:?}");
    }
}

/// A number's text in one of the accepted spellings.
fn spelled(v: i128, hex: bool, upper_x: bool) -> String {
    let sign = if v < 0 { "-" } else { "" };
    let m = v.unsigned_abs();
    match (hex, upper_x) {
        (false, _) => format!("{sign}{m}"),
        (true, false) => format!("{sign}0x{m:x}"),
        (true, true) => format!("{sign}0X{m:X}"),
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn no_string_panics(s in any::<String>()) {
        let _ = parse_int(&s, false);
        let _ = parse_int(&s, true);
        let _ = parse_node(&s);
        let _ = parse_index(&s);
        let _ = parse_sub(&s);
        let _ = parse_timeout_ms(&s);
        let _ = parse_udp(&s);
        for ty in Type::value_variants() {
            let _ = encode(*ty, &s);
        }
    }

    #[test]
    fn no_number_like_string_panics(s in "[-+0-9a-fA-FxX. eé_]{0,30}") {
        let _ = parse_int(&s, true);
        let _ = parse_node(&s);
        let _ = parse_udp(&format!("udp:{s}"));
        for ty in Type::value_variants() {
            let _ = encode(*ty, &s);
        }
    }

    #[test]
    fn unsigned_numbers_read_back(v in any::<u64>(), hex in any::<bool>(), up in any::<bool>()) {
        let s = spelled(i128::from(v), hex, up);
        prop_assert_eq!(parse_unsigned::<u64>(&s, "u64"), Ok(v));
        prop_assert_eq!(parse_int(&s, false), Ok(i128::from(v)));
        prop_assert_eq!(encode(Type::U64, &s), Ok(v.to_le_bytes().to_vec()));
    }

    #[test]
    fn signed_numbers_read_back(v in any::<i64>(), hex in any::<bool>(), up in any::<bool>()) {
        let s = spelled(i128::from(v), hex, up);
        prop_assert_eq!(parse_signed::<i64>(&s, "i64"), Ok(v));
        prop_assert_eq!(encode(Type::I64, &s), Ok(v.to_le_bytes().to_vec()));
        // A second sign in front never parses.
        let doubled = format!("--{}", s.trim_start_matches('-'));
        prop_assert!(parse_signed::<i64>(&doubled, "i64").is_err());
        // Unsigned fields refuse any sign, even on zero.
        if v < 0 {
            prop_assert!(parse_int(&s, false).is_err());
        }
    }

    #[test]
    fn node_ids_read_back_and_nothing_else(v in 0u32..1000, hex in any::<bool>()) {
        let s = spelled(i128::from(v), hex, false);
        match parse_node(&s) {
            Ok(n) => prop_assert!((1..=127).contains(&v) && u32::from(n.raw()) == v),
            Err(_) => prop_assert!(!(1..=127).contains(&v)),
        }
    }

    #[test]
    fn hex_bytes_read_back(b in proptest::collection::vec(any::<u8>(), 1..64), spaced in any::<bool>()) {
        let s: Vec<String> = b.iter().map(|x| format!("{x:02x}")).collect();
        let s = s.join(if spaced { " " } else { "" });
        prop_assert_eq!(parse_hex_bytes(&s), Ok(b));
    }
}
