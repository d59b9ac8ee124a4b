//! Multiplexed PDOs between nodes on a zero-latency wire: the master's destination-address
//! writes, a node's source-address values through the master's dispatcher list, refusals and
//! what is ignored, each counted.
// List entries are written in their fields' groups (block_index_sub, …), not in bytes.
#![allow(clippy::unusual_byte_groupings)]

use crate::common::{node, TestNode, Wire};
use duocan::mpdo::{dispatcher_list, scanner_list, DispatcherEntry, MpdoError, MpdoStats};
use duocan::node::NodeEventKind as K;
use duocan::od::{Access, DefaultValue, ObjectDef, ObjectDictionary};
use duocan::pdo::{params, PdoEvent};
use duocan::{AbortCode, Frame, Id, NmtCommand, NmtState, NmtTarget};

pub(super) const MASTER: usize = 0;
pub(super) const N5: usize = 1;
pub(super) const N6: usize = 2;
/// The master's DAM channel, which every slave receives.
pub(super) const DAM_COB: u16 = 0x300;
/// Node 5's SAM channel, which the master receives.
pub(super) const SAM_COB: u16 = 0x185;

pub(super) fn comm(tx: bool, pdo: u16, cob: u32) -> Vec<ObjectDef> {
    let cob = DefaultValue::Unsigned(cob as u64);
    if tx {
        params::tpdo_comm(pdo, cob, 254, 0, 0).to_vec()
    } else {
        params::rpdo_comm(pdo, cob, 254, 0).to_vec()
    }
}

/// A mapping parameter whose count marks an MPDO (0xFE, 0xFF).
pub(super) fn mpdo_mapping(tx: bool, pdo: u16, count: u8) -> Vec<ObjectDef> {
    let mut m = if tx {
        params::tpdo_mapping::<2>(pdo, &[]).to_vec()
    } else {
        params::rpdo_mapping::<2>(pdo, &[]).to_vec()
    };
    m[0] = ObjectDef::u8(m[0].index, 0, Access::Rw, count);
    m
}

fn app() -> Vec<ObjectDef> {
    vec![
        ObjectDef::u16(0x2000, 0, Access::Rw, 0).mappable(),
        ObjectDef::u32(0x2001, 0, Access::Rw, 0),
        ObjectDef::u16(0x2002, 0, Access::Ro, 9).mappable(),
        ObjectDef::u16(0x6000, 1, Access::Ro, 0).mappable(),
        ObjectDef::u16(0x6000, 2, Access::Ro, 0).mappable(),
        ObjectDef::u16(0x6001, 0, Access::Ro, 0).mappable(),
        ObjectDef::u16(0x2100, 1, Access::Rw, 0).mappable(),
        ObjectDef::u16(0x2100, 2, Access::Rw, 0).mappable(),
    ]
}

fn with(id: u8, master: bool, tables: &[Vec<ObjectDef>]) -> TestNode {
    let mut n = node(id, master);
    n.od_mut().insert_all(&app()).unwrap();
    for t in tables {
        n.od_mut().insert_all(t).unwrap();
    }
    n
}

/// Master (node 1): DAM on TPDO1, SAM consumer on RPDO1 with node 5's 0x6000/1..=2 dispatched
/// to its 0x2100/1..=2. Node 5: DAM consumer on RPDO1, SAM producer on TPDO1 allowed
/// 0x6000/1..=2. Node 6: DAM consumer on RPDO1. All operational.
fn wire() -> Wire {
    let scan = scanner_list::<2>(0, &[0x02_6000_01]);
    let dispatch = dispatcher_list::<2>(
        0,
        &[DispatcherEntry {
            producer: 5,
            producer_index: 0x6000,
            producer_sub: 1,
            local_index: 0x2100,
            local_sub: 1,
            block: 2,
        }
        .raw()],
    );
    let master = with(
        1,
        true,
        &[
            comm(true, 1, DAM_COB.into()),
            mpdo_mapping(true, 1, 0xFF),
            comm(false, 1, SAM_COB.into()),
            mpdo_mapping(false, 1, 0xFE),
            dispatch.to_vec(),
        ],
    );
    let n5 = with(
        5,
        false,
        &[
            comm(false, 1, DAM_COB.into()),
            mpdo_mapping(false, 1, 0xFF),
            comm(true, 1, SAM_COB.into()),
            mpdo_mapping(true, 1, 0xFE),
            scan.to_vec(),
        ],
    );
    let n6 = with(
        6,
        false,
        &[comm(false, 1, DAM_COB.into()), mpdo_mapping(false, 1, 0xFF)],
    );
    let mut w = Wire::new(vec![master, n5, n6]);
    w.boot_all();
    let now = w.now;
    w.nodes[MASTER].set_nmt_state(now, NmtState::Operational);
    w.nodes[MASTER]
        .nmt_command(now, NmtCommand::Start, NmtTarget::All)
        .unwrap();
    w.flush();
    for i in [N5, N6] {
        assert_eq!(w.nodes[i].nmt_state(), NmtState::Operational);
    }
    w
}

