use super::*;
use crate::od::{DefaultValue, ObjectDictionary};
use proptest::prelude::*;

fn n(x: u8) -> NodeId {
    NodeId::must(x)
}

const A: DeviceAddress = DeviceAddress::board_at(1, 2, 3, 4);
const B: DeviceAddress = DeviceAddress::board_at(1, 2, 3, 5);

fn profile() -> RailwayProfile {
    RailwayProfile::with(&[
        (n(10), A),
        (n(11), B),
        (n(1), DeviceAddress::board_at(0, 0, 0, 1)),
    ])
    .unwrap()
}

#[test]
fn services_of_a_node_sit_at_its_board_address() {
    let p = profile();
    assert_eq!(p.nmt(), Id::Extended(0));
    assert_eq!(p.heartbeat(n(10)), Id::Extended(0x0081_2340));
    assert_eq!(p.guarding(n(10)), Id::Extended(0x0401_2340));
    assert_eq!(p.emcy(n(11)), Id::Extended(0x0041_2350));
    assert_eq!(
        p.id(RailFunction::StateChange, n(10), 7),
        Some(Id::Extended(0x0201_2347))
    );
    assert_eq!(p.id(RailFunction::StateChange, n(12), 7), None);
    assert_eq!(RailwayProfile::SYNC, Id::Extended(0x0020_0000));
}

#[test]
fn classify_recognises_the_fixed_services_only() {
    let p = profile();
    let c = |raw, remote| p.classify(Id::Extended(raw), remote);
    assert_eq!(c(0x0000_0000, false), Some(ProfileFrame::Nmt));
    assert_eq!(c(0x0000_0000, true), None);
    assert_eq!(c(0x0000_0001, false), None, "NMT lives at address 0 only");
    assert_eq!(c(0x0081_2340, false), Some(ProfileFrame::Heartbeat(n(10))));
    assert_eq!(
        c(0x0081_2340, true),
        None,
        "guarding has its own identifier"
    );
    assert_eq!(c(0x0401_2350, true), Some(ProfileFrame::Guarding(n(11))));
    assert_eq!(c(0x0401_2350, false), Some(ProfileFrame::Guarding(n(11))));
    assert_eq!(c(0x0041_2340, false), Some(ProfileFrame::Emcy(n(10))));
    // Port ≠ 0, addresses nobody has, codes that are not services: none of the profile's.
    assert_eq!(c(0x0081_2341, false), None);
    assert_eq!(c(0x0081_2360, false), None);
    assert_eq!(c(0x0201_2340, false), None);
    assert_eq!(c(0x1FF0_000A, false), None);
    assert_eq!(p.classify(Id::Standard(0x70A), false), None);
}

#[test]
fn a_node_missing_from_the_table_is_visible_and_decoded_by_nobody() {
    let p = profile();
    let id = p.heartbeat(n(99));
    assert_eq!(id, Id::Extended(0x1FF0_0063));
    assert_eq!(p.classify(id, false), None);
    assert_eq!(
        p.decode(id),
        Some(Decoded {
            function: RailFunction::Unmapped,
            address: DeviceAddress::from_raw(99).unwrap(),
            node: None
        })
    );
}

#[test]
fn table_rules() {
    let mut p = profile();
    assert_eq!(p.len(), 3);
    assert_eq!(
        p.add(n(12), A),
        Err(TableError::AddressTaken {
            address: A,
            by: n(10)
        })
    );
    let port3 = A.with_port(3);
    assert_eq!(
        p.add(n(12), port3),
        Err(TableError::NotABoard {
            node: n(12),
            address: port3
        })
    );
    assert!(p
        .add(n(12), port3)
        .unwrap_err()
        .to_string()
        .contains("port 3"));
    // Re-adding is a no-op; moving a node frees its old address.
    p.add(n(10), A).unwrap();
    let c = DeviceAddress::board_at(2, 0, 0, 1);
    p.add(n(10), c).unwrap();
    assert_eq!(
        (p.address(n(10)), p.node_at(A), p.node_at(c)),
        (Some(c), None, Some(n(10)))
    );
    assert_eq!(
        p.node_at(c.with_port(9)),
        Some(n(10)),
        "node_at ignores the port"
    );
    assert_eq!(p.remove(n(10)), Some(c));
    assert_eq!(p.remove(n(10)), None);
    assert_eq!(p.node_at(c), None);
    let all: Vec<_> = p.iter().collect();
    assert_eq!(
        all,
        [(n(1), DeviceAddress::board_at(0, 0, 0, 1)), (n(11), B)]
    );
}

