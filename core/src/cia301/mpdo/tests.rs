// List entries are written in their fields' groups (block_index_sub, …), not in bytes.
#![allow(clippy::unusual_byte_groupings)]

use super::*;
use crate::od::abort::AbortCode;
use crate::od::{Access, DataType, ObjectDef, ObjectDictionary};
use proptest::prelude::*;

#[test]
fn classic_layout_is_byte_exact() {
    let m = Mpdo::sam(0x7F, 0x6401, 0x12, &[1, 2, 3, 4]).unwrap();
    assert_eq!(m.to_bytes(), [0x7F, 0x01, 0x64, 0x12, 1, 2, 3, 4]);
    let d = Mpdo::dam(0, 0x2000, 0, &[0xAA]).unwrap();
    assert_eq!(d.to_bytes(), [0x80, 0x00, 0x20, 0x00, 0xAA, 0, 0, 0]);
    assert_eq!(d.frame(crate::Id::Standard(0x181)).data(), &d.to_bytes());
}

#[test]
fn constructors_refuse_what_the_form_cannot_carry() {
    assert_eq!(Mpdo::dam(128, 0x2000, 0, &[]), None);
    assert_eq!(Mpdo::dam(5, 0x2000, 0, &[0; 5]), None);
    assert_eq!(Mpdo::sam(0, 0x2000, 0, &[1]), None);
}

#[test]
fn decoding_checks_length_and_producer() {
    for n in [0, 1, 4, 7, 9] {
        assert_eq!(
            Mpdo::decode(&[0x85; 9][..n]),
            Err(MpdoDecodeError::Length { got: n })
        );
    }
    assert_eq!(
        Mpdo::decode(&[0x00, 0, 0x20, 0, 0, 0, 0, 0]),
        Err(MpdoDecodeError::NoProducer)
    );
    // DAM to node 0 is a broadcast, not an error.
    let b = Mpdo::decode(&[0x80, 0x34, 0x12, 9, 1, 0, 0, 0]).unwrap();
    assert_eq!(
        (b.mode, b.node, b.index, b.sub),
        (Mode::Destination, 0, 0x1234, 9)
    );
}

#[test]
fn mapping_counts_name_the_modes() {
    assert_eq!(Mode::from_mapping_count(0xFE), Some(Mode::Source));
    assert_eq!(Mode::from_mapping_count(0xFF), Some(Mode::Destination));
    for c in [0, 1, 64, 0xFD, 0x1FF] {
        assert_eq!(Mode::from_mapping_count(c), None);
    }
    assert_eq!(Mode::Source.mapping_count(), SAM_COUNT);
    assert_eq!(Mode::Destination.mapping_count(), DAM_COUNT);
}

#[test]
fn list_entries_decode_their_fields() {
    let s = ScannerEntry::from_raw(0x03_6401_02);
    assert_eq!(
        s,
        ScannerEntry {
            index: 0x6401,
            sub: 2,
            block: 3
        }
    );
    assert_eq!(s.raw(), 0x03_6401_02);
    assert!(!s.covers(0x6401, 1) && s.covers(0x6401, 2) && s.covers(0x6401, 4));
    assert!(!s.covers(0x6401, 5) && !s.covers(0x6400, 2));
    assert!(
        !ScannerEntry::from_raw(0x00_6401_02).covers(0x6401, 2),
        "block 0: unused"
    );

    let d = DispatcherEntry::from_raw(0x02_2100_05_6000_01_07);
    assert_eq!(
        (d.producer, d.producer_index, d.producer_sub),
        (7, 0x6000, 1)
    );
    assert_eq!((d.local_index, d.local_sub, d.block), (0x2100, 5, 2));
    assert_eq!(d.raw(), 0x02_2100_05_6000_01_07);
    assert_eq!(d.map(7, 0x6000, 1), Some((0x2100, 5)));
    assert_eq!(d.map(7, 0x6000, 2), Some((0x2100, 6)));
    assert_eq!(d.map(7, 0x6000, 3), None);
    assert_eq!(d.map(7, 0x6000, 0), None);
    assert_eq!(d.map(6, 0x6000, 1), None);
    // A block that runs past sub-index 255 ends there.
    let end = DispatcherEntry::from_raw(0x04_2100_FF_6000_01_07);
    assert_eq!(end.map(7, 0x6000, 1), Some((0x2100, 0xFF)));
    assert_eq!(end.map(7, 0x6000, 2), None);
}

