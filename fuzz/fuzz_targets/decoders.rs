//! Every byte-level decoder: candump log lines, pcap files and packets, python-can UDP
//! datagrams, SDO request/response/segment codecs, NMT and error-control frames, railway payloads,
//! a value of any data type as the front door decodes an SDO upload.
//! Each must answer any input with a value or an error, never a panic.
#![no_main]

use duocan::capture::{candump, pcap};
use duocan::port::udp;
use duocan::profile::railway::Payload;
use duocan::sdo::codec::{BlockSegment, Request, Response};
use duocan::net::AnyValue;
use duocan::od::DataType;
use duocan::{nmt, Frame, Id};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    for line in text.lines() {
        let _ = candump::parse_line(line);
    }
    for entry in candump::read_log("fuzz", data).take(1000) {
        let _ = entry;
    }
    let _ = pcap::decode_packet(data);
    if let Ok(mut r) = pcap::PcapReader::new(data) {
        for _ in 0..1000 {
            match r.next_packet() {
                Ok(Some(_)) => {}
                _ => break,
            }
        }
    }
    let _ = udp::decode(data);
    // The CAN FD decoder too: what it takes must encode back to a datagram it takes again.
    if let Ok((frame, ts)) = udp::decode_any(data) {
        let again = match frame {
            udp::UdpFrame::Frame(f) => udp::encode(&f, ts, None),
            udp::UdpFrame::Fd(f) => udp::encode_fd(&f, ts, None),
        };
        let back = udp::decode_any(&again).map(|(f, _)| f);
        assert_eq!(back, Ok(frame), "re-encoded datagram decodes to the same frame");
    }
    if data.len() >= 8 {
        let d: [u8; 8] = data[..8].try_into().unwrap_or([0; 8]);
        let _ = Request::decode(&d);
        let _ = Response::decode(&d);
        let _ = BlockSegment::decode(&d);
    }
    if let Some((&head, rest)) = data.split_first() {
        let len = rest.len().min(8);
        let id = if head & 1 == 0 {
            Id::Standard(u16::from(head) << 3 | 0x5)
        } else {
            Id::Extended(u32::from(head) << 20 | 0x1234)
        };
        let _ = Payload::decode_bytes(id, &rest[..len]);
        if let Some(t) = DataType::from_code(u16::from(head & 0x1F)) {
            if let Some(v) = AnyValue::decode(t, rest) {
                let _ = v.to_string();
            }
        }
        if let Ok(f) = Frame::new(id, &rest[..len]) {
            let _ = nmt::parse_command(&f);
            let _ = nmt::parse_error_control(&f);
            let _ = Payload::decode(&f);
        }
    }
});
