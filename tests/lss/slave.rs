//! The slave: each service as frames in and frames out, in the modes CiA 305 serves it.

use super::wire::{addr, ans, feed, req, slave};
use duocan::cia305::{BitTiming, LssMode, LssSlave, LssSlaveEventKind, LssStoreError, StoredLss};
use duocan::{Duration, Frame, Id, Instant, Machine, NodeId};

const A: [u32; 4] = [0x0000_002A, 0x0000_0007, 0x0001_0002, 0x0000_1234];

fn board() -> duocan::cia305::LssAddress {
    addr(A[0], A[1], A[2], A[3])
}

fn u32_req(cs: u8, v: u32) -> Frame {
    let b = v.to_le_bytes();
    req([cs, b[0], b[1], b[2], b[3], 0, 0, 0])
}

fn to_config() -> Frame {
    req([0x04, 1, 0, 0, 0, 0, 0, 0])
}

fn events<S: duocan::od::parameters::ParameterStorage>(
    s: &mut LssSlave<S>,
) -> Vec<LssSlaveEventKind> {
    std::iter::from_fn(|| s.poll_event())
        .map(|e| e.kind)
        .collect()
}

#[test]
fn switch_selective_answers_the_fourth_part_only_in_sequence() {
    let mut s = slave(board(), 0xFF);
    let t = Instant::ZERO;
    // Vendor, product, then a wrong revision: the sequence restarts, no answer.
    let wrong = [
        u32_req(0x40, A[0]),
        u32_req(0x41, A[1]),
        u32_req(0x42, 9),
        u32_req(0x43, A[3]),
    ];
    assert!(feed(&mut s, t, &wrong).is_empty());
    assert_eq!(s.mode(), LssMode::Waiting);
    // Serial alone does not select either.
    assert!(feed(&mut s, t, &[u32_req(0x43, A[3])]).is_empty());
    // A vendor part in the middle starts the sequence over: vendor, product, vendor, product,
    // revision, serial selects.
    let mut right: Vec<Frame> = vec![u32_req(0x40, A[0]), u32_req(0x41, A[1])];
    right.extend((0..4).map(|i| u32_req(0x40 + i as u8, A[i])));
    assert_eq!(feed(&mut s, t, &right), [[0x44, 0, 0, 0, 0, 0, 0, 0]]);
    assert_eq!(s.mode(), LssMode::Configuration);
    assert_eq!(
        events(&mut s),
        [LssSlaveEventKind::Mode(LssMode::Configuration)]
    );
    // Switch state global back to waiting: no answer.
    assert!(feed(&mut s, t, &[req([0x04, 0, 0, 0, 0, 0, 0, 0])]).is_empty());
    assert_eq!(s.mode(), LssMode::Waiting);
}

#[test]
fn configure_node_id_only_in_configuration_and_only_valid_ids() {
    let mut s = slave(board(), 0xFF);
    let t = Instant::ZERO;
    // Waiting: ignored.
    assert!(feed(&mut s, t, &[req([0x11, 5, 0, 0, 0, 0, 0, 0])]).is_empty());
    assert_eq!(s.pending_node_id(), 0xFF);
    feed(&mut s, t, &[to_config()]);
    let answers = feed(
        &mut s,
        t,
        &[
            req([0x11, 0, 0, 0, 0, 0, 0, 0]),
            req([0x11, 128, 0, 0, 0, 0, 0, 0]),
            req([0x11, 5, 0, 0, 0, 0, 0, 0]),
        ],
    );
    // 0 and 128 are out of range (error 1), 5 is taken.
    assert_eq!(
        answers,
        [
            [0x11, 1, 0, 0, 0, 0, 0, 0],
            [0x11, 1, 0, 0, 0, 0, 0, 0],
            [0x11, 0, 0, 0, 0, 0, 0, 0]
        ]
    );
    assert_eq!((s.pending_node_id(), s.node_id()), (5, None));
    // The inquired node-ID is the active one: still none.
    assert_eq!(
        feed(&mut s, t, &[req([0x5E, 0, 0, 0, 0, 0, 0, 0])]),
        [[0x5E, 0xFF, 0, 0, 0, 0, 0, 0]]
    );
}

