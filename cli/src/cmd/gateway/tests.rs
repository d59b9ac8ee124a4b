//! The parser on the request lines of CiA 309-3's and CANopenNode's examples, the data types'
//! text both ways, and the bounded line reader; property tests: no line panics, every value
//! reads back.

use super::lss::LssRequest;
use super::parse::{parse_line, Code, Command, HelpPage, Line, Request};
use super::serve::read_line;
use super::value::{base64_decode, base64_encode, c_g, encode_value, show_value, DataType, Word};
use super::MAX_LINE;
use duocan::cia305::{BitTiming, Inquiry, LssAddress};
use duocan::NmtCommand as N;
use proptest::prelude::*;

fn req(line: &str) -> Request {
    match parse_line(line) {
        Line::Request(r) => r,
        other => panic!("{line:?}: {other:?}"),
    }
}

fn err(line: &str) -> (Option<u32>, Code) {
    match parse_line(line) {
        Line::Error(seq, bad) => (seq, bad.code),
        other => panic!("{line:?}: {other:?}"),
    }
}

fn words(ws: &[&str]) -> Vec<Word> {
    ws.iter()
        .map(|w| Word {
            text: w.to_string(),
            quoted: false,
        })
        .collect()
}

#[test]
fn the_examples_of_the_standard_and_canopennode() {
    // Reading the heartbeat producer time of node 4 (CANopenNode's gateway documentation).
    assert_eq!(
        req("[1] 4 read 0x1017 0 i16"),
        Request {
            seq: 1,
            net: None,
            node: Some(4),
            command: Command::Read {
                index: 0x1017,
                sub: 0,
                ty: DataType::Int(2)
            }
        }
    );
    let r = req("[2] 1 4 w 0x1017 0 u16 1000");
    assert_eq!((r.seq, r.net, r.node), (2, Some(1), Some(4)));
    assert_eq!(
        r.command,
        Command::Write {
            index: 0x1017,
            sub: 0,
            data: vec![0xE8, 0x03]
        }
    );
    assert_eq!(req("[3] set node 4").command, Command::SetNode(4));
    // `[<net>] set …`: a single number before a network-level command is the net.
    let r = req("[4] 1 set sdo_timeout 1000");
    assert_eq!((r.net, r.node), (Some(1), None));
    assert_eq!(r.command, Command::SetSdoTimeout(1000));
    assert_eq!(
        req("[5] set sdo_block 1").command,
        Command::SetSdoBlock(true)
    );
    assert_eq!(req("[6] set network 1").command, Command::SetNetwork(1));
    // Any net names the one network served, as in CANopenNode's single-network gateway.
    assert_eq!(req("[6] set network 2").command, Command::SetNetwork(2));
    assert_eq!(req("[6] 2 5 start").net, Some(2));
    for (line, cmd) in [
        ("[7] 4 start", N::Start),
        ("[8] 4 stop", N::Stop),
        ("[9] 4 preop", N::EnterPreOperational),
        ("[10] 4 preoperational", N::EnterPreOperational),
        ("[11] 4 reset node", N::ResetNode),
        ("[12] 4 reset comm", N::ResetCommunication),
        ("[13] 4 reset communication", N::ResetCommunication),
        ("[14] 0 start", N::Start),
    ] {
        assert_eq!(req(line).command, Command::Nmt(cmd), "{line}");
    }
    assert_eq!(req("[15] info version").command, Command::Version);
    assert_eq!(req("[0] help").command, Command::Help(HelpPage::Requests));
    assert_eq!(
        req("[0] HELP Datatype").command,
        Command::Help(HelpPage::DataTypes)
    );
    assert_eq!(req("[0] help lss").command, Command::Help(HelpPage::Lss));
    // In upper case, with a comment and a CR LF line end.
    let r = req("[9] 4 R 0x1018 1 U32 # the vendor-ID\r");
    assert_eq!(r.seq, 9);
    assert_eq!(
        r.command,
        Command::Read {
            index: 0x1018,
            sub: 1,
            ty: DataType::Uint(4)
        }
    );
    // No type: the bytes in hex.
    assert!(matches!(
        req("[16] r 0x1008 0").command,
        Command::Read {
            ty: DataType::Bytes,
            ..
        }
    ));
}