fn u16_at(w: &Wire, i: usize, index: u16, sub: u8) -> u16 {
    w.nodes[i].od().get_value::<u16>(index, sub).unwrap()
}

fn mpdo_events(w: &Wire, i: usize) -> Vec<PdoEvent> {
    w.events[i]
        .iter()
        .filter_map(|e| match e.kind {
            K::Pdo(p @ (PdoEvent::MpdoWritten { .. } | PdoEvent::MpdoRefused { .. })) => Some(p),
            _ => None,
        })
        .collect()
}

#[test]
fn a_dam_write_reaches_the_addressed_node_only() {
    let mut w = wire();
    let now = w.now;
    w.nodes[MASTER]
        .mpdo_send_dam(now, 1, 5, 0x2000, 0, &[0x34, 0x12])
        .unwrap();
    w.flush();
    let sent = w.sent(MASTER, DAM_COB);
    assert_eq!(sent.len(), 1);
    assert_eq!(
        sent[0].1.data(),
        &[0x85, 0x00, 0x20, 0x00, 0x34, 0x12, 0, 0]
    );
    assert_eq!(u16_at(&w, N5, 0x2000, 0), 0x1234);
    assert_eq!(u16_at(&w, N6, 0x2000, 0), 0, "addressed to node 5, not 6");
    assert_eq!(
        w.nodes[N5].mpdo_stats(),
        MpdoStats {
            written: 1,
            ..MpdoStats::default()
        }
    );
    assert_eq!(
        w.nodes[N6].mpdo_stats(),
        MpdoStats {
            other_node: 1,
            ..MpdoStats::default()
        }
    );
    assert_eq!(
        mpdo_events(&w, N5),
        [PdoEvent::MpdoWritten {
            pdo: 1,
            index: 0x2000,
            sub: 0
        }]
    );
    assert!(mpdo_events(&w, N6).is_empty());
}

#[test]
fn a_dam_write_to_node_0_reaches_every_node() {
    let mut w = wire();
    let now = w.now;
    w.nodes[MASTER]
        .mpdo_send_dam(now, 1, 0, 0x2000, 0, &[7])
        .unwrap();
    w.flush();
    assert_eq!(u16_at(&w, N5, 0x2000, 0), 7);
    assert_eq!(u16_at(&w, N6, 0x2000, 0), 7);
}

#[test]
fn refused_writes_are_counted_and_reported() {
    let mut w = wire();
    let now = w.now;
    for (index, data) in [
        (0x2001u16, [1u8, 2, 3, 4]),
        (0x2002, [1, 0, 0, 0]),
        (0x2999, [1; 4]),
    ] {
        w.nodes[MASTER]
            .mpdo_send_dam(now, 1, 6, index, 0, &data)
            .unwrap();
    }
    w.flush();
    let st = w.nodes[N6].mpdo_stats();
    assert_eq!((st.written, st.refused), (0, 3));
    assert_eq!(w.nodes[N6].od().get_value::<u32>(0x2001, 0), Ok(0));
    assert_eq!(u16_at(&w, N6, 0x2002, 0), 9);
    assert_eq!(
        mpdo_events(&w, N6),
        [
            PdoEvent::MpdoRefused {
                pdo: 1,
                index: 0x2001,
                sub: 0,
                reason: AbortCode::NOT_MAPPABLE
            },
            PdoEvent::MpdoRefused {
                pdo: 1,
                index: 0x2002,
                sub: 0,
                reason: AbortCode::NOT_MAPPABLE
            },
            PdoEvent::MpdoRefused {
                pdo: 1,
                index: 0x2999,
                sub: 0,
                reason: AbortCode::NO_OBJECT
            },
        ]
    );
}