#[test]
fn a_non_configured_slave_takes_its_node_id_when_switched_back_to_waiting() {
    let mut s = slave(board(), 0xFF);
    let t = Instant::from_millis(3);
    feed(&mut s, t, &[to_config(), req([0x11, 9, 0, 0, 0, 0, 0, 0])]);
    let _ = events(&mut s);
    feed(&mut s, t, &[req([0x04, 0, 0, 0, 0, 0, 0, 0])]);
    assert_eq!(s.node_id(), Some(NodeId::must(9)));
    assert_eq!(
        events(&mut s),
        [
            LssSlaveEventKind::Mode(LssMode::Waiting),
            LssSlaveEventKind::ResetCommunication(NodeId::must(9))
        ]
    );
    assert!(!s.is_non_configured());
}

#[test]
fn a_configured_slave_takes_a_new_node_id_at_reset_communication() {
    let mut s = slave(board(), 4);
    let t = Instant::ZERO;
    feed(
        &mut s,
        t,
        &[
            to_config(),
            req([0x11, 7, 0, 0, 0, 0, 0, 0]),
            req([0x04, 0, 0, 0, 0, 0, 0, 0]),
        ],
    );
    // Configured before: switching back does not reset; the old node-ID stays active.
    assert_eq!(s.node_id(), Some(NodeId::must(4)));
    let _ = events(&mut s);
    // NMT start of node 4 changes nothing; reset-communication of another node neither.
    s.handle_frame(t, &Frame::from_array(Id::Standard(0), [0x01, 4]));
    s.handle_frame(t, &Frame::from_array(Id::Standard(0), [0x82, 5]));
    assert_eq!(s.node_id(), Some(NodeId::must(4)));
    // Reset-communication of node 4: node-ID 7 is active.
    s.handle_frame(t, &Frame::from_array(Id::Standard(0), [0x82, 4]));
    assert_eq!(s.node_id(), Some(NodeId::must(7)));
    assert_eq!(
        events(&mut s),
        [LssSlaveEventKind::NodeIdActivated(Some(NodeId::must(7)))]
    );
    // Configured to 0xFF and reset by the composer: non-configured again.
    feed(
        &mut s,
        t,
        &[to_config(), req([0x11, 0xFF, 0, 0, 0, 0, 0, 0])],
    );
    s.reset_communication(t);
    assert_eq!(s.node_id(), None);
    assert!(s.is_non_configured());
}

#[test]
fn bit_timing_is_configured_then_activated_with_the_two_delays() {
    // A device that runs at 500 and 250 kbit/s only (indices 2 and 3).
    let mut s = slave(board(), 3).with_bit_rates(0b1100);
    let t0 = Instant::from_millis(10);
    feed(&mut s, t0, &[to_config()]);
    let answers = feed(
        &mut s,
        t0,
        &[
            req([0x13, 0, 0, 0, 0, 0, 0, 0]),
            req([0x13, 0, 5, 0, 0, 0, 0, 0]),
            req([0x13, 1, 3, 0, 0, 0, 0, 0]),
            req([0x13, 0, 3, 0, 0, 0, 0, 0]),
        ],
    );
    // 1000 kbit/s unsupported, index 5 reserved, table 1 unknown: error 1; 250 kbit/s taken.
    let refused = [0x13, 1, 0, 0, 0, 0, 0, 0];
    assert_eq!(
        answers,
        [refused, refused, refused, [0x13, 0, 0, 0, 0, 0, 0, 0]]
    );
    let _ = events(&mut s);
    // Activate with a 100 ms delay: no answer, silent at once.
    assert!(feed(&mut s, t0, &[req([0x15, 100, 0, 0, 0, 0, 0, 0])]).is_empty());
    assert_eq!(s.poll_timeout(), Some(t0 + Duration::from_millis(100)));
    assert!(feed(
        &mut s,
        t0 + Duration::from_millis(50),
        &[req([0x5E, 0, 0, 0, 0, 0, 0, 0])]
    )
    .is_empty());
    s.handle_timeout(t0 + Duration::from_millis(100));
    assert_eq!(s.bit_timing(), Some(BitTiming::standard(3)));
    let e = s.poll_event().unwrap();
    assert_eq!(
        (e.at, e.kind),
        (
            t0 + Duration::from_millis(100),
            LssSlaveEventKind::SwitchBitRate(BitTiming::standard(3))
        )
    );
    // Silent for the second delay too, then answering again.
    assert!(feed(
        &mut s,
        t0 + Duration::from_millis(199),
        &[req([0x5E, 0, 0, 0, 0, 0, 0, 0])]
    )
    .is_empty());
    assert_eq!(s.stats().silenced, 2);
    let late = t0 + Duration::from_millis(200);
    assert_eq!(
        feed(&mut s, late, &[req([0x5E, 0, 0, 0, 0, 0, 0, 0])]),
        [[0x5E, 3, 0, 0, 0, 0, 0, 0]]
    );
}