fn od() -> crate::od::DynamicDictionary {
    let mut od = crate::od::DynamicDictionary::new(5);
    od.insert_all(&[
        ObjectDef::u16(0x2000, 1, Access::Rw, 0).mappable(),
        ObjectDef::u16(0x2000, 2, Access::Ro, 0x77).mappable(),
        ObjectDef::u32(0x2001, 0, Access::Rw, 0),
        ObjectDef::new(0x2002, 0, DataType::Integer8)
            .mappable()
            .access(Access::Rw),
        ObjectDef::new(0x2003, 0, DataType::Unsigned64)
            .mappable()
            .access(Access::Rw),
        ObjectDef::bytes(0x2004, 0, DataType::OctetString, 4)
            .mappable()
            .access(Access::Rw),
    ])
    .unwrap();
    od.insert_all(&scanner_list::<3>(0, &[0x01_2000_01, 0x01_2000_02]))
        .unwrap();
    od.insert_all(&dispatcher_list::<3>(
        1,
        &[0x01_2000_01_6000_00_07, 0x01_2002_00_6000_00_07],
    ))
    .unwrap();
    od
}

#[test]
fn writes_follow_the_rules_of_an_rpdo_mapping() {
    let mut od = od();
    assert_eq!(
        access::write(&mut od, 0x2000, 1, &[0x34, 0x12, 0xFF, 0xFF]),
        Ok(())
    );
    assert_eq!(od.get_value::<u16>(0x2000, 1), Ok(0x1234));
    assert_eq!(access::write(&mut od, 0x2002, 0, &[0xFE, 0, 0, 0]), Ok(()));
    assert_eq!(od.get_value::<i8>(0x2002, 0), Ok(-2));
    let refused = [
        (0x2000, 2, AbortCode::NOT_MAPPABLE), // read-only
        (0x2001, 0, AbortCode::NOT_MAPPABLE), // not mappable
        (0x2003, 0, AbortCode::NOT_MAPPABLE), // larger than 4 bytes
        (0x2004, 0, AbortCode::NOT_MAPPABLE), // a string
        (0x0007, 0, AbortCode::NOT_MAPPABLE), // a dummy entry
        (0x2999, 0, AbortCode::NO_OBJECT),
    ];
    for (i, s, code) in refused {
        assert_eq!(
            access::write(&mut od, i, s, &[1, 2, 3, 4]),
            Err(code),
            "{i:#x}/{s}"
        );
    }
    assert_eq!(od.get_value::<u16>(0x2000, 2), Ok(0x77), "untouched");
    assert_eq!(od.get_value::<u32>(0x2001, 0), Ok(0));
}

#[test]
fn the_scanner_list_decides_what_may_be_sent() {
    let od = od();
    let mut out = [0u8; 4];
    assert!(scanned(&od, 0x2000, 2) && !scanned(&od, 0x2002, 0));
    assert_eq!(access::read(&od, 0x2000, 2, &mut out), Ok(2));
    assert_eq!(out[..2], [0x77, 0]);
    assert_eq!(
        access::read(&od, 0x2002, 0, &mut out),
        Err(MpdoError::NotScanned {
            index: 0x2002,
            sub: 0
        })
    );
}

#[test]
fn the_dispatcher_list_maps_in_list_order() {
    let od = od();
    assert_eq!(
        dispatch(&od, 7, 0x6000, 0),
        Some((0x2000, 1)),
        "the first entry wins"
    );
    assert_eq!(dispatch(&od, 8, 0x6000, 0), None);
    assert_eq!(dispatch(&od, 7, 0x6000, 1), None);
}