#[test]
fn a_sam_value_reaches_the_master_through_its_dispatcher_list() {
    let mut w = wire();
    let now = w.now;
    w.nodes[N5].set(now, 0x6000, 2, 0xBEEFu16).unwrap();
    w.nodes[N5].mpdo_send_sam(now, 1, 0x6000, 2).unwrap();
    w.flush();
    let sent = w.sent(N5, SAM_COB);
    assert_eq!(sent.len(), 1);
    assert_eq!(
        sent[0].1.data(),
        &[0x05, 0x00, 0x60, 0x02, 0xEF, 0xBE, 0, 0]
    );
    assert_eq!(u16_at(&w, MASTER, 0x2100, 2), 0xBEEF);
    assert_eq!(u16_at(&w, MASTER, 0x2100, 1), 0);
    assert_eq!(w.nodes[MASTER].mpdo_stats().written, 1);
    assert_eq!(
        mpdo_events(&w, MASTER),
        [PdoEvent::MpdoWritten {
            pdo: 1,
            index: 0x2100,
            sub: 2
        }]
    );
}

#[test]
fn only_scanned_objects_go_out_as_sam() {
    let mut w = wire();
    let now = w.now;
    assert_eq!(
        w.nodes[N5].mpdo_send_sam(now, 1, 0x6001, 0),
        Err(MpdoError::NotScanned {
            index: 0x6001,
            sub: 0
        })
    );
    w.flush();
    assert!(w.sent(N5, SAM_COB).is_empty());
}

#[test]
fn a_sam_no_dispatcher_entry_covers_is_ignored_and_counted() {
    let mut w = wire();
    // Node 9's 0x6000/1, and node 5's 0x6000/3 (past the block of 2).
    w.deliver(Frame::new(Id::Standard(SAM_COB), &[0x09, 0x00, 0x60, 0x01, 1, 0, 0, 0]).unwrap());
    w.deliver(Frame::new(Id::Standard(SAM_COB), &[0x05, 0x00, 0x60, 0x03, 1, 0, 0, 0]).unwrap());
    let st = w.nodes[MASTER].mpdo_stats();
    assert_eq!((st.written, st.not_dispatched), (0, 2));
    assert_eq!(u16_at(&w, MASTER, 0x2100, 1), 0);
    assert!(mpdo_events(&w, MASTER).is_empty());
}

#[test]
fn frames_that_are_no_mpdo_are_counted_not_applied() {
    let mut w = wire();
    w.deliver(Frame::new(Id::Standard(DAM_COB), &[0x85, 0x00, 0x20, 0x00, 1, 0, 0]).unwrap());
    w.deliver(Frame::new(Id::Standard(SAM_COB), &[0x00, 0x00, 0x60, 0x01, 1, 0, 0, 0]).unwrap());
    assert_eq!(w.nodes[N5].mpdo_stats().malformed, 1);
    assert_eq!(w.nodes[MASTER].mpdo_stats().malformed, 1, "SAM from node 0");
    assert_eq!(u16_at(&w, N5, 0x2000, 0), 0);
}

#[test]
fn requests_name_an_mpdo_of_the_right_mode_while_operational() {
    let mut w = wire();
    let now = w.now;
    let m = &mut w.nodes[MASTER];
    assert_eq!(
        m.mpdo_send_dam(now, 9, 5, 0x2000, 0, &[1]),
        Err(MpdoError::NoSuchPdo { pdo: 9 })
    );
    assert_eq!(
        m.mpdo_send_sam(now, 1, 0x2000, 0),
        Err(MpdoError::WrongMode { pdo: 1 })
    );
    assert_eq!(
        m.mpdo_send_dam(now, 1, 5, 0x2000, 0, &[1; 5]),
        Err(MpdoError::BadRequest)
    );
    assert_eq!(
        m.mpdo_send_dam(now, 1, 128, 0x2000, 0, &[1]),
        Err(MpdoError::BadRequest)
    );
    m.set_nmt_state(now, NmtState::PreOperational);
    assert_eq!(
        m.mpdo_send_dam(now, 1, 5, 0x2000, 0, &[1]),
        Err(MpdoError::NotRunning { pdo: 1 })
    );
    w.flush();
    assert!(w.sent(MASTER, DAM_COB).is_empty());
}