#[test]
fn every_node_id_fits() {
    let mut p = RailwayProfile::new();
    for id in 1..=127u8 {
        let a = DeviceAddress::new(id >> 4, id & 0xF, 1, 1, 0).unwrap();
        p.add(n(id), a).unwrap();
    }
    assert_eq!(p.len(), 127);
    for id in 1..=127u8 {
        let a = p.address(n(id)).unwrap();
        assert_eq!(p.node_at(a), Some(n(id)));
        assert_eq!(
            p.classify(p.heartbeat(n(id)), false),
            Some(ProfileFrame::Heartbeat(n(id)))
        );
    }
}

#[test]
fn sdo_channel_and_dictionary_defaults_are_29_bit() {
    let p = profile();
    let (rx, tx) = p.sdo_cob_ids(n(10)).unwrap();
    assert_eq!((rx, tx), (0x2820_0000 | 0x1_2340, 0x2800_0000 | 0x1_2340));
    let ch = p.sdo_channel(n(10)).unwrap();
    assert_eq!(ch.request, Id::Extended(0x0821_2340));
    assert_eq!(ch.response, Id::Extended(0x0801_2340));
    assert_eq!(p.sdo_channel(n(12)), None);

    let mut od = crate::od::comm::standard_dictionary(10, Default::default());
    for def in RailwayProfile::comm_objects(A.with_port(5)) {
        od.upsert(def);
    }
    assert_eq!(od.get_u32(comm::SDO_SERVER, 1), Some(rx));
    assert_eq!(od.get_u32(comm::SDO_SERVER, 2), Some(tx));
    assert_eq!(od.get_u32(comm::EMCY_COB_ID, 0), Some(0x2041_2340));
    assert_eq!(od.get_u32(comm::SYNC_COB_ID, 0), Some(0x2020_0000));
    // Resets restore these defaults, not the predefined ones.
    od.store(comm::EMCY_COB_ID, 0, &0x85u32.to_le_bytes())
        .unwrap();
    od.reset_range(0x1000..=0x1FFF);
    assert_eq!(od.get_u32(comm::EMCY_COB_ID, 0), Some(0x2041_2340));
    let defs = RailwayProfile::comm_objects(A);
    assert!(defs
        .iter()
        .all(|d| !matches!(d.default_value(), DefaultValue::NodeIdPlus(_))));
}

proptest! {
    /// Whatever the identifier, classify and decode agree with the table and never panic.
    #[test]
    fn classify_agrees_with_the_table(
        code in prop_oneof![0u16..=FUNCTION_MAX, proptest::sample::select(RailFunction::ALL.map(RailFunction::code).to_vec())],
        address in prop_oneof![0u32..=ADDRESS_MAX, proptest::sample::select(vec![0, 0x1_2340, 0x1_2350, 0x1_2341, 0x10])],
        remote in any::<bool>(),
    ) {
        let p = profile();
        let id = compose(code, DeviceAddress::from_raw(address).unwrap());
        match p.classify(id, remote) {
            Some(ProfileFrame::Heartbeat(x)) => prop_assert_eq!(p.heartbeat(x), id),
            Some(ProfileFrame::Guarding(x)) => prop_assert_eq!(p.guarding(x), id),
            Some(ProfileFrame::Emcy(x)) => prop_assert_eq!(p.emcy(x), id),
            Some(ProfileFrame::Nmt) => prop_assert_eq!(p.nmt(), id),
            None => {}
        }
        if let Some(d) = p.decode(id) {
            prop_assert_eq!(id, super::id(d.function, d.address));
        }
    }
}
