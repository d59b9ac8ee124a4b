//! pcap layout, strict reading, errors with the record.

use super::*;
use proptest::prelude::*;

fn file(frames: &[(u64, Frame)]) -> Vec<u8> {
    let mut w = PcapWriter::new(Vec::new()).unwrap();
    for (t, f) in frames {
        w.write(*t, f).unwrap();
    }
    w.into_inner()
}

#[test]
fn header_and_packet_layout() {
    let b = file(&[(
        1_700_000_000_000_001,
        Frame::from_array(Id::Extended(0x1234_5678), [0xAA]),
    )]);
    assert_eq!(&b[..4], &[0xD4, 0xC3, 0xB2, 0xA1]);
    assert_eq!(u32::from_le_bytes(b[20..24].try_into().unwrap()), 227);
    // record header then 0x92345678 (EFF flag) big-endian, len 1, 3 reserved, data.
    assert_eq!(&b[40..49], &[0x92, 0x34, 0x56, 0x78, 1, 0, 0, 0, 0xAA]);
    assert_eq!(b.len(), 24 + 16 + 9);
}

#[test]
fn truncated_and_foreign_files_are_errors() {
    let b = file(&[
        (1, Frame::from_array(Id::Standard(0x181), [1, 2, 3])),
        (2, Frame::from_array(Id::Standard(0x701), [5])),
    ]);
    for cut in 0..b.len() {
        let r = PcapReader::new(&b[..cut]);
        let Ok(r) = r else { continue };
        let items: Vec<_> = r.collect();
        let complete = items.iter().filter(|x| x.is_ok()).count();
        if cut == 24 || cut == 24 + 27 || cut == b.len() {
            assert!(items.iter().all(|x| x.is_ok()), "cut {cut}");
        } else {
            assert!(
                matches!(items.last(), Some(Err(PcapError::Truncated { .. }))),
                "cut {cut}: {items:?}"
            );
        }
        assert!(complete <= 2);
    }
    assert!(matches!(
        PcapReader::new(&b"hello world, not pcap"[..]),
        Err(PcapError::NotPcap)
    ));
    let mut other = b.clone();
    other[20] = 1;
    assert!(matches!(
        PcapReader::new(&other[..]),
        Err(PcapError::LinkType(1))
    ));
    let mut huge = b.clone();
    huge[32..36].copy_from_slice(&1_000_000u32.to_le_bytes());
    let first = PcapReader::new(&huge[..]).unwrap().next().unwrap();
    assert!(matches!(first, Err(PcapError::Oversized { .. })));
}

/// The file's bytes with the identifier word at byte `at` replaced.
fn with_word(mut b: Vec<u8>, at: usize, word: u32) -> Vec<u8> {
    b[at..at + 4].copy_from_slice(&word.to_be_bytes());
    b
}

/// The error of the second of `items`, checked to be a bad packet, record 2 at byte 49 (after
/// a 24-byte file header and a 25-byte first record).
fn second_is_bad_at_49(items: &[Result<Packet, PcapError>]) -> &PcapError {
    let e = items[1].as_ref().unwrap_err();
    assert!(
        matches!(
            e,
            PcapError::BadPacket {
                record: 2,
                offset: 49,
                ..
            }
        ),
        "{e:?}"
    );
    e
}

#[test]
fn standard_identifier_above_0x7ff_is_an_error_not_masked() {
    let frames = [
        (1, Frame::from_array(Id::Standard(0x181), [1])),
        (2, Frame::from_array(Id::Standard(0x182), [2])),
        (3, Frame::from_array(Id::Standard(0x183), [3])),
    ];
    // Records are 16 + 8 + 1 bytes; the second one's identifier word is at 24 + 25 + 16.
    let b = with_word(file(&frames), 24 + 25 + 16, 0x0000_0981);
    let items: Vec<_> = PcapReader::new(&b[..]).unwrap().collect();
    assert_eq!(items.len(), 3);
    assert_eq!(
        items[0].as_ref().unwrap().record,
        Record::Frame(frames[0].1)
    );
    let e = second_is_bad_at_49(&items);
    assert_eq!(
        e.to_string(),
        "pcap record 2 (byte 49): bad SocketCAN packet: identifier 0x981 above 0x7FF without the extended flag"
    );
    // The record was framed by its length: the next one reads.
    assert_eq!(
        items[2].as_ref().unwrap().record,
        Record::Frame(frames[2].1)
    );
    // The same word with the extended flag is a 29-bit identifier.
    let ext = with_word(file(&frames[..1]), 40, 0x8000_0981);
    let p = PcapReader::new(&ext[..]).unwrap().next().unwrap().unwrap();
    assert_eq!(
        p.record,
        Record::Frame(Frame::from_array(Id::Extended(0x981), [1]))
    );
    // A remote frame keeps its RTR flag apart from the identifier bits.
    let rtr = with_word(file(&frames[..1]), 40, 0x4000_0801);
    assert!(matches!(
        PcapReader::new(&rtr[..]).unwrap().next(),
        Some(Err(PcapError::BadPacket { record: 1, .. }))
    ));
}