#[test]
fn blank_lines_and_comments_are_not_requests() {
    for line in ["", "   ", "\t", "\r", "# a comment", "   # indented"] {
        assert_eq!(parse_line(line), Line::Empty, "{line:?}");
    }
}

#[test]
fn quoted_strings_keep_spaces_quotes_and_hashes() {
    let r = req(r#"[1] 4 w 0x2001 0 vs "say ""hi"" # not a comment""#);
    assert_eq!(
        r.command,
        Command::Write {
            index: 0x2001,
            sub: 0,
            data: b"say \"hi\" # not a comment".to_vec()
        }
    );
    // One bare word needs no quotes; an empty string does.
    assert!(
        matches!(req("[2] w 0x2001 0 vs word").command, Command::Write { data, .. } if data == b"word")
    );
    assert!(
        matches!(req(r#"[3] w 0x2001 0 vs """#).command, Command::Write { data, .. } if data.is_empty())
    );
}

#[test]
fn each_error_has_its_code() {
    use Code::*;
    for (line, seq, code) in [
        ("[1] 4 read", Some(1), Syntax),
        ("[2] 4 read 0x1017", Some(2), Syntax),
        ("[3] 4 read 0x1017 0 i17", Some(3), Syntax),
        ("[4] 4 read 0x10000 0 u8", Some(4), Syntax),
        ("[5] 4 read 0x1017 256 u8", Some(5), Syntax),
        ("[6] 4 read 0x1017 0 u8 extra", Some(6), Syntax),
        ("[7] 4 w 0x2000 0 u8 256", Some(7), Syntax),
        ("[8] 4 w 0x2000 0 i8 -129", Some(8), Syntax),
        ("[9] 4 w 0x2000 0 u8 -1", Some(9), Syntax),
        ("[10] 4 w 0x2000 0 u8", Some(10), Syntax),
        ("[11] 4 w 0x2000 0 b 256", Some(11), Syntax),
        ("[12] 4 w 0x2000 0 r32 nan", Some(12), Syntax),
        ("[13] 4 w 0x2000 0 d Zg=", Some(13), Syntax),
        (r#"[14] 4 w 0x2000 0 vs "open"#, Some(14), Syntax),
        (r#"[15] 4 w 0x2000 0 vs "a"b"#, Some(15), Syntax),
        ("[16] 4 w 0x2000 0 vs two words", Some(16), Syntax),
        ("[17] 4 reset", Some(17), Syntax),
        ("[18] 4 start now", Some(18), Syntax),
        ("[19] set sdo_block 2", Some(19), Syntax),
        ("[20] set sdo_timeout 0", Some(20), Syntax),
        ("[21] 1 2 3 start", Some(21), Syntax),
        ("[22]", Some(22), Syntax),
        ("[x] 4 start", None, Syntax),
        ("[1 4 start", None, Syntax),
        ("[23] 200 start", Some(23), UnsupportedNode),
        ("[24] set node 0", Some(24), UnsupportedNode),
        ("[25] set node 128", Some(25), UnsupportedNode),
        ("[26] 70000 4 start", Some(26), UnsupportedNet),
        ("[27] frobnicate", Some(27), NotSupported),
        ("[28] set colour blue", Some(28), NotSupported),
        ("[29] 4 1x start", Some(29), Syntax),
        ("[30] 1 4 set node 5", Some(30), Syntax),
        ("[31] help me", Some(31), Syntax),
        ("[32] help datatype lss", Some(32), Syntax),
        ("[33] lss_set_node 128", Some(33), Syntax),
        ("[34] lss_conf_bitrate 0 5", Some(34), Syntax),
        ("[35] lss_conf_bitrate 1 0", Some(35), Syntax),
        ("[36] lss_switch_glob 2", Some(36), Syntax),
        ("[37] lss_switch_sel 1 2 3", Some(37), Syntax),
        ("[38] lss_inquire_addr 4", Some(38), Syntax),
        ("[39] lss_store now", Some(39), Syntax),
        ("[40] lss_allnodes 100 0 1", Some(40), Syntax),
        (
            "[41] lss_allnodes 100 2 1 1 0 0 0 0 0 0 0",
            Some(41),
            NotSupported,
        ),
        ("[42] lss_frob", Some(42), NotSupported),
        ("[43] 4 5 lss_store", Some(43), Syntax),
    ] {
        assert_eq!(err(line), (seq, code), "{line}");
    }
}

#[test]
fn requests_of_309_3_this_gateway_does_not_carry_out_are_named_not_supported() {
    for line in [
        "[1] 4 enable guarding 100 3",
        "[2] 4 disable guarding",
        "[3] 4 enable heartbeat 500",
        "[4] 4 disable heartbeat",
        "[5] 1 set rpdo 1 0x201 255 1 0x6200 1 u8",
        "[6] set tpdo 1 0x181 254 1 u16",
        "[7] 1 r p 1",
        "[8] 1 write pdo 1 1 0x5",
        "[9] init 0",
        "[10] set heartbeat 100",
        "[11] set id 1",
        "[12] set command_timeout 1000",
        "[13] boot_up_indication Enable",
        "[16] led",
        "[17] log",
    ] {
        assert!(
            matches!(req(line).command, Command::NotSupported(_)),
            "{line}"
        );
    }
}

#[test]
fn a_line_without_its_sequence_number_is_a_syntax_error_not_a_request() {
    // CiA 309-3 writes the sequence number in every request; CANopenNode's gateway refuses a
    // request without one, and so does this one (the old gateway carried it out).
    for line in [
        "4 start",
        "r 0x1018 1 u32",
        "help",
        "[] start",
        "[-1] start",
    ] {
        assert_eq!(err(line), (None, Code::Syntax), "{line}");
    }
    let Line::Error(_, bad) = parse_line("5 r 0x1018 1 u32") else {
        unreachable!()
    };
    assert!(bad.why.unwrap().contains("[<sequence>]"));
}

#[test]
fn the_lss_requests_of_309_3_and_canopennode() {
    use LssRequest as L;
    let lss = |line: &str| match req(line).command {
        Command::Lss(l) => l,
        other => panic!("{line}: {other:?}"),
    };
    assert_eq!(lss("[1] lss_switch_glob 1"), L::SwitchGlobal(true));
    assert_eq!(lss("[2] 1 lss_switch_glob 0"), L::SwitchGlobal(false));
    assert_eq!(
        lss("[3] lss_switch_sel 0xD0CA00 0x305 1 2"),
        L::SwitchSelective(LssAddress {
            vendor: 0xD0_CA00,
            product: 0x305,
            revision: 1,
            serial: 2
        })
    );
    assert_eq!(lss("[4] lss_set_node 0x20"), L::SetNode(0x20));
    assert_eq!(lss("[5] lss_set_node 255"), L::SetNode(0xFF));
    assert_eq!(lss("[5] lss_set_node 0"), L::SetNode(0));
    assert_eq!(
        lss("[6] lss_conf_bitrate 0 2"),
        L::ConfBitrate(BitTiming::standard(2))
    );
    assert_eq!(lss("[7] lss_activate_bitrate 100"), L::ActivateBitrate(100));
    assert_eq!(lss("[8] LSS_STORE"), L::Store);
    assert_eq!(lss("[9] lss_inquire_addr"), L::InquireAddr(None));
    assert_eq!(
        lss("[10] lss_inquire_addr 3"),
        L::InquireAddr(Some(Inquiry::Serial))
    );
    assert_eq!(lss("[11] lss_get_node"), L::GetNode);
    assert_eq!(lss("[12] _lss_fastscan"), L::Fastscan);
    assert_eq!(lss("[13] _lss_fastscan 200"), L::Fastscan);
    let all = |first, store| L::AllNodes { first, store };
    assert_eq!(lss("[14] lss_allnodes"), all(2, true));
    assert_eq!(lss("[15] lss_allnodes 100"), all(2, true));
    assert_eq!(lss("[16] lss_allnodes 100 0x20 0"), all(0x20, false));
    assert_eq!(
        lss("[17] lss_allnodes 100 5 1 0 0 0 0 0 0 0 0"),
        all(5, true)
    );
}

#[test]
fn data_types_read_and_write_their_text() {
    let cases: &[(&str, &[&str], &[u8], &str)] = &[
        ("b", &["1"], &[1], "1"),
        ("i8", &["-128"], &[0x80], "-128"),
        ("i16", &["-2"], &[0xFE, 0xFF], "-2"),
        ("i24", &["-1"], &[0xFF, 0xFF, 0xFF], "-1"),
        (
            "i64",
            &["-9223372036854775808"],
            &[0, 0, 0, 0, 0, 0, 0, 0x80],
            "-9223372036854775808",
        ),
        ("u8", &["0xFF"], &[0xFF], "255"),
        ("u16", &["1000"], &[0xE8, 0x03], "1000"),
        ("u40", &["0x0102030405"], &[5, 4, 3, 2, 1], "4328719365"),
        (
            "u64",
            &["18446744073709551615"],
            &[0xFF; 8],
            "18446744073709551615",
        ),
        ("x8", &["10"], &[10], "0x0A"),
        ("x16", &["0xff"], &[0xFF, 0], "0x00FF"),
        ("x32", &["0x00D0CA00"], &[0, 0xCA, 0xD0, 0], "0x00D0CA00"),
        ("r32", &["1.5"], &[0, 0, 0xC0, 0x3F], "1.5"),
        ("r64", &["-0.25"], &[0, 0, 0, 0, 0, 0, 0xD0, 0xBF], "-0.25"),
        ("vs", &["word"], b"word", "\"word\""),
        ("os", &["AQID"], &[1, 2, 3], "AQID"),
        ("d", &["AAECAwQ="], &[0, 1, 2, 3, 4], "AAECAwQ="),
        ("us", &["QQBCAA=="], &[b'A', 0, b'B', 0], "QQBCAA=="),
        (
            "t",
            &["15000", "43200000"],
            &[0x00, 0x2E, 0x93, 0x02, 0x98, 0x3A],
            "15000 43200000",
        ),
        ("hex", &["01", "0a", "FF"], &[1, 0x0A, 0xFF], "01 0A FF"),
    ];
    for (ty, text, bytes, shown) in cases {
        let t = DataType::parse(ty).unwrap_or_else(|| panic!("{ty}"));
        assert_eq!(
            encode_value(t, &words(text)).as_deref(),
            Ok(*bytes),
            "{ty} {text:?}"
        );
        assert_eq!(show_value(t, bytes), *shown, "{ty}");
    }
    // A visible string read shows in quotes, a quote doubled, NUL padding dropped, a control
    // character replaced: the response stays one line.
    assert_eq!(
        show_value(DataType::Visible, b"a \"b\"\nc\0\r\0"),
        "\"a \"\"b\"\"\u{FFFD}c\""
    );
    // A boolean is written as a byte, in any number form; the node judges its value.
    for text in ["1", "0x1", "01"] {
        assert_eq!(
            encode_value(DataType::Bool, &words(&[text])).as_deref(),
            Ok(&[1u8][..])
        );
    }
    for bad in ["256", "-1", "true", ""] {
        assert!(
            encode_value(DataType::Bool, &words(&[bad])).is_err(),
            "{bad}"
        );
    }
    for ty in ["i8", "u8", "x8", "r32", "r64", "t", "b"] {
        let t = DataType::parse(ty).unwrap();
        assert!(encode_value(t, &[]).is_err(), "{ty}");
    }
    // A value read whose size is not its type's shows as the bytes the node sent, as
    // CANopenNode's gateway shows it (the old gateway answered 0x06070010).
    assert_eq!(show_value(DataType::Uint(4), &[0xE8, 0x03]), "E8 03");
    assert_eq!(show_value(DataType::Real32, &[0x64, 0]), "64 00");
    assert_eq!(show_value(DataType::Bool, &[]), "");
    for bad in ["x24", "u", "i0", "u128", "f32", "str", ""] {
        assert_eq!(DataType::parse(bad), None, "{bad}");
    }
}

#[test]
fn real_numbers_read_as_c_prints_them_with_percent_g() {
    // What glibc's printf("%g") prints for each (CANopenNode's gateway answers that text).
    for (v, shown) in [
        (1.5, "1.5"),
        (-0.25, "-0.25"),
        (100000.0, "100000"),
        (1_000_000.0, "1e+06"),
        (123_456_789.0, "1.23457e+08"),
        (std::f64::consts::PI, "3.14159"),
        (0.0001, "0.0001"),
        (0.000_012_5, "1.25e-05"),
        (1e-300, "1e-300"),
        (1e300, "1e+300"),
        (999_999.5, "1e+06"),
        (0.0, "0"),
        (-0.0, "-0"),
        (f64::INFINITY, "inf"),
        (f64::NEG_INFINITY, "-inf"),
        (f64::NAN, "nan"),
    ] {
        assert_eq!(c_g(v), shown, "{v:e}");
    }
    // REAL32 is widened to a double first, as C passes a float to printf: 0.1f shows 0.1.
    assert_eq!(show_value(DataType::Real32, &0.1f32.to_le_bytes()), "0.1");
    assert_eq!(
        show_value(DataType::Real32, &16_777_216f32.to_le_bytes()),
        "1.67772e+07"
    );
    assert_eq!(
        show_value(DataType::Real64, &(2.0f64 / 3.0).to_le_bytes()),
        "0.666667"
    );
}

#[test]
fn base64_is_rfc_4648_with_padding_and_strict() {
    for (plain, coded) in [
        ("", ""),
        ("f", "Zg=="),
        ("fo", "Zm8="),
        ("foo", "Zm9v"),
        ("foob", "Zm9vYg=="),
        ("fooba", "Zm9vYmE="),
        ("foobar", "Zm9vYmFy"),
    ] {
        assert_eq!(base64_encode(plain.as_bytes()), coded);
        assert_eq!(base64_decode(coded).as_deref(), Some(plain.as_bytes()));
    }
    for bad in [
        "Zg", "Zg=", "Zh==", "Z===", "Zg==Zg==", "Zm9v!A==", "Zm 9v", "====",
    ] {
        assert_eq!(base64_decode(bad), None, "{bad}");
    }
}

#[tokio::test]
async fn a_line_too_long_is_dropped_without_being_held() {
    let mut input = vec![b'x'; MAX_LINE + 10];
    input.extend_from_slice(b"\n[1] start\r\nlast");
    let mut r = &input[..];
    let mut buf = Vec::new();
    assert_eq!(read_line(&mut r, &mut buf).await.unwrap(), Some(false));
    assert!(buf.len() <= MAX_LINE);
    assert_eq!(read_line(&mut r, &mut buf).await.unwrap(), Some(true));
    assert_eq!(buf, b"[1] start\r");
    assert_eq!(read_line(&mut r, &mut buf).await.unwrap(), Some(true));
    assert_eq!(buf, b"last");
    assert_eq!(read_line(&mut r, &mut buf).await.unwrap(), None);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(3000))]

    #[test]
    fn no_line_panics(s in any::<String>()) {
        let _ = parse_line(&s);
    }

    #[test]
    fn no_line_of_request_words_panics(
        words in proptest::collection::vec(
            prop_oneof![
                Just("[7]".to_string()), Just("5".to_string()), Just("0x1018".to_string()),
                Just("r".to_string()), Just("w".to_string()), Just("set".to_string()),
                Just("node".to_string()), Just("vs".to_string()), Just("u32".to_string()),
                Just("\"".to_string()), Just("\"\"".to_string()), Just("#".to_string()),
                Just("reset".to_string()), Just("-1".to_string()), Just("d".to_string()),
                Just("lss_allnodes".to_string()), Just("_lss_fastscan".to_string()),
                Just("lss_set_node".to_string()), Just("lss_switch_sel".to_string()),
                Just("lss_conf_bitrate".to_string()), Just("help".to_string()),
                Just("0".to_string()), Just("2".to_string()), Just("b".to_string()),
                "[ -~]{0,6}",
            ],
            0..12,
        )
    ) {
        let line = words.join(" ");
        match parse_line(&line) {
            Line::Empty | Line::Request(_) | Line::Error(..) => {}
        }
    }

    #[test]
    fn base64_reads_back(b in proptest::collection::vec(any::<u8>(), 0..64)) {
        prop_assert_eq!(base64_decode(&base64_encode(&b)), Some(b));
    }

    #[test]
    fn integers_read_back(v in any::<i64>(), n in 1u8..=8) {
        let bits = 8 * u32::from(n);
        let v = v >> (64 - bits); // in range for n bytes
        let ty = DataType::Int(n);
        let bytes = encode_value(ty, &words(&[&v.to_string()])).unwrap();
        prop_assert_eq!(bytes.len(), usize::from(n));
        prop_assert_eq!(show_value(ty, &bytes), v.to_string());
    }

    #[test]
    fn visible_strings_read_back(s in "[ -~]{0,40}") {
        let quoted = show_value(DataType::Visible, s.as_bytes());
        let line = format!("[1] w 0x2000 0 vs {quoted}");
        prop_assert_eq!(
            req(&line).command,
            Command::Write { index: 0x2000, sub: 0, data: s.into_bytes() }
        );
    }
}
