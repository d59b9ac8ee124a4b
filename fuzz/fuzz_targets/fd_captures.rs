//! CAN FD in the capture readers: candump `##` lines and SocketCAN `canfd_frame` records. Any
//! input gives a record or an error, never a panic, and every FD frame read is written back
//! (candump line, 72-byte pcap record) and read again as the same frame.
//!
//! The input's first byte picks the identifier form; the rest is fed as text lines (as they
//! are, and behind an `ID##` prefix that reaches the FD branch at once), as one packet (as it
//! is, and with `CANFD_FDF` set), and as the records of a pcap file.
#![no_main]

use duocan::capture::candump::{self, format_fd_frame, parse_line};
use duocan::capture::pcap::{self, decode_packet, encode_fd_frame, encode_frame, PcapWriter};
use duocan::capture::Record;
use libfuzzer_sys::fuzz_target;

/// A record read back from what it writes as.
fn round_trip(r: &Record) {
    match r {
        Record::Fd(f) => {
            let line = format_fd_frame(1, "can0", f);
            let again = parse_line(&line).map(|e| e.record);
            assert_eq!(again.as_ref(), Ok(r), "{line}");
            assert_eq!(decode_packet(&encode_fd_frame(f)).ok().as_ref(), Some(r));
        }
        Record::Frame(c) => {
            let (b, n) = encode_frame(c);
            assert_eq!(decode_packet(&b[..n]).ok().as_ref(), Some(r));
        }
        Record::Error { .. } => {}
    }
}

fuzz_target!(|data: &[u8]| {
    let Some((&mode, rest)) = data.split_first() else {
        return;
    };
    let id = if mode & 1 == 0 { "123" } else { "1234ABCD" };
    let text = String::from_utf8_lossy(rest);
    for line in text.lines().take(64) {
        if let Ok(e) = parse_line(line) {
            round_trip(&e.record);
        }
        if let Ok(e) = parse_line(&format!("(1.000000) can0 {id}##{line}")) {
            round_trip(&e.record);
        }
    }
    for e in candump::read_log("fuzz", rest).take(1000).flatten() {
        round_trip(&e.record);
    }
    if let Ok(r) = decode_packet(rest) {
        round_trip(&r);
    }
    if rest.len() >= 8 {
        let mut p = rest.to_vec();
        p[5] |= pcap::CANFD_FDF;
        if let Ok(r) = decode_packet(&p) {
            round_trip(&r);
        }
    }
    if let Ok(w) = PcapWriter::new(Vec::new()) {
        let mut file = w.into_inner();
        file.extend_from_slice(rest);
        if let Ok(mut r) = pcap::PcapReader::new(&file[..]) {
            for _ in 0..1000 {
                match r.next_packet() {
                    Ok(Some(p)) => round_trip(&p.record),
                    Ok(None) => break,
                    // A bad record is skipped; a truncated file ends.
                    Err(
                        pcap::PcapError::BadPacket { .. } | pcap::PcapError::BadTimestamp { .. },
                    ) => {}
                    Err(_) => break,
                }
            }
        }
    }
});
