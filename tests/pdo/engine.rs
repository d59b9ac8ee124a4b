//! PDO engine on a zero-latency wire: every transmission type with exact timing, RPDO handling,
//! dynamic mapping with its abort codes.

use crate::common::{node, TestNode, Wire};
use duocan::emcy::code as emcy_code;
use duocan::node::NodeEventKind as K;
use duocan::od::ObjectAccess;
use duocan::od::{comm, Access, DataType, ObjectDef, ObjectDictionary};
use duocan::pdo::{params, Dir, PdoError, PdoEvent};
use duocan::{AbortCode, Frame, Id, Instant, NmtCommand, NmtState, NmtTarget, NodeId};

const MASTER: usize = 0;
const SLAVE: usize = 1;
const S: NodeId = NodeId::must(5);

fn ms(v: u64) -> Instant {
    Instant::from_millis(v)
}

fn app() -> Vec<ObjectDef> {
    vec![
        ObjectDef::u8(0x6000, 0, Access::Rw, 0).mappable(),
        ObjectDef::u16(0x6001, 0, Access::Rw, 0).mappable(),
        ObjectDef::u8(0x6200, 0, Access::Rw, 0).mappable(),
        ObjectDef::new(0x6201, 0, DataType::Integer16)
            .mappable()
            .access(Access::Rw),
        ObjectDef::u32(0x6300, 0, Access::Rw, 0),
    ]
}

/// A node with the application entries and the given PDO tables.
fn with(id: u8, master: bool, tables: &[&[ObjectDef]]) -> TestNode {
    let mut n = node(id, master);
    n.od_mut().insert_all(&app()).unwrap();
    for t in tables {
        n.od_mut().insert_all(t).unwrap();
    }
    n
}

/// Master (node 1, SYNC producer when asked) and slave (node 5) with PDO tables, booted; the
/// slave is started at 0 ms.
fn wire(slave_tables: &[&[ObjectDef]]) -> Wire {
    let mut w = Wire::new(vec![with(1, true, &[]), with(5, false, slave_tables)]);
    w.boot_all();
    start_slave(&mut w);
    w
}

fn start_slave(w: &mut Wire) {
    let now = w.now;
    w.nodes[MASTER]
        .nmt_command(now, NmtCommand::Start, NmtTarget::Node(S))
        .unwrap();
    w.flush();
    assert_eq!(w.nodes[SLAVE].nmt_state(), NmtState::Operational);
}

fn sync_producer(w: &mut Wire, period_us: u32, overflow: u8) {
    let now = w.now;
    for i in [MASTER, SLAVE] {
        w.nodes[i]
            .set(now, comm::SYNC_OVERFLOW, 0, overflow)
            .unwrap();
    }
    let m = &mut w.nodes[MASTER];
    m.set(now, comm::SYNC_COB_ID, 0, 0x4000_0080u32).unwrap();
    m.set(now, comm::SYNC_PERIOD, 0, period_us).unwrap();
}

/// Sets a slave entry at `t` (the wire runs until then first).
fn set_at<T: duocan::od::OdValue>(w: &mut Wire, t: Instant, index: u16, v: T) {
    w.run_until(t);
    w.nodes[SLAVE].set(t, index, 0, v).unwrap();
    w.flush();
}

fn times(frames: &[(Instant, Frame)]) -> Vec<Instant> {
    frames.iter().map(|(t, _)| *t).collect()
}

fn pdo_events(w: &Wire, i: usize) -> Vec<(Instant, PdoEvent)> {
    w.events[i]
        .iter()
        .filter_map(|e| match e.kind {
            K::Pdo(p) => Some((e.at, p)),
            _ => None,
        })
        .collect()
}

fn tpdo1(ttype: u8, inhibit_100us: u16, timer_ms: u16) -> Vec<ObjectDef> {
    let mut v = params::tpdo_comm(
        1,
        params::predefined_tpdo_cob(1),
        ttype,
        inhibit_100us,
        timer_ms,
    )
    .to_vec();
    v.extend(params::tpdo_mapping::<9>(1, &[0x6001_0010]));
    v
}