#[test]
fn a_pdo_becomes_an_mpdo_by_its_mapping_count() {
    let mut w = wire();
    let now = w.now;
    let n6 = &mut w.nodes[N6];
    n6.od_mut()
        .insert_all(&comm(false, 2, 0x8000_0301))
        .unwrap();
    n6.od_mut()
        .insert_all(&params::rpdo_mapping::<2>(2, &[]))
        .unwrap();
    n6.reload_pdos(now);
    // The count may be 0xFE/0xFF only while the PDO is invalid, as any count; 0x41–0xFD stay
    // refused as before.
    assert_eq!(
        n6.write(now, 0x1601, 0, &[0x41]),
        Err(AbortCode::VALUE_RANGE)
    );
    assert_eq!(n6.write(now, 0x1601, 0, &[0xFF]), Ok(()));
    n6.write(now, 0x1401, 1, &0x301u32.to_le_bytes()).unwrap();
    assert_eq!(n6.write(now, 0x1601, 0, &[0]), Err(AbortCode::VALUE_RANGE));
    w.deliver(Frame::new(Id::Standard(0x301), &[0x86, 0x00, 0x20, 0x00, 5, 0, 0, 0]).unwrap());
    assert_eq!(u16_at(&w, N6, 0x2000, 0), 5);
}

#[test]
fn a_written_value_triggers_event_driven_tpdos_mapping_it() {
    let mut w = wire();
    let now = w.now;
    // Node 6: TPDO2 maps 0x2000 (event-driven on change of state).
    let n6 = &mut w.nodes[N6];
    n6.od_mut().insert_all(&comm(true, 2, 0x286)).unwrap();
    n6.od_mut()
        .insert_all(&params::tpdo_mapping::<2>(2, &[0x2000_0010]))
        .unwrap();
    n6.reload_pdos(now);
    w.flush();
    let before = w.sent(N6, 0x286).len();
    w.nodes[MASTER]
        .mpdo_send_dam(now, 1, 6, 0x2000, 0, &[0x22, 0x11])
        .unwrap();
    w.flush();
    let after = w.sent(N6, 0x286);
    assert_eq!(after.len(), before + 1);
    assert_eq!(after.last().unwrap().1.data(), &[0x22, 0x11]);
}

proptest::proptest! {
    /// Any frames on a consumer's MPDO identifier: each is counted exactly once (written,
    /// refused, for another node, not dispatched or malformed), nothing panics, and objects
    /// the rules protect keep their values.
    #[test]
    fn every_frame_on_an_mpdo_is_counted_once(
        frames in proptest::collection::vec(proptest::collection::vec(proptest::prelude::any::<u8>(), 0..=8), 0..40)
    ) {
        let mut w = wire();
        for b in &frames {
            w.deliver(Frame::new(Id::Standard(DAM_COB), b).unwrap());
        }
        let st = w.nodes[N6].mpdo_stats();
        proptest::prop_assert_eq!(
            st.written + st.refused + st.other_node + st.not_dispatched + st.malformed,
            frames.len() as u32
        );
        proptest::prop_assert_eq!(u16_at(&w, N6, 0x2002, 0), 9);
        proptest::prop_assert_eq!(w.nodes[N6].od().get_value::<u32>(0x2001, 0), Ok(0));
    }
}

#[test]
fn a_synchronous_mpdo_takes_effect_at_the_next_sync() {
    let mut w = wire();
    let now = w.now;
    let n6 = &mut w.nodes[N6];
    let mut rx = params::rpdo_comm(2, DefaultValue::Unsigned(0x301), 1, 0).to_vec();
    rx.extend(mpdo_mapping(false, 2, 0xFF));
    n6.od_mut().insert_all(&rx).unwrap();
    n6.reload_pdos(now);
    w.deliver(Frame::new(Id::Standard(0x301), &[0x86, 0x00, 0x20, 0x00, 3, 0, 0, 0]).unwrap());
    assert_eq!(u16_at(&w, N6, 0x2000, 0), 0, "held until the SYNC");
    w.deliver(Frame::new(Id::Standard(0x080), &[]).unwrap());
    assert_eq!(u16_at(&w, N6, 0x2000, 0), 3);
    assert_eq!(w.nodes[N6].mpdo_stats().written, 1);
}
