//! The candump format: writing, strict reading, bounded lines.

use super::*;
use proptest::prelude::*;

#[test]
fn formats_like_candump() {
    let f = Frame::from_array(Id::Standard(0x123), [0xDE, 0xAD, 0xBE, 0xEF]);
    assert_eq!(
        format_frame(1_700_000_000_123_456, "vcan0", &f),
        "(1700000000.123456) vcan0 123#DEADBEEF"
    );
    let r = Frame::remote(Id::Extended(0x1234567), 3).unwrap();
    assert_eq!(format_frame(5, "can1", &r), "(0.000005) can1 01234567#R3");
    let e = Frame::new(Id::Standard(0x80), &[]).unwrap();
    assert_eq!(format_frame(0, "x", &e), "(0.000000) x 080#");
}

#[test]
fn parses_can_utils_variants() {
    let l = parse_line("(1700000000.123456) vcan0 123#DE.AD.BE.EF").unwrap();
    assert_eq!(l.timestamp_us, 1_700_000_000_123_456);
    assert_eq!(
        l.record,
        Record::Frame(Frame::from_array(
            Id::Standard(0x123),
            [0xDE, 0xAD, 0xBE, 0xEF]
        ))
    );
    let r = parse_line("(1.5) can0 701#R").unwrap();
    assert_eq!(r.timestamp_us, 1_500_000);
    assert_eq!(
        r.record,
        Record::Frame(Frame::remote(Id::Standard(0x701), 0).unwrap())
    );
    let e = parse_line("(1.000001) can0 20000040#0000000000000000").unwrap();
    assert_eq!(
        e.record,
        Record::Error {
            bits: 0x40,
            data: [0; 8]
        }
    );
    let fd = parse_line("(1.000001) can0 123##1112233").unwrap();
    assert_eq!(
        fd.record,
        Record::Fd(Box::new(
            FdFrame::new(Id::Standard(0x123), &[0x11, 0x22, 0x33])
                .unwrap()
                .with_brs(true)
        ))
    );
    // FDF (4), as newer can-utils may write it, restates `##` and is dropped; ESI is kept.
    let fdf = parse_line("(1.000001) 0 12345678##600").unwrap();
    let f = fdf.record.fd_frame().unwrap();
    assert_eq!(
        (f.id(), f.flags(), f.data()),
        (Id::Extended(0x1234_5678), 2, &[0][..])
    );
    let dlc = parse_line("(1.000001) can0 123#1122334455667788_E").unwrap();
    assert_eq!(dlc.record.frame().unwrap().dlc(), 8);
    assert!(parse_line("(1.000001) can0 123#11 R").is_ok());
}

#[test]
fn bad_and_truncated_lines_are_errors_with_line_numbers() {
    let log = "(1.000000) can0 123#11\n(1.000001) can0 12\n(1.0000\n\n(2.000000) can0 800#00\n(3.000000) can0 123#112";
    let items: Vec<_> = read_log("t.log", log.as_bytes()).collect();
    assert_eq!(items.len(), 5);
    assert!(items[0].is_ok());
    assert_eq!(items[1].as_ref().unwrap_err().line, 2);
    assert_eq!(items[2].as_ref().unwrap_err().line, 3);
    assert!(items[3]
        .as_ref()
        .unwrap_err()
        .reason
        .contains("above 0x7FF"));
    assert_eq!(items[4].as_ref().unwrap_err().line, 6);
    assert_eq!(
        items[3].as_ref().unwrap_err().to_string(),
        "t.log, line 5: standard identifier 800 above 0x7FF"
    );
    for bad in [
        "",
        "(x.1) a 1#",
        "(1.1234567890) a 123#",
        "(1.1) a 123#123456789012345678",
        "(1.1) a 1234#00",
        "(1.1) a 123#RZ",
        "(1.1) a 123##",
    ] {
        assert!(parse_line(bad).is_err(), "{bad:?} parsed");
    }
}

/// The reason `parse_line` gives for `line`.
fn reason(line: &str) -> String {
    match parse_line(line) {
        Ok(e) => panic!("{line:?} parsed as {e:?}"),
        Err(e) => e.reason,
    }
}