#[test]
fn event_driven_tpdo_never_violates_the_inhibit_time() {
    // TPDO1: type 255, inhibit 10 ms, maps 0x6001 (16 bits).
    let mut w = wire(&[&tpdo1(255, 100, 0)]);
    set_at(&mut w, ms(1), 0x6001, 1u16);
    set_at(&mut w, ms(2), 0x6001, 2u16);
    set_at(&mut w, ms(3), 0x6001, 3u16);
    set_at(&mut w, ms(25), 0x6001, 4u16);
    set_at(&mut w, ms(27), 0x6001, 5u16);
    w.run_until(ms(100));
    let sent: Vec<_> = w
        .sent(SLAVE, 0x185)
        .iter()
        .map(|(t, f)| (*t, u16::from_le_bytes([f.data()[0], f.data()[1]])))
        .collect();
    // Entering operational sends at 0; writes during the inhibit time go at its end, with the
    // latest value; a write after it goes at once.
    assert_eq!(sent, [(ms(0), 0), (ms(10), 3), (ms(25), 4), (ms(35), 5)]);

    // A write every 700 µs for a second: frames exactly every 10 ms, never closer.
    let start = ms(200);
    let mut t = start;
    let mut v = 100u16;
    while t < ms(1200) {
        set_at(&mut w, t, 0x6001, v);
        v += 1;
        t += duocan::Duration::from_micros(700);
    }
    w.run_until(ms(1300));
    let ts = times(&w.sent(SLAVE, 0x185)[4..]);
    assert_eq!(ts[0], start);
    let gaps: Vec<u64> = ts.windows(2).map(|p| (p[1] - p[0]).as_micros()).collect();
    assert!(gaps.iter().all(|g| *g == 10_000), "gaps {gaps:?}");
    assert_eq!(ts.len(), 101, "200 ms … 1200 ms");
}

#[test]
fn event_timer_period_is_exact_and_restarts_at_each_transmission() {
    let mut w = wire(&[&tpdo1(254, 0, 50)]);
    w.run_until(ms(1000));
    let expected: Vec<_> = (0..=20).map(|k| ms(50 * k)).collect();
    assert_eq!(times(&w.sent(SLAVE, 0x185)), expected);
    set_at(&mut w, ms(1020), 0x6001, 7u16);
    w.run_until(ms(1200));
    assert_eq!(
        times(&w.sent(SLAVE, 0x185)[21..]),
        [ms(1020), ms(1070), ms(1120), ms(1170)]
    );
    // Stopped: nothing more, and no deadline left behind.
    w.nodes[MASTER]
        .nmt_command(ms(1200), NmtCommand::Stop, NmtTarget::Node(S))
        .unwrap();
    w.flush();
    w.run_until(ms(2000));
    assert_eq!(w.sent(SLAVE, 0x185).len(), 25);
}

#[test]
fn every_nth_sync_is_exact_over_1000_syncs() {
    let mut tables = tpdo1(3, 0, 0);
    tables.extend(params::tpdo_comm(
        2,
        params::predefined_tpdo_cob(2),
        1,
        0,
        0,
    ));
    tables.extend(params::tpdo_mapping::<2>(2, &[0x6000_0008]));
    let mut w = wire(&[&tables]);
    sync_producer(&mut w, 1_000, 0);
    w.run_until(ms(1000));
    let syncs = times(&w.sent(MASTER, 0x80));
    assert_eq!(syncs.len(), 1000);
    assert_eq!(syncs[999], ms(1000));
    let every_third = times(&w.sent(SLAVE, 0x185));
    let expected: Vec<_> = syncs.iter().skip(2).step_by(3).copied().collect();
    assert_eq!(every_third.len(), 333);
    assert_eq!(every_third, expected);
    assert_eq!(times(&w.sent(SLAVE, 0x285)), syncs, "type 1: every SYNC");
    // On the wire each TPDO follows its SYNC.
    let log: Vec<_> = w.log.iter().filter(|(t, _, _)| *t == ms(3)).collect();
    assert_eq!(log[0].2.id(), Id::Standard(0x80));
}