#[test]
fn bad_lengths_and_timestamps_are_errors_with_the_record() {
    let one = file(&[(5, Frame::from_array(Id::Standard(0x181), [1]))]);
    // Remote frame with DLC 9.
    let mut rtr = with_word(one.clone(), 40, 0x4000_0181);
    rtr[44] = 9;
    let e = PcapReader::new(&rtr[..])
        .unwrap()
        .next()
        .unwrap()
        .unwrap_err();
    assert_eq!(
        e.to_string(),
        "pcap record 1 (byte 24): bad SocketCAN packet: remote frame DLC 9 above 8"
    );
    // Length field beyond the packet.
    let mut long = one.clone();
    long[44] = 2;
    let e = PcapReader::new(&long[..])
        .unwrap()
        .next()
        .unwrap()
        .unwrap_err();
    assert!(e.to_string().contains("length field 2 beyond"), "{e}");
    // Microseconds not below one second.
    let mut ts = one.clone();
    ts[28..32].copy_from_slice(&1_000_000u32.to_le_bytes());
    let e = PcapReader::new(&ts[..])
        .unwrap()
        .next()
        .unwrap()
        .unwrap_err();
    assert!(
        matches!(
            e,
            PcapError::BadTimestamp {
                record: 1,
                offset: 24,
                fraction: 1_000_000
            }
        ),
        "{e:?}"
    );
    // A lone packet shorter than its header.
    assert_eq!(
        decode_packet(&[0; 5]).unwrap_err().to_string(),
        "bad SocketCAN packet: 5 bytes, shorter than the 8-byte SocketCAN header"
    );
}

/// An FD frame of 12 bytes (0x11…), BRS set.
fn fd12() -> FdFrame {
    FdFrame::new(Id::Standard(0x185), &[0x11; 12])
        .unwrap()
        .with_brs(true)
}

#[test]
fn fd_record_layout_is_a_whole_canfd_frame_with_fdf() {
    let mut w = PcapWriter::new(Vec::new()).unwrap();
    w.write_fd(1_000_002, &fd12()).unwrap();
    let b = w.into_inner();
    assert_eq!(b.len(), 24 + 16 + 72);
    assert_eq!(u32::from_le_bytes(b[32..36].try_into().unwrap()), 72);
    // Word 0x185, length 12, flags BRS | FDF, two reserved bytes, the data, zeros after it.
    assert_eq!(&b[40..48], &[0, 0, 0x01, 0x85, 12, 0x05, 0, 0]);
    assert_eq!(&b[48..60], &[0x11; 12]);
    assert!(b[60..].iter().all(|&x| x == 0));
    let p = PcapReader::new(&b[..]).unwrap().next().unwrap().unwrap();
    assert_eq!(
        (p.timestamp_us, p.record),
        (1_000_002, Record::Fd(Box::new(fd12())))
    );
}

#[test]
fn fd_is_told_from_classic_by_fdf_flags_length_or_size() {
    let classic = encode_frame(&Frame::from_array(Id::Standard(0x185), [1, 2]));
    let classic = &classic.0[..classic.1];
    assert!(matches!(decode_packet(classic), Ok(Record::Frame(_))));
    // The same 10 bytes with FDF, or with only BRS (an FD flag), are an FD frame of 2 bytes.
    for flags in [0x04, 0x01, 0x02] {
        let mut p = classic.to_vec();
        p[5] = flags;
        let f = decode_packet(&p).unwrap();
        let f = f.fd_frame().unwrap();
        assert_eq!((f.data(), f.flags()), (&[1, 2][..], flags & 0x03));
    }
    // A whole 72-byte canfd_frame without FDF (kernels before 6.x) is FD.
    let mut old = encode_fd_frame(&fd12());
    old[5] = 0;
    assert_eq!(
        decode_packet(&old).unwrap(),
        Record::Fd(Box::new(fd12().with_brs(false)))
    );
    // Above 8 bytes it can only be FD.
    let mut long = old;
    long[4] = 64;
    assert_eq!(
        decode_packet(&long[..72])
            .unwrap()
            .fd_frame()
            .map(|f| f.len()),
        Some(64)
    );
}

