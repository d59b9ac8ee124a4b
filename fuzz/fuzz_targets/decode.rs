//! The frame decoder (`duocan::capture::decode`), as `duocan dump` runs it: a candump log read
//! from the input, or frames built from it (11- and 29-bit, data and remote, railway functions
//! at a table's boards, a PDO layout of any entries and types), decoded in order by one decoder
//! that keeps the SDO transfers per node. Every frame must give one non-empty line without a
//! line break, name the node its identifier names, and decode the same way a second time from a
//! fresh decoder (the context is the frames', nothing else).
#![no_main]

use duocan::capture::candump;
use duocan::capture::decode::{DecodedFrame, Decoder, Kind, PdoFieldDef, PdoLayout};
use duocan::od::DataType;
use duocan::pdo::{Dir, MapEntry};
use duocan::profile::railway::{compose, DeviceAddress, RailFunction, RailwayProfile};
use duocan::{Frame, Id, NodeId};
use libfuzzer_sys::fuzz_target;

/// At most this many frames per input: the decoder's cost per frame is what is fuzzed.
const MAX_FRAMES: usize = 4096;

fn check(frame: &Frame, d: &DecodedFrame) {
    let text = d.to_string();
    assert!(!text.is_empty() && !text.contains('\n'), "{text:?}");
    if let (Id::Standard(raw), Some(n)) = (frame.id(), d.node()) {
        match d.kind() {
            Kind::Sdo | Kind::Emcy | Kind::Heartbeat => {
                assert_eq!(u16::from(n.raw()), raw & 0x7F, "{text}")
            }
            _ => {}
        }
    }
    if d.kind() == Kind::Sdo {
        assert!(matches!(
            frame.id(),
            Id::Standard(0x581..=0x5FF | 0x601..=0x67F)
        ));
    }
}

/// A decoder with a railway table and a PDO layout from the input's head; the boards of the
/// table; the rest of the input.
fn decoder(data: &[u8]) -> (Decoder, Vec<DeviceAddress>, &[u8]) {
    let mut rest = data;
    let mut take = |n: usize| -> Option<&[u8]> {
        let (a, b) = rest.split_at_checked(n)?;
        rest = b;
        Some(a)
    };
    let mut profile = RailwayProfile::new();
    let n = take(1).map_or(0, |b| b[0] % 5);
    for _ in 0..n {
        let Some(e) = take(4) else { break };
        let raw = u32::from_le_bytes([e[1], e[2], e[3] & 0x0F, 0]) & !0xF;
        if let (Some(node), Ok(a)) = (NodeId::new(e[0] & 0x7F), DeviceAddress::from_raw(raw)) {
            let _ = profile.add(node, a);
        }
    }
    let boards: Vec<DeviceAddress> = profile.iter().map(|(_, a)| a).collect();
    let mut dec = Decoder::new().with_railway(profile);
    let m = take(1).map_or(0, |b| b[0] % 9);
    let id = take(2).map_or(0, |b| u16::from_le_bytes([b[0], b[1]]) & 0x7FF);
    let mut fields = Vec::new();
    for _ in 0..m {
        let Some(e) = take(5) else { break };
        let def = PdoFieldDef::new(MapEntry::new(u16::from_le_bytes([e[0], e[1]]), e[2], e[3]));
        fields.push(match DataType::from_code(u16::from(e[4] & 0x1F)) {
            Some(t) => def.with_name("v", t),
            None => def,
        });
    }
    if !fields.is_empty() {
        let layout = PdoLayout {
            node: NodeId::new((id & 0x7F) as u8),
            dir: Dir::Transmit,
            number: 1,
            fields,
        };
        dec.add_pdo(Id::Standard(id), layout);
    }
    (dec, boards, rest)
}

/// A frame from 14 bytes: flags, identifier, DLC, data.
fn frame(c: &[u8], railway: &[DeviceAddress]) -> Option<Frame> {
    let [flags, i0, i1, i2, i3, dlc, d @ ..] = c else {
        return None;
    };
    let raw = u32::from_le_bytes([*i0, *i1, *i2, *i3]);
    let id = match flags % 4 {
        0 => Id::Standard((raw & 0x7FF) as u16),
        // The identifiers of node (raw & 0x7F) by function code: SDO, heartbeat, EMCY, PDO.
        1 => Id::Standard(((raw >> 8 & 0xF) as u16) << 7 | (raw & 0x7F) as u16),
        2 if !railway.is_empty() => {
            let f = RailFunction::ALL[*i1 as usize % RailFunction::ALL.len()];
            let a = railway[*i2 as usize % railway.len()].with_port(*i3 & 0x0F);
            compose(f.code(), a)
        }
        _ => Id::Extended(raw & 0x1FFF_FFFF),
    };
    if flags & 0x80 != 0 {
        Frame::remote(id, dlc % 9).ok()
    } else {
        Frame::new(id, &d[..usize::from(dlc % 9).min(d.len())]).ok()
    }
}

fuzz_target!(|data: &[u8]| {
    let Some((&mode, rest)) = data.split_first() else {
        return;
    };
    let log = mode & 1 == 1;
    let (mut first, boards, tail) = decoder(if log { &[] } else { rest });
    let frames: Vec<Frame> = if log {
        // A log as `duocan dump` reads it: lines until the first error.
        candump::read_log("fuzz", rest)
            .take(MAX_FRAMES)
            .map_while(Result::ok)
            .filter_map(|e| e.record.frame().copied())
            .collect()
    } else {
        tail.chunks_exact(14)
            .take(MAX_FRAMES)
            .filter_map(|c| frame(c, &boards))
            .collect()
    };
    let lines: Vec<DecodedFrame> = frames.iter().map(|f| first.decode(f)).collect();
    for (f, d) in frames.iter().zip(&lines) {
        check(f, d);
    }
    let (mut second, _, _) = decoder(if log { &[] } else { rest });
    // Compared as Debug text: a REAL mapped value may be NaN, which equals nothing.
    let text = |d: &DecodedFrame| format!("{d:?}");
    for (f, d) in frames.iter().zip(&lines) {
        assert_eq!(
            text(&second.decode(f)),
            text(d),
            "the same frames decode the same way"
        );
    }
    // Forgetting the transfers is a fresh start: the first frame decodes as it did first.
    first.forget_transfers();
    if let (Some(f), Some(d)) = (frames.first(), lines.first()) {
        assert_eq!(text(&first.decode(f)), text(d));
    }
});