#[test]
fn sync_start_value_is_honoured() {
    let mut tables = params::tpdo_comm(1, params::predefined_tpdo_cob(1), 4, 0, 0).to_vec();
    tables.extend(params::tpdo_mapping::<2>(1, &[0x6000_0008]));
    let mut w = Wire::new(vec![with(1, true, &[]), with(5, false, &[&tables])]);
    w.boot_all();
    let s = &mut w.nodes[SLAVE];
    s.set(ms(0), 0x1800, 1, 0x8000_0185u32).unwrap();
    s.set(ms(0), 0x1800, params::sub::SYNC_START, 7u8).unwrap();
    s.set(ms(0), 0x1800, 1, 0x185u32).unwrap();
    start_slave(&mut w);
    sync_producer(&mut w, 1_000, 10);
    w.run_until(ms(1000));
    let syncs = w.sent(MASTER, 0x80);
    let sent = times(&w.sent(SLAVE, 0x185));
    let counters: Vec<u8> = sent
        .iter()
        .map(|t| syncs.iter().find(|(s, _)| s == t).unwrap().1.data()[0])
        .collect();
    // First at the SYNC whose counter is 7 (the 7th), then every 4th SYNC.
    assert_eq!(sent[0], ms(7));
    assert_eq!(counters[0], 7);
    let expected: Vec<_> = (7..=1000).step_by(4).map(ms).collect();
    assert_eq!(sent, expected);
    assert_eq!(sent.len(), 249);
    // The start value only changes while the PDO is invalid.
    assert_eq!(
        w.nodes[SLAVE].set(w.now, 0x1800, params::sub::SYNC_START, 3u8),
        Err(AbortCode::VALUE_RANGE)
    );
}

#[test]
fn synchronous_acyclic_sends_at_the_sync_after_an_event() {
    let mut w = wire(&[&tpdo1(0, 0, 0)]);
    sync_producer(&mut w, 1_000, 0);
    w.run_until(ms(5));
    assert!(w.sent(SLAVE, 0x185).is_empty(), "no event, no PDO");
    w.run_until(Instant::from_micros(5_500));
    w.nodes[SLAVE].set(w.now, 0x6001, 0, 0x1234u16).unwrap();
    w.nodes[SLAVE].tpdo_request(w.now, 1).unwrap();
    w.run_until(ms(10));
    let sent = w.sent(SLAVE, 0x185);
    assert_eq!(times(&sent), [ms(6)]);
    assert_eq!(sent[0].1.data(), &[0x34, 0x12]);
    assert_eq!(
        w.nodes[SLAVE].tpdo_request(w.now, 2),
        Err(PdoError::NotRunning { pdo: 2 })
    );
    assert_eq!(
        w.nodes[SLAVE].tpdo_request(w.now, 9),
        Err(PdoError::NoSuchPdo { pdo: 9 })
    );
}

#[test]
fn rtr_only_types_answer_remote_frames() {
    // TPDO1 type 252 (sampled at SYNC), TPDO2 type 253 (sampled at the RTR), TPDO3 type 255 with
    // RTR forbidden (bit 30).
    let mut tables = tpdo1(252, 0, 0);
    tables.extend(params::tpdo_comm(
        2,
        params::predefined_tpdo_cob(2),
        253,
        0,
        0,
    ));
    tables.extend(params::tpdo_mapping::<2>(2, &[0x6001_0010]));
    tables.extend(params::tpdo_comm(
        3,
        duocan::od::DefaultValue::NodeIdPlus(0x4000_0380),
        255,
        0,
        0,
    ));
    tables.extend(params::tpdo_mapping::<2>(3, &[0x6001_0010]));
    let mut w = wire(&[&tables]);
    let initial = w.sent(SLAVE, 0x385).len();
    w.nodes[SLAVE].set(w.now, 0x6001, 0, 0xAAAAu16).unwrap();
    w.deliver(Frame::new(Id::Standard(0x80), &[]).unwrap());
    w.nodes[SLAVE].set(w.now, 0x6001, 0, 0xBBBBu16).unwrap();
    w.flush();
    assert!(w.sent(SLAVE, 0x185).is_empty() && w.sent(SLAVE, 0x285).is_empty());
    for id in [0x185, 0x285, 0x385] {
        w.deliver(Frame::remote(Id::Standard(id), 2).unwrap());
    }
    let data = |id| -> Vec<Vec<u8>> {
        w.sent(SLAVE, id)
            .iter()
            .map(|(_, f)| f.data().to_vec())
            .collect()
    };
    assert_eq!(data(0x185), [vec![0xAA, 0xAA]], "252: value of the SYNC");
    assert_eq!(data(0x285), [vec![0xBB, 0xBB]], "253: value at the RTR");
    assert_eq!(w.sent(SLAVE, 0x385).len(), initial + 2, "no answer to RTR");
    // An RTR-only type needs RTR allowed.
    let s = &mut w.nodes[SLAVE];
    assert_eq!(
        s.set(ms(0), 0x1800, 1, 0x4000_0185u32),
        Err(AbortCode::VALUE_RANGE)
    );
    s.set(ms(0), 0x1802, 1, 0xC000_0385u32).unwrap();
    s.set(ms(0), 0x1802, 2, 253u8).unwrap();
    assert_eq!(
        s.set(ms(0), 0x1802, 1, 0x4000_0385u32),
        Err(AbortCode::VALUE_RANGE)
    );
    s.set(ms(0), 0x1802, 1, 0x385u32).unwrap();
}

