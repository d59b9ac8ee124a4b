use super::*;
use crate::cia301::pdo::MapEntry;
use crate::eds::ImportOptions;
use crate::od::DataType;
use crate::profile::railway::{self as rw, DeviceAddress, Payload, RailFunction};
use proptest::prelude::*;

mod pdo;
mod rail;
mod sdo;

pub(super) fn std(id: u16, data: &[u8]) -> Frame {
    Frame::new(Id::Standard(id), data).unwrap()
}

/// The lines one decoder gives for `frames`, in order.
pub(super) fn lines(dec: &mut Decoder, frames: &[Frame]) -> Vec<String> {
    frames.iter().map(|f| dec.decode(f).to_string()).collect()
}

pub(super) fn line(frame: Frame) -> String {
    Decoder::new().decode(&frame).to_string()
}

#[test]
fn nmt_commands_name_their_target() {
    assert_eq!(line(std(0, &[0x01, 5])), "NMT start node 5");
    assert_eq!(line(std(0, &[0x02, 0])), "NMT stop all");
    assert_eq!(line(std(0, &[0x80, 127])), "NMT pre-operational node 127");
    assert_eq!(line(std(0, &[0x81, 5])), "NMT reset node 5");
    assert_eq!(line(std(0, &[0x82, 0])), "NMT reset communication all");
    assert_eq!(
        line(std(0, &[0x03, 5])),
        "NMT: command specifier 0x03 is no NMT command"
    );
    assert_eq!(
        line(std(0, &[0x01, 200])),
        "NMT: node-ID 200 is outside 1-127"
    );
    assert_eq!(
        line(std(0, &[0x01])),
        "NMT: 1 byte, an NMT command has 2 (01)"
    );
    assert_eq!(
        line(Frame::remote(Id::Standard(0), 2).unwrap()),
        "NMT: remote frame, an NMT command carries data"
    );
}

#[test]
fn sync_and_time() {
    assert_eq!(line(std(0x80, &[])), "SYNC");
    assert_eq!(line(std(0x80, &[7])), "SYNC counter 7");
    assert_eq!(
        line(std(0x80, &[7, 8])),
        "SYNC: 2 bytes, a SYNC has 0 or 1 (07 08)"
    );
    assert_eq!(line(std(0x100, &[0; 6])), "TIME 1984-01-01 00:00:00.000");
    // 2026-11-24 is day 15668 after 1984-01-01; 08:13:12.345 is 29,592,345 ms after midnight.
    let ms = 29_592_345u32.to_le_bytes();
    let days = 15668u16.to_le_bytes();
    let f = std(0x100, &[ms[0], ms[1], ms[2], ms[3], days[0], days[1]]);
    assert_eq!(line(f), "TIME 2026-11-24 08:13:12.345");
    // The top four bits of the millisecond word are reserved.
    let f = std(
        0x100,
        &[ms[0], ms[1], ms[2], ms[3] | 0xF0, days[0], days[1]],
    );
    assert_eq!(line(f), "TIME 2026-11-24 08:13:12.345");
    assert_eq!(
        line(std(0x100, &[1, 2])),
        "TIME: 2 bytes, a TIME has 6 (01 02)"
    );
}

#[test]
fn emcy_with_its_cia301_text() {
    let f = std(0x85, &[0x30, 0x81, 0x11, 1, 2, 3, 4, 5]);
    assert_eq!(
        line(f),
        "node 5 EMCY 0x8130 life guard or heartbeat error, register 0x11, data 01 02 03 04 05"
    );
    let f = std(0x8A, &[0x10, 0x23, 0x03, 0, 0, 0, 0, 0]);
    assert_eq!(
        line(f),
        "node 10 EMCY 0x2310 current, device output side, register 0x03, data 00 00 00 00 00"
    );
    assert_eq!(line(std(0x85, &[0; 8])), "node 5 EMCY reset, register 0x00");
    let short = Decoder::new().decode(&std(0x85, &[0x30, 0x81, 0x11]));
    assert_eq!((short.kind(), short.node()), (Kind::Emcy, NodeId::new(5)));
    assert_eq!(
        short.to_string(),
        "node 5 EMCY: 3 bytes, an EMCY has 8 (30 81 11)"
    );
}

#[test]
fn heartbeat_boot_up_and_guarding() {
    assert_eq!(line(std(0x705, &[0x00])), "node 5 boot-up");
    assert_eq!(line(std(0x705, &[0x05])), "node 5 heartbeat operational");
    assert_eq!(
        line(std(0x705, &[0x7F])),
        "node 5 heartbeat pre-operational"
    );
    assert_eq!(line(std(0x705, &[0x04])), "node 5 heartbeat stopped");
    assert_eq!(
        line(std(0x705, &[0x84])),
        "node 5 guarding answer stopped (toggle 1)"
    );
    assert_eq!(
        line(Frame::remote(Id::Standard(0x705), 1).unwrap()),
        "node 5 guarding request"
    );
    assert_eq!(
        line(std(0x705, &[0x12])),
        "node 5 heartbeat: state byte 0x12 is no NMT state"
    );
    assert_eq!(
        line(std(0x705, &[])),
        "node 5 heartbeat: 0 bytes, a heartbeat has 1"
    );
}