fn any_mpdo() -> impl Strategy<Value = Mpdo> {
    (
        any::<bool>(),
        0u8..=127,
        any::<u16>(),
        any::<u8>(),
        any::<[u8; 4]>(),
    )
        .prop_filter_map("SAM needs a producer", |(dam, node, index, sub, data)| {
            if dam {
                Mpdo::dam(node, index, sub, &data)
            } else {
                Mpdo::sam(node, index, sub, &data)
            }
        })
}

proptest! {
    #[test]
    fn every_mpdo_round_trips(m in any_mpdo()) {
        prop_assert_eq!(Mpdo::decode(&m.to_bytes()), Ok(m));
    }

    #[test]
    fn decoding_any_bytes_never_panics(b in proptest::collection::vec(any::<u8>(), 0..80)) {
        match Mpdo::decode(&b) {
            Ok(m) => prop_assert_eq!(&m.to_bytes()[..], &b[..]),
            Err(_) => prop_assert!(b.len() != 8 || (b[0] & 0x80 == 0 && b[0] == 0)),
        }
        let _ = DispatcherEntry::from_raw(crate::cia301::pdo::mapping::le_u64(&b)).map(b.len() as u8, 0, 0);
    }

    #[test]
    fn list_entries_round_trip(raw32 in any::<u32>(), raw64 in any::<u64>()) {
        prop_assert_eq!(ScannerEntry::from_raw(raw32).raw(), raw32);
        prop_assert_eq!(DispatcherEntry::from_raw(raw64).raw(), raw64);
    }
}

#[cfg(feature = "fd")]
mod fd {
    use super::*;

    #[test]
    fn fd_form_pads_to_a_can_fd_length() {
        let m = FdMpdo::new(Mode::Destination, 5, 0x2000, 1, &[7; 9]).unwrap();
        assert_eq!(m.data().len(), 12, "4 + 9 bytes → a 16-byte frame");
        let f = m.frame(crate::Id::Standard(0x181));
        assert_eq!(f.data().len(), 16);
        assert_eq!(f.data()[..4], [0x85, 0x00, 0x20, 0x01]);
        assert_eq!(f.data()[13..], [0, 0, 0]);
        assert_eq!(FdMpdo::decode(f.data()), Ok(m));
        assert_eq!(
            FdMpdo::new(Mode::Source, 1, 0, 0, &[])
                .unwrap()
                .data()
                .len(),
            4
        );
        assert_eq!(FdMpdo::new(Mode::Source, 1, 0, 0, &[0; 61]), None);
        assert_eq!(
            FdMpdo::decode(&[0x85; 9]),
            Err(MpdoDecodeError::Length { got: 9 })
        );
        assert_eq!(
            FdMpdo::decode(&[0x85; 7]),
            Err(MpdoDecodeError::Length { got: 7 })
        );
    }

    proptest! {
        #[test]
        fn fd_mpdos_round_trip(dam in any::<bool>(), node in 1u8..=127, index in any::<u16>(),
                               sub in any::<u8>(), data in proptest::collection::vec(any::<u8>(), 0..=60)) {
            let mode = if dam { Mode::Destination } else { Mode::Source };
            let m = FdMpdo::new(mode, node, index, sub, &data).unwrap();
            prop_assert_eq!(&m.data()[..data.len()], &data[..]);
            let f = m.frame(crate::Id::Standard(0x181));
            prop_assert_eq!(FdMpdo::decode(f.data()), Ok(m));
        }

        #[test]
        fn fd_decoding_any_bytes_never_panics(b in proptest::collection::vec(any::<u8>(), 0..80)) {
            if let Ok(m) = FdMpdo::decode(&b) {
                let f = m.frame(crate::Id::Standard(0x181));
                prop_assert_eq!(f.data(), &b[..]);
            }
        }
    }
}