fn rpdos(sync_type: u8, timeout_ms: u16) -> Vec<ObjectDef> {
    // RPDO1 (0x205): 0x6200, synchronous; RPDO2 (0x305): 0x6201, asynchronous, timeout.
    let mut v = params::rpdo_comm(1, params::predefined_rpdo_cob(1), sync_type, 0).to_vec();
    v.extend(params::rpdo_mapping::<9>(1, &[0x6200_0008]));
    v.extend(params::rpdo_comm(
        2,
        params::predefined_rpdo_cob(2),
        255,
        timeout_ms,
    ));
    v.extend(params::rpdo_mapping::<9>(2, &[0x6201_0010]));
    v
}

#[test]
fn synchronous_rpdos_take_effect_at_the_next_sync_asynchronous_at_once() {
    let mut w = wire(&[&rpdos(1, 0)]);
    w.now = ms(3);
    w.deliver(Frame::new(Id::Standard(0x205), &[0x11]).unwrap());
    w.deliver(Frame::new(Id::Standard(0x205), &[0x22]).unwrap());
    w.deliver(Frame::new(Id::Standard(0x305), &[0xFE, 0xFF]).unwrap());
    let od = w.nodes[SLAVE].od();
    assert_eq!(od.get_value::<u8>(0x6200, 0), Ok(0), "waits for SYNC");
    assert_eq!(
        od.get_value::<i16>(0x6201, 0),
        Ok(-2),
        "asynchronous: at once"
    );
    w.now = ms(4);
    w.deliver(Frame::new(Id::Standard(0x80), &[]).unwrap());
    assert_eq!(w.nodes[SLAVE].od().get_value::<u8>(0x6200, 0), Ok(0x22));
    assert_eq!(
        pdo_events(&w, SLAVE),
        [
            (ms(3), PdoEvent::RpdoReceived { pdo: 2 }),
            (ms(4), PdoEvent::RpdoReceived { pdo: 1 })
        ]
    );
    // Not operational: RPDOs are ignored.
    w.nodes[MASTER]
        .nmt_command(ms(4), NmtCommand::EnterPreOperational, NmtTarget::Node(S))
        .unwrap();
    w.flush();
    w.deliver(Frame::new(Id::Standard(0x305), &[1, 0]).unwrap());
    assert_eq!(w.nodes[SLAVE].od().get_value::<i16>(0x6201, 0), Ok(-2));
    assert_eq!(w.nodes[SLAVE].rpdo_status(2).unwrap().received, 1);
}

#[test]
fn short_rpdo_raises_emcy_0x8210_once_long_is_accepted() {
    let mut w = wire(&[&rpdos(255, 0)]);
    w.now = ms(1);
    w.deliver(Frame::new(Id::Standard(0x305), &[0x01]).unwrap());
    w.deliver(Frame::new(Id::Standard(0x305), &[]).unwrap());
    assert_eq!(w.nodes[SLAVE].od().get_value::<i16>(0x6201, 0), Ok(0));
    assert!(w.nodes[SLAVE].rpdo_status(2).unwrap().length_error);
    w.now = ms(2);
    w.deliver(Frame::new(Id::Standard(0x305), &[0x05, 0x00, 0x99]).unwrap());
    assert_eq!(w.nodes[SLAVE].od().get_value::<i16>(0x6201, 0), Ok(5));
    let emcy: Vec<_> = w
        .sent(SLAVE, 0x85)
        .iter()
        .map(|(t, f)| (*t, u16::from_le_bytes([f.data()[0], f.data()[1]])))
        .collect();
    assert_eq!(
        emcy,
        [(ms(1), emcy_code::PDO_LENGTH), (ms(2), 0)],
        "one EMCY per episode, reset by a good frame"
    );
    assert_eq!(
        pdo_events(&w, SLAVE),
        [
            (
                ms(1),
                PdoEvent::RpdoTooShort {
                    pdo: 2,
                    expected: 2,
                    got: 1
                }
            ),
            (ms(2), PdoEvent::RpdoReceived { pdo: 2 })
        ]
    );
}