#[test]
fn signs_and_stray_characters_are_refused_in_every_token() {
    for (line, what) in [
        ("(+1.000000) can0 123#11", "seconds are not decimal digits"),
        ("(1.+00000) can0 123#11", "fraction is not"),
        ("(-1.000000) can0 123#11", "seconds are not decimal digits"),
        ("(1.000000 can0 123#11", "not in parentheses"),
        ("(1) can0 123#11", "no fraction"),
        (
            "(99999999999999999999.0) can0 123#11",
            "seconds out of range",
        ),
        ("(1.0) can0 +23#11", "identifier \"+23\" is not hexadecimal"),
        ("(1.0) can0 +1234567#11", "is not hexadecimal"),
        ("(1.0) can0 12G#11", "is not hexadecimal"),
        ("(1.0) can0 #11", "identifier \"\" is not hexadecimal"),
        ("(1.0) can0 12345#11", "has 5 digits"),
        ("(1.0) can0 20000000A#11", "has 9 digits"),
        ("(1.0) can0 123#+1", "data \"+1\": not hexadecimal"),
        ("(1.0) can0 123#1+", "not hexadecimal"),
        ("(1.0) can0 123#GG", "not hexadecimal"),
        ("(1.0) can0 123#1", "pairs"),
        ("(1.0) can0 123#.11", "pairs"),
        ("(1.0) can0 123#11.", "pairs"),
        ("(1.0) can0 123#11..22", "pairs"),
        ("(1.0) can0 123#112233445566778899", "more than 8 bytes"),
        ("(1.0) can0 123#R9", "DLC digit 0–8"),
        ("(1.0) can0 123#R+", "DLC digit 0–8"),
        ("(1.0) can0 123#R12", "DLC digit 0–8"),
        ("(1.0) can0 123#11_E", "one digit 9–F after 8 data bytes"),
        ("(1.0) can0 123#1122334455667788_8", "one digit 9–F"),
        ("(1.0) can0 123#1122334455667788_EE", "one digit 9–F"),
        ("(1.0) can0 123##", "no flags digit"),
        ("(1.0) can0 123##1112233445566778899", "9 data bytes"),
        ("(1.0) can0 123##F", "only BRS (1), ESI (2) and FDF (4)"),
        ("(1.0) can0 123##G00", "no flags digit"),
        ("(1.0) can0 123##1R0", "not hexadecimal"),
        ("(1.0) can0 123##1112", "pairs"),
        (
            format!("(1.0) can0 123##1{}", "00".repeat(65)).as_str(),
            "more than 64 bytes",
        ),
        (
            format!("(1.0) can0 123##0{}", "00".repeat(33)).as_str(),
            "33 data bytes",
        ),
        ("(1.0) can0 FFFFFFFF#", "bits above the error flag"),
        (
            "(1.0) can0 80000123#11",
            "extended identifier 80000123 above",
        ),
        (
            "(1.0) can0 3FFFFFFF#",
            "error frame with 0 data bytes, not 8",
        ),
        ("(1.0) can0 20000040#+0", "not hexadecimal"),
        ("(1.0) can0 123", "no '#'"),
        ("(1.0) can0", "missing frame"),
        ("(1.0)", "missing interface"),
        ("(1.0) can0 123#11 X", "only a direction R or T"),
        ("(1.0) can0 123#11 R junk", "unexpected \"junk\" at the end"),
        ("(1.0) can0 123#11 123#22", "unexpected \"123#22\""),
        ("(1.0) can0\u{7f} 123#11", "not printable ASCII"),
        (
            "(1.0) an-interface-name-of-forty-characters 123#11",
            "longer than 32 characters",
        ),
    ] {
        let r = reason(line);
        assert!(r.contains(what), "{line:?}: {r:?} does not say {what:?}");
    }
    // The accepted forms around them still parse.
    for ok in [
        "(1.0) can0 123#11 T",
        "(1.0) can0 123#R8",
        "(1.0) can0 123#r",
        "(1.0) can0 123#1122334455667788_9",
        "(1.0) can0 123##7",
        "(1.0) can0 123##0112233445566778899AABBCC",
        "(1.0) can0 1FFFFFFF#",
        "(1.0) can0 3FFFFFFF#0000000000000000",
        "(1.0) can0 123#",
        "(0.1234567) can0 7FF#11.22",
    ] {
        assert!(parse_line(ok).is_ok(), "{ok:?}: {:?}", parse_line(ok));
    }
    assert_eq!(
        parse_line("(0.1234567) a 123#").unwrap().timestamp_us,
        123_456
    );
}