#[test]
fn malformed_fd_records_are_errors_naming_record_and_offset() {
    let mut w = PcapWriter::new(Vec::new()).unwrap();
    w.write(1, &Frame::from_array(Id::Standard(0x181), [1]))
        .unwrap();
    w.write_fd(2, &fd12()).unwrap();
    w.write_fd(3, &fd12()).unwrap();
    let good = w.into_inner();
    // The FD records start at 24 + 25 = 49 and 49 + 88 = 137; their word 16 bytes later.
    let cases: [(usize, u8, &str); 4] = [
        (16 + 4, 13, "CAN FD length field 13: a CAN FD frame holds"),
        (16 + 5, 0x0D, "CAN FD flags 0x0D: only BRS"),
        (16, 0x40, "remote frame (RTR flag) in a CAN FD record"),
        (
            16 + 4,
            65,
            "length field 65 beyond the packet's 64 data bytes",
        ),
    ];
    for (at, value, what) in cases {
        let mut b = good.clone();
        b[49 + at] = value;
        let items: Vec<_> = PcapReader::new(&b[..]).unwrap().collect();
        assert_eq!(items.len(), 3);
        let e = second_is_bad_at_49(&items);
        let text = e.to_string();
        assert!(
            text.starts_with("pcap record 2 (byte 49): bad SocketCAN packet: "),
            "{text}"
        );
        assert!(text.contains(what), "{text:?} does not say {what:?}");
        assert_eq!(
            items[2].as_ref().unwrap().record,
            Record::Fd(Box::new(fd12()))
        );
    }
}

/// An input that fails every read: the reader reports it once and stops.
struct Failing;
impl Read for Failing {
    fn read(&mut self, _: &mut [u8]) -> io::Result<usize> {
        Err(io::Error::other("disk gone"))
    }
}

#[test]
fn an_io_error_ends_the_reading() {
    let head = file(&[]);
    let mut r = PcapReader::new(head.as_slice().chain(Failing)).unwrap();
    assert!(matches!(r.next(), Some(Err(PcapError::Io(_)))));
    assert!(r.next().is_none());
}

proptest! {
    #[test]
    fn round_trip(frames in proptest::collection::vec((0u64..4_000_000_000_000_000, crate::frame::arbitrary::any_frame()), 0..20)) {
        let b = file(&frames);
        let back: Vec<_> = PcapReader::new(&b[..]).unwrap().map(|p| p.unwrap()).collect();
        prop_assert_eq!(back.len(), frames.len());
        for (p, (t, f)) in back.iter().zip(&frames) {
            prop_assert_eq!(p.timestamp_us, *t);
            prop_assert_eq!(&p.record, &Record::Frame(*f));
        }
    }

    #[test]
    fn fd_and_classic_round_trip(
        frames in proptest::collection::vec(
            (
                0u64..4_000_000_000_000_000,
                prop_oneof![
                    crate::frame::arbitrary::any_frame().prop_map(Record::Frame),
                    crate::frame::arbitrary::any_fd_frame().prop_map(|f| Record::Fd(Box::new(f))),
                ],
            ),
            0..20,
        )
    ) {
        let mut w = PcapWriter::new(Vec::new()).unwrap();
        for (t, r) in &frames {
            match r {
                Record::Frame(f) => w.write(*t, f).unwrap(),
                Record::Fd(f) => w.write_fd(*t, f).unwrap(),
                Record::Error { .. } => unreachable!(),
            }
        }
        let b = w.into_inner();
        let back: Vec<_> = PcapReader::new(&b[..]).unwrap().map(|p| p.unwrap()).collect();
        prop_assert_eq!(back.len(), frames.len());
        for (p, (t, r)) in back.iter().zip(&frames) {
            prop_assert_eq!(p.timestamp_us, *t);
            prop_assert_eq!(&p.record, r);
        }
    }

    #[test]
    fn arbitrary_bytes_never_panic(mut b in proptest::collection::vec(any::<u8>(), 0..200)) {
        if b.len() >= 24 {
            b[..4].copy_from_slice(&MAGIC_US.to_le_bytes());
            b[20..24].copy_from_slice(&227u32.to_le_bytes());
        }
        if let Ok(r) = PcapReader::new(&b[..]) {
            for _ in r {}
        }
    }
}