#[test]
fn rpdo_timeout_fires_exactly_and_clears_on_reception() {
    let mut w = wire(&[&rpdos(255, 100)]);
    w.run_until(ms(500));
    assert!(
        pdo_events(&w, SLAVE).is_empty(),
        "monitoring starts with the first frame"
    );
    w.deliver(Frame::new(Id::Standard(0x305), &[1, 0]).unwrap());
    w.run_until(ms(560));
    w.deliver(Frame::new(Id::Standard(0x305), &[2, 0]).unwrap());
    w.run_until(ms(900));
    w.deliver(Frame::new(Id::Standard(0x305), &[3, 0]).unwrap());
    w.run_until(ms(950));
    let timeouts: Vec<_> = pdo_events(&w, SLAVE)
        .into_iter()
        .filter(|(_, e)| matches!(e, PdoEvent::RpdoTimeout { .. }))
        .collect();
    assert_eq!(
        timeouts,
        [(
            ms(660),
            PdoEvent::RpdoTimeout {
                pdo: 2,
                last: ms(560)
            }
        )]
    );
    let emcy: Vec<_> = w
        .sent(SLAVE, 0x85)
        .iter()
        .map(|(t, f)| (*t, u16::from_le_bytes([f.data()[0], f.data()[1]])))
        .collect();
    assert_eq!(emcy, [(ms(660), emcy_code::RPDO_TIMEOUT), (ms(900), 0)]);
}

#[test]
fn dynamic_mapping_follows_the_cia_order_and_abort_codes() {
    let mut w = wire(&[&tpdo1(254, 0, 0), &rpdos(255, 0)]);
    let now = w.now;
    let s = w.nodes[SLAVE].core_mut();
    let map = 0x1A00;
    // Valid PDO: mapping is locked.
    assert_eq!(s.write(now, map, 0, &[0]), Err(AbortCode::VALUE_RANGE));
    assert_eq!(
        s.write(now, map, 1, &0x6000_0008u32.to_le_bytes()),
        Err(AbortCode::VALUE_RANGE)
    );
    // Its identifier cannot change while valid; restricted and malformed ones never.
    assert_eq!(
        s.write(now, 0x1800, 1, &0x186u32.to_le_bytes()),
        Err(AbortCode::VALUE_RANGE)
    );
    assert_eq!(s.write(now, 0x1800, 2, &[245]), Err(AbortCode::VALUE_RANGE));
    assert_eq!(
        s.write(now, 0x1800, 3, &10u16.to_le_bytes()),
        Err(AbortCode::VALUE_RANGE),
        "inhibit time only while invalid"
    );
    // 1. invalidate
    s.write(now, 0x1800, 1, &0x8000_0185u32.to_le_bytes())
        .unwrap();
    assert_eq!(
        s.write(now, map, 1, &0x6000_0008u32.to_le_bytes()),
        Err(AbortCode::VALUE_RANGE),
        "entries only while sub 0 is 0"
    );
    // 2. count 0
    s.write(now, map, 0, &[0]).unwrap();
    // 3. entries, each checked
    assert_eq!(
        s.write(now, map, 1, &0x7000_0008u32.to_le_bytes()),
        Err(AbortCode::NO_OBJECT)
    );
    assert_eq!(
        s.write(now, map, 1, &0x6300_0020u32.to_le_bytes()),
        Err(AbortCode::NOT_MAPPABLE)
    );
    assert_eq!(
        s.write(now, map, 1, &0x6000_0009u32.to_le_bytes()),
        Err(AbortCode::NOT_MAPPABLE),
        "longer than the object"
    );
    for sub in 1..=8u8 {
        s.write(now, map, sub, &0x6000_0008u32.to_le_bytes())
            .unwrap();
    }
    s.write(now, map, 1, &0x6001_0010u32.to_le_bytes()).unwrap();
    s.write(now, map, 2, &0x6000_0003u32.to_le_bytes()).unwrap();
    // 4. count: checked against 64 bits (16 + 3 + 6 × 8 = 67)
    assert_eq!(s.write(now, map, 0, &[65]), Err(AbortCode::VALUE_RANGE));
    assert_eq!(s.write(now, map, 0, &[8]), Err(AbortCode::PDO_LENGTH));
    s.write(now, map, 3, &0x6000_0005u32.to_le_bytes()).unwrap();
    s.write(now, map, 0, &[3]).unwrap();
    // 5. validate, with restricted identifiers refused
    assert_eq!(
        s.write(now, 0x1800, 1, &0x705u32.to_le_bytes()),
        Err(AbortCode::VALUE_RANGE)
    );
    assert_eq!(
        s.write(now, 0x1800, 1, &0x0800u32.to_le_bytes()),
        Err(AbortCode::VALUE_RANGE),
        "11-bit COB-ID with bit 11 set"
    );
    s.write(now, 0x1800, 1, &0x2001_8005u32.to_le_bytes())
        .unwrap();
    w.flush();
    // Becoming valid while operational sends (type 254) with the new layout:
    // 0x6001 (16) | 0x6000 (3 bits) | 0x6000 (5 bits).
    w.nodes[SLAVE].set(now, 0x6000, 0, 0b1011_0110u8).unwrap();
    w.nodes[SLAVE].set(now, 0x6001, 0, 0xBEEFu16).unwrap();
    w.flush();
    let last = w
        .log
        .iter()
        .rev()
        .find(|(_, i, f)| *i == SLAVE && f.id() == Id::Extended(0x1_8005))
        .unwrap();
    assert_eq!(last.2.data(), &[0xEF, 0xBE, 0b110 | (0b10110 << 3)]);
    assert_eq!(w.nodes[SLAVE].tpdo_status(1).unwrap().mapped_bits, 24);
}