#[test]
fn store_writes_the_pending_configuration_and_a_new_board_loads_it() {
    let mut s = slave(board(), 0xFF);
    let t = Instant::ZERO;
    feed(
        &mut s,
        t,
        &[
            to_config(),
            req([0x11, 12, 0, 0, 0, 0, 0, 0]),
            req([0x13, 0, 4, 0, 0, 0, 0, 0]),
        ],
    );
    assert_eq!(
        feed(&mut s, t, &[req([0x17, 0, 0, 0, 0, 0, 0, 0])]),
        [[0x17, 0, 0, 0, 0, 0, 0, 0]]
    );
    assert!(events(&mut s).contains(&LssSlaveEventKind::Stored));
    let medium = s.storage().unwrap().clone();
    assert_eq!(medium.image().unwrap().len(), 12);
    // Power cycle: the same medium, a board that boots non-configured, loads node 12.
    let mut again = LssSlave::new(board(), 0xFF).with_storage(medium.clone());
    let stored = again.load_stored().unwrap();
    assert_eq!(
        stored,
        Some(StoredLss {
            node_id: 12,
            bit_timing: Some(BitTiming::standard(4))
        })
    );
    assert_eq!(again.node_id(), Some(NodeId::must(12)));
    // A flipped bit is noticed, nothing taken from it.
    let mut torn = medium.image().unwrap().to_vec();
    torn[4] ^= 1;
    let mut bad = duocan::od::parameters::MemoryStorage::<16>::new();
    duocan::od::parameters::ParameterStorage::store(&mut bad, &torn).unwrap();
    let mut third = LssSlave::new(board(), 0xFF).with_storage(bad);
    assert_eq!(third.load_stored(), Err(LssStoreError::Corrupt));
    assert_eq!(third.node_id(), None);
    // Without a medium: "not supported" (1).
    let mut plain = LssSlave::new(board(), 0xFF);
    assert_eq!(
        feed(
            &mut plain,
            t,
            &[to_config(), req([0x17, 0, 0, 0, 0, 0, 0, 0])]
        ),
        [[0x17, 1, 0, 0, 0, 0, 0, 0]]
    );
    assert_eq!(plain.load_stored(), Err(LssStoreError::Unsupported));
}

#[test]
fn inquire_answers_each_part_in_configuration_mode_only() {
    let mut s = slave(board(), 0x22);
    let t = Instant::ZERO;
    assert!(feed(&mut s, t, &[req([0x5A, 0, 0, 0, 0, 0, 0, 0])]).is_empty());
    feed(&mut s, t, &[to_config()]);
    for (i, cs) in (0x5A..=0x5D).enumerate() {
        let b = A[i].to_le_bytes();
        let want = [cs, b[0], b[1], b[2], b[3], 0, 0, 0];
        assert_eq!(feed(&mut s, t, &[req([cs, 0, 0, 0, 0, 0, 0, 0])]), [want]);
    }
    assert_eq!(
        feed(&mut s, t, &[req([0x5E, 0, 0, 0, 0, 0, 0, 0])]),
        [[0x5E, 0x22, 0, 0, 0, 0, 0, 0]]
    );
}

