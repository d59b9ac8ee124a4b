//! The demo's device descriptions (`examples/demo/devices/`): the boards' EDS gives each board
//! the dictionary the demo's boards always had, and each rack's DCF configures exactly the
//! heartbeat the pair supervision uses and the EMCY inhibit time.

use crate::scenario::devices::{read, Devices, BOARD_EDS, RACK_DCFS};
use crate::scenario::BOARD_HB;
use duocan::eds::{difference, EdsErrorKind, FileKind};
use duocan::master::{ConfigStep, SlaveConfig};
use duocan::od::{comm, Access, DefaultValue, ObjectDef, ObjectDictionary, ObjectType};
use duocan::NodeId;

#[test]
fn the_boards_eds_gives_the_standard_board_dictionary() {
    let d = Devices::load().unwrap();
    assert_eq!(d.board.kind, FileKind::Eds);
    // The boards have an LSS slave (a spare arrives without node-ID), and each rack's DCF
    // names the identity its slots expect (the boards').
    assert!(d.board.device_info.lss_supported);
    for dcf in &d.racks {
        assert!(dcf.device_info.lss_supported);
        let i = &dcf.device_info;
        assert_eq!(
            (i.vendor_number, i.product_number, i.revision_number),
            (Some(0xD0CA), Some(0x10), Some(1))
        );
    }
    let node = 0x12;
    let identity = comm::Identity {
        device_type: 0x0001_0191,
        vendor: 0x0000_D0CA,
        product: 0x10,
        revision: 1,
        serial: 0,
    };
    let mut expected = comm::standard_dictionary(node, identity);
    expected.upsert(
        ObjectDef::u32(comm::IDENTITY, 4, Access::Const, 0)
            .default(DefaultValue::NodeIdPlus(0x1000))
            .object_type(ObjectType::Record)
            .named("Serial number"),
    );
    expected.reset_range(0..=0xFFFF);
    let od = d.board.dictionary(node);
    assert_eq!(difference(&od, &expected), None);
    assert_eq!(od.get_value::<u32>(comm::IDENTITY, 4), Ok(0x1012));
}

#[test]
fn each_rack_dcf_configures_the_heartbeat_and_the_emcy_inhibit_time() {
    let d = Devices::load().unwrap();
    for (dcf, (name, _)) in d.racks.iter().zip(RACK_DCFS) {
        assert_eq!(dcf.kind, FileKind::Dcf, "{name}");
        for node in [0x11, 0x2c] {
            let cfg = SlaveConfig::from_dcf(NodeId::must(node), dcf);
            assert_eq!(
                cfg.heartbeat_producer_ms,
                Some(BOARD_HB.as_millis() as u16),
                "{name}"
            );
            assert_eq!(
                cfg.steps,
                [ConfigStep::Write {
                    index: comm::EMCY_INHIBIT,
                    sub: 0,
                    data: 100u16.to_le_bytes().to_vec()
                }],
                "{name}"
            );
        }
    }
}

#[test]
fn a_broken_description_is_an_error_naming_file_line_section_and_key() {
    let (name, text) = BOARD_EDS;
    let broken = text.replacen("AccessType=rw", "AccessType=readwrite", 1);
    let e = read((name, &broken)).err().unwrap();
    assert!(matches!(e.kind, EdsErrorKind::UnknownAccessType { .. }));
    assert_eq!(e.at.file, "io_board.eds");
    assert_eq!(e.at.key.as_deref(), Some("AccessType"));
    assert!(e.at.line > 0);
}