#[test]
fn rpdo_dummy_entries_skip_bits() {
    let mut tables = params::rpdo_comm(1, params::predefined_rpdo_cob(1), 255, 0).to_vec();
    tables.extend(params::rpdo_mapping::<4>(
        1,
        &[0x0005_0008, 0x6200_0008, 0x0001_0001],
    ));
    let mut w = wire(&[&tables]);
    w.deliver(Frame::new(Id::Standard(0x205), &[0xAA, 0x42, 0x01]).unwrap());
    assert_eq!(w.nodes[SLAVE].od().get_value::<u8>(0x6200, 0), Ok(0x42));
    // A TPDO is checked for readability, an RPDO for writability.
    let now = w.now;
    let s = w.nodes[SLAVE].core_mut();
    s.write(now, 0x1400, 1, &0x8000_0205u32.to_le_bytes())
        .unwrap();
    s.write(now, 0x1600, 0, &[0]).unwrap();
    assert_eq!(
        s.write(now, 0x1600, 1, &0x1001_0008u32.to_le_bytes()),
        Err(AbortCode::NOT_MAPPABLE),
        "0x1001 is read-only"
    );
}

#[test]
fn writes_through_an_rpdo_trigger_event_driven_tpdos_that_map_the_entry() {
    // Gateway: RPDO2 writes 0x6201; TPDO1 (type 255) maps it.
    let mut tables = rpdos(255, 0);
    tables.extend(params::tpdo_comm(
        1,
        params::predefined_tpdo_cob(1),
        255,
        0,
        0,
    ));
    tables.extend(params::tpdo_mapping::<2>(1, &[0x6201_0010]));
    let mut w = wire(&[&tables]);
    w.now = ms(5);
    w.deliver(Frame::new(Id::Standard(0x305), &[0x34, 0x12]).unwrap());
    let sent = w.sent(SLAVE, 0x185);
    assert_eq!(sent.len(), 2);
    assert_eq!(
        sent[1],
        (
            ms(5),
            Frame::new(Id::Standard(0x185), &[0x34, 0x12]).unwrap()
        )
    );
}

#[test]
fn unusable_stored_mapping_is_reported_and_silent() {
    let mut tables = params::tpdo_comm(1, params::predefined_tpdo_cob(1), 255, 0, 0).to_vec();
    tables.extend(params::tpdo_mapping::<2>(1, &[0x7777_0008]));
    let mut w = Wire::new(vec![with(1, true, &[]), with(5, false, &[&tables])]);
    w.boot_all();
    start_slave(&mut w);
    assert!(w.sent(SLAVE, 0x185).is_empty());
    assert!(pdo_events(&w, SLAVE).contains(&(
        ms(0),
        PdoEvent::Unusable {
            dir: Dir::Transmit,
            pdo: 1,
            reason: AbortCode::NO_OBJECT
        }
    )));
    assert_eq!(
        w.nodes[SLAVE].tpdo_status(1).unwrap().error,
        Some(AbortCode::NO_OBJECT)
    );
    // Once the entry exists, a reload brings the PDO up.
    w.nodes[SLAVE]
        .od_mut()
        .insert(ObjectDef::u8(0x7777, 0, Access::Rw, 9).mappable())
        .unwrap();
    w.nodes[SLAVE].reload_pdos(w.now);
    w.flush();
    assert_eq!(w.sent(SLAVE, 0x185)[0].1.data(), &[9]);
}