#[test]
fn identify_remote_slave_matches_ranges_and_non_configured_answers_0x50() {
    let t = Instant::ZERO;
    let ident =
        |v: [u32; 6]| -> Vec<Frame> { (0..6).map(|i| u32_req(0x46 + i as u8, v[i])).collect() };
    let mut s = slave(board(), 0xFF);
    // Revision 0x10002 in [0x10000, 0x1FFFF], serial 0x1234 in [0x1000, 0x1FFF]: answers, in
    // waiting mode and in configuration mode alike.
    let hit = ident([A[0], A[1], 0x1_0000, 0x1_FFFF, 0x1000, 0x1FFF]);
    assert_eq!(feed(&mut s, t, &hit), [[0x4F, 0, 0, 0, 0, 0, 0, 0]]);
    feed(&mut s, t, &[to_config()]);
    assert_eq!(feed(&mut s, t, &hit), [[0x4F, 0, 0, 0, 0, 0, 0, 0]]);
    // Serial above the range, or another product: silent.
    assert!(feed(&mut s, t, &ident([A[0], A[1], 0, u32::MAX, 0, 0x1233])).is_empty());
    assert!(feed(&mut s, t, &ident([A[0], 8, 0, u32::MAX, 0, u32::MAX])).is_empty());
    // Identify non-configured: this one is, a configured one is not.
    assert_eq!(
        feed(&mut s, t, &[req([0x4C, 0, 0, 0, 0, 0, 0, 0])]),
        [[0x50, 0, 0, 0, 0, 0, 0, 0]]
    );
    let mut configured = slave(board(), 5);
    assert!(feed(&mut configured, t, &[req([0x4C, 0, 0, 0, 0, 0, 0, 0])]).is_empty());
}

#[test]
fn fastscan_steps_compare_the_bits_above_bit_checked() {
    let mut s = slave(board(), 0xFF);
    let t = Instant::ZERO;
    let scan = |id: u32, bit: u8, sub: u8, next: u8| {
        let b = id.to_le_bytes();
        req([0x51, b[0], b[1], b[2], b[3], bit, sub, next])
    };
    let hit = [0x4F, 0, 0, 0, 0, 0, 0, 0];
    // Reset: answered.
    assert_eq!(feed(&mut s, t, &[scan(0, 0x80, 0, 0)]), [hit]);
    // Vendor 0x2A: bits 31..6 are 0 (answered); bit 5 set, so "bits 31..5 = 0" is not.
    assert_eq!(feed(&mut s, t, &[scan(0, 6, 0, 0)]), [hit]);
    assert!(feed(&mut s, t, &[scan(0, 5, 0, 0)]).is_empty());
    // A step for another part than the slave's position: silent.
    assert!(feed(&mut s, t, &[scan(A[1], 0, 1, 2)]).is_empty());
    // Confirm each part in turn; after the serial the slave is in configuration mode.
    for sub in 0..4u8 {
        assert_eq!(
            feed(&mut s, t, &[scan(A[sub as usize], 0, sub, (sub + 1) & 3)]),
            [hit]
        );
    }
    assert_eq!(s.mode(), LssMode::Configuration);
    // A configured slave ignores fastscan, reset included.
    let mut other = slave(board(), 5);
    assert!(feed(&mut other, t, &[scan(0, 0x80, 0, 0)]).is_empty());
}

#[test]
fn frames_that_are_not_lss_requests_are_counted_and_never_answered() {
    let mut s = slave(board(), 0xFF);
    let t = Instant::ZERO;
    let bad = [
        Frame::new(Id::Standard(0x7E5), &[0x04, 1]).unwrap(),
        req([0x99, 0, 0, 0, 0, 0, 0, 0]),
        req([0x04, 2, 0, 0, 0, 0, 0, 0]),
        req([0x51, 0, 0, 0, 0, 0x40, 0, 0]),
        Frame::remote(Id::Standard(0x7E5), 8).unwrap(),
    ];
    assert!(feed(&mut s, t, &bad).is_empty());
    assert_eq!(s.stats().malformed, 5);
    assert_eq!(s.mode(), LssMode::Waiting);
    // An answer of another slave on 0x7E4 is not a request.
    assert!(feed(&mut s, t, &[ans([0x4F, 0, 0, 0, 0, 0, 0, 0])]).is_empty());
    assert_eq!(s.stats().malformed, 5);
}