#[test]
fn errors_name_the_source_the_line_and_the_token() {
    let log = "(1.0) can0 123#11\r\n\n(1.0) can0 123#11 trailing\n(1.0) c\u{e4}n0 123#11\n(1.0) can0 7FF#";
    let items: Vec<_> = read_log("racks/signal.log", log.as_bytes()).collect();
    assert_eq!(items.len(), 4);
    assert!(items[0].is_ok(), "a CR before the line end is allowed");
    assert_eq!(
        items[1].as_ref().unwrap_err().to_string(),
        r#"racks/signal.log, line 3: unexpected "trailing" after the frame (only a direction R or T may follow)"#
    );
    assert_eq!(
        items[2].as_ref().unwrap_err().to_string(),
        "racks/signal.log, line 4: byte 0xC3 at column 8 is not ASCII"
    );
    assert!(items[3].is_ok(), "reading goes on after a bad line");
    assert_eq!(
        parse_line("(1.0) can0 123#+1").unwrap_err().to_string(),
        r#"candump line: data "+1": not hexadecimal digits"#
    );
    let missing = CandumpReader::open("/nonexistent/duocan.log").unwrap_err();
    assert_eq!(missing.source, "/nonexistent/duocan.log");
    assert!(missing
        .to_string()
        .starts_with("/nonexistent/duocan.log: cannot open:"));
}

/// A reader of `len` bytes of `b'A'` that counts what was taken from it.
struct Endless {
    left: u64,
    taken: std::rc::Rc<std::cell::Cell<u64>>,
}

impl std::io::Read for Endless {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = (buf.len() as u64).min(self.left) as usize;
        buf[..n].fill(b'A');
        self.left -= n as u64;
        self.taken.set(self.taken.get() + n as u64);
        Ok(n)
    }
}

#[test]
fn a_one_gigabyte_line_fails_at_once_with_bounded_memory() {
    let taken = std::rc::Rc::new(std::cell::Cell::new(0));
    let gib = Endless {
        left: 1 << 30,
        taken: taken.clone(),
    };
    let mut r = read_log("huge.log", std::io::BufReader::with_capacity(1024, gib));
    let e = r.next().unwrap().unwrap_err();
    assert_eq!(
        e.to_string(),
        format!("huge.log, line 1: line longer than {MAX_LINE} bytes: not a candump log")
    );
    assert!(r.next().is_none(), "reading stops at the long line");
    // Only the bound and one buffer's worth were read from the source, and held.
    assert!(taken.get() <= 2048, "read {} bytes", taken.get());
    assert!(r.held() <= 2 * (MAX_LINE + 1));
    // A line of exactly MAX_LINE bytes is read (and refused as a line, not for its length).
    let line = "A".repeat(MAX_LINE) + "\n(1.0) can0 123#11\n";
    let items: Vec<_> = read_log("edge.log", line.as_bytes()).collect();
    assert_eq!(items.len(), 2);
    assert!(!items[0].as_ref().unwrap_err().reason.contains("longer"));
    assert!(items[1].is_ok());
}

proptest! {
    #[test]
    fn round_trip(f in crate::frame::arbitrary::any_frame(), ts in 0u64..4_000_000_000_000_000) {
        let line = format_frame(ts, "vcan1", &f);
        let e = parse_line(&line).unwrap();
        prop_assert_eq!(e.timestamp_us, ts);
        prop_assert_eq!(e.interface, "vcan1");
        prop_assert_eq!(e.record, Record::Frame(f));
    }

    #[test]
    fn fd_round_trip(f in crate::frame::arbitrary::any_fd_frame(), ts in 0u64..4_000_000_000_000_000) {
        let line = format_fd_frame(ts, "can0", &f);
        prop_assert!(line.len() < MAX_LINE);
        let e = parse_line(&line).unwrap();
        prop_assert_eq!(e.timestamp_us, ts);
        prop_assert_eq!(e.record, Record::Fd(Box::new(f)));
        // Through the writer and the reader, between classic lines.
        let c = Frame::from_array(Id::Standard(0x701), [5]);
        let mut w = CandumpWriter::new(Vec::new());
        w.write(ts, "can0", &c).unwrap();
        w.write_fd(ts, "can1", &f).unwrap();
        w.write(ts, "can0", &c).unwrap();
        let text = w.into_inner();
        let back: Vec<_> = read_log("fd.log", &text[..]).map(|e| e.unwrap().record).collect();
        prop_assert_eq!(back, vec![Record::Frame(c), Record::Fd(Box::new(f)), Record::Frame(c)]);
    }

    #[test]
    fn arbitrary_text_never_panics(s in "\\PC{0,60}") {
        let _ = parse_line(&s);
    }

    #[test]
    fn arbitrary_bytes_never_panic(b in proptest::collection::vec(any::<u8>(), 0..2000)) {
        for item in read_log("any", &b[..]) {
            let _ = item;
        }
    }
}