#[test]
fn lss_and_flying_master() {
    assert_eq!(
        line(std(0x7E5, &[0x04, 1, 0, 0, 0, 0, 0, 0])),
        "LSS request cs=0x04 (switch state global) 01 00 00 00 00 00 00"
    );
    assert_eq!(
        line(std(0x7E4, &[0x5E, 5, 0, 0, 0, 0, 0, 0])),
        "LSS response cs=0x5e (inquire node-ID) 05 00 00 00 00 00 00"
    );
    assert_eq!(line(std(0x7E4, &[])), "LSS: 0 bytes, an LSS frame has 8");
    assert_eq!(
        line(std(0x71, &[1, 5])),
        "flying master active-master response node 5 (priority 1)"
    );
    assert_eq!(line(std(0x73, &[])), "flying master active-master request");
    assert_eq!(line(std(0x72, &[])), "flying master negotiation request");
    assert_eq!(line(std(0x75, &[])), "flying master master-capable request");
    assert_eq!(
        line(std(0x74, &[2, 6])),
        "flying master master-capable response node 6 (priority 2)"
    );
    assert_eq!(
        line(std(0x76, &[1])),
        "flying master: force negotiation: 1 byte, it has 2 (priority, node-ID) (01)"
    );
    assert_eq!(
        line(std(0x76, &[1, 0])),
        "flying master: force negotiation: node-ID 0 is outside 1-127"
    );
    // Each identifier of the table names its frame.
    for raw in 0x71..=0x76 {
        assert_eq!(FlyingMasterFrame::from_cob_id(raw).unwrap().cob_id(), raw);
    }
}

#[test]
fn unknown_identifiers_print_the_frame() {
    assert_eq!(line(std(0x123, &[1, 2, 3])), "unknown 0x123 [3] 01 02 03");
    assert_eq!(line(std(0x7E6, &[])), "unknown 0x7e6 [0]");
}

#[test]
fn kinds_nodes_and_filters() {
    for k in Kind::ALL {
        assert_eq!(Kind::from_name(k.name()), Some(k));
    }
    assert_eq!(Kind::from_name("Flying-Master"), Some(Kind::FlyingMaster));
    assert_eq!(Kind::from_name("pdo1"), None);
    let n5 = NodeId::must(5);
    let mut dec = Decoder::new();
    let all = dec.decode(&std(0, &[0x01, 0]));
    assert_eq!((all.node(), all.concerns(n5)), (None, true));
    let to6 = dec.decode(&std(0, &[0x01, 6]));
    assert!(!to6.concerns(n5));
    assert!(dec
        .decode(&std(0x605, &[0x40, 0, 0x10, 0, 0, 0, 0, 0]))
        .concerns(n5));
    assert_eq!(dec.decode(&std(0x80, &[])).node(), None);
}

fn any_frame() -> impl Strategy<Value = Frame> {
    let id = prop_oneof![
        (0u16..=0x7FF).prop_map(Id::Standard),
        (0u32..=0x1FFF_FFFF).prop_map(Id::Extended),
        // The railway codes, so the 29-bit rules are reached often.
        (
            prop::sample::select(RailFunction::ALL.to_vec()),
            0u32..=0xF_FFFF
        )
            .prop_map(|(f, a)| Id::Extended((f.code() as u32) << 20 | a)),
        // The SDO, PDO, LSS and flying-master identifiers of a few nodes.
        prop::sample::select(vec![
            0x000, 0x071, 0x076, 0x080, 0x100, 0x185, 0x585, 0x605, 0x705, 0x7E4, 0x7E5
        ])
        .prop_map(Id::Standard),
    ];
    (
        id,
        prop::collection::vec(any::<u8>(), 0..=8),
        any::<bool>(),
        0u8..=8,
    )
        .prop_map(|(id, data, remote, dlc)| {
            if remote {
                Frame::remote(id, dlc).unwrap()
            } else {
                Frame::new(id, &data).unwrap()
            }
        })
}

proptest! {
    #[test]
    fn any_frame_sequence_decodes_without_panic(frames in prop::collection::vec(any_frame(), 1..64)) {
        let desc = Description::parse(pdo::EDS.as_bytes(), "io.eds", &ImportOptions::lenient()).unwrap();
        let profile = rw::RailwayProfile::with(&[(NodeId::must(5), DeviceAddress::board_at(0, 0, 0, 5))]).unwrap();
        let mut dec = Decoder::new().with_railway(profile);
        dec.describe(NodeId::must(5), &desc);
        for f in &frames {
            let d = dec.decode(f);
            let text = d.to_string();
            prop_assert!(!text.is_empty() && !text.contains('\n'));
            // The node a line names is the node its identifier names.
            if let (Some(n), Id::Standard(raw)) = (d.node(), f.id()) {
                if matches!(d.kind(), Kind::Sdo | Kind::Emcy | Kind::Heartbeat) {
                    prop_assert_eq!(n.raw() as u16, raw & 0x7F);
                }
            }
        }
    }
}

#[test]
fn the_sdo_context_is_bounded_by_the_node_count() {
    // 127 records, replaced by each initiate frame: what the module docs promise.
    assert!(core::mem::size_of::<super::sdo::Tracks>() <= 4096);
    let mut dec = Decoder::new();
    for n in 1..=127u16 {
        dec.decode(&std(0x600 + n, &[0x40, 0x08, 0x10, 0, 0, 0, 0, 0]));
    }
    assert_eq!(
        dec.decode(&std(0x5FF, &[0x00, 1, 2, 3, 4, 5, 6, 7]))
            .to_string(),
        "node 127 SDO upload 0x1008:00 segment 1 (7 bytes)"
    );
    dec.forget_transfers();
    assert_eq!(
        dec.decode(&std(0x5FF, &[0x00, 1, 2, 3, 4, 5, 6, 7]))
            .to_string(),
        "node 127 SDO upload (transfer unknown) segment (7 bytes)"
    );
}
