//! The master: each service against a slave with the frames on the wire, and every way a
//! request ends badly (timeout, refusal, wrong answer, malformed answer, busy).

use super::wire::{addr, ans, slave, Wire};
use duocan::cia305::{
    BitTiming, IdentifyRange, Inquiry, LssError, LssFrameError, LssMaster, LssMasterConfig,
    LssMasterEventKind as K, LssMode, LssOutcome, LssService,
};
use duocan::{Duration, Instant, Machine, NodeId};

const MS: u64 = 1000;

fn board() -> duocan::cia305::LssAddress {
    addr(0x2A, 7, 0x1_0002, 0x1234)
}

fn master() -> LssMaster {
    LssMaster::new(LssMasterConfig::default().with_timeout(Duration::from_millis(20)))
}

fn one(node: u8) -> Wire {
    Wire::new(master(), vec![slave(board(), node)])
}

#[test]
fn selective_switch_configure_store_and_inquire_each_with_its_frames() {
    let mut w = one(0xFF);
    let t = Instant::ZERO;
    w.master.switch_selective(t, board()).unwrap();
    w.run(10);
    assert_eq!(
        w.data(),
        [
            (0x7E5, vec![0x40, 0x2A, 0, 0, 0, 0, 0, 0]),
            (0x7E5, vec![0x41, 7, 0, 0, 0, 0, 0, 0]),
            (0x7E5, vec![0x42, 2, 0, 1, 0, 0, 0, 0]),
            (0x7E5, vec![0x43, 0x34, 0x12, 0, 0, 0, 0, 0]),
            (0x7E4, vec![0x44, 0, 0, 0, 0, 0, 0, 0]),
        ]
    );
    assert_eq!(w.take_events(), [K::Done(LssOutcome::Selected)]);
    w.log.clear();
    w.master.configure_node_id(t, 17).unwrap();
    w.run(10);
    w.master
        .configure_bit_timing(t, BitTiming::standard(2))
        .unwrap();
    w.run(10);
    w.master.store(t).unwrap();
    w.run(10);
    w.master.inquire(t, Inquiry::Serial).unwrap();
    w.run(10);
    w.master.inquire(t, Inquiry::NodeId).unwrap();
    w.run(10);
    assert_eq!(
        w.data(),
        [
            (0x7E5, vec![0x11, 17, 0, 0, 0, 0, 0, 0]),
            (0x7E4, vec![0x11, 0, 0, 0, 0, 0, 0, 0]),
            (0x7E5, vec![0x13, 0, 2, 0, 0, 0, 0, 0]),
            (0x7E4, vec![0x13, 0, 0, 0, 0, 0, 0, 0]),
            (0x7E5, vec![0x17, 0, 0, 0, 0, 0, 0, 0]),
            (0x7E4, vec![0x17, 0, 0, 0, 0, 0, 0, 0]),
            (0x7E5, vec![0x5D, 0, 0, 0, 0, 0, 0, 0]),
            (0x7E4, vec![0x5D, 0x34, 0x12, 0, 0, 0, 0, 0]),
            (0x7E5, vec![0x5E, 0, 0, 0, 0, 0, 0, 0]),
            (0x7E4, vec![0x5E, 0xFF, 0, 0, 0, 0, 0, 0]),
        ]
    );
    assert_eq!(
        w.take_events(),
        [
            K::Done(LssOutcome::NodeIdConfigured),
            K::Done(LssOutcome::BitTimingConfigured),
            K::Done(LssOutcome::Stored),
            K::Done(LssOutcome::Inquired(Inquiry::Serial, 0x1234)),
            K::Done(LssOutcome::Inquired(Inquiry::NodeId, 0xFF)),
        ]
    );
    // Switch global to waiting: the slave takes node 17 by itself.
    w.master.switch_global(t, LssMode::Waiting).unwrap();
    w.run(10);
    assert_eq!(
        w.take_events(),
        [K::Done(LssOutcome::Sent(LssService::SwitchGlobal))]
    );
    assert_eq!(w.slaves[0].node_id(), Some(NodeId::must(17)));
    assert_eq!(w.master.stats().unsolicited, 0);
}

#[test]
fn activate_bit_timing_is_done_when_written_and_the_slave_switches_after_the_delay() {
    let mut w = one(3);
    let t = Instant::ZERO;
    w.master.switch_global(t, LssMode::Configuration).unwrap();
    // Switch global is done when written: the next request is accepted at once.
    assert!(w.master.is_idle());
    w.master
        .configure_bit_timing(t, BitTiming::standard(4))
        .unwrap();
    w.run(10);
    w.master.activate_bit_timing(w.now, 30).unwrap();
    w.run(10);
    assert_eq!(w.log.last().unwrap().1.data(), [0x15, 30, 0, 0, 0, 0, 0, 0]);
    // The slave switched at 30 ms and was silent until 60 ms.
    assert_eq!(w.now, Instant::from_millis(60));
    assert_eq!(w.slaves[0].bit_timing(), Some(BitTiming::standard(4)));
}

#[test]
fn identify_waits_the_whole_timeout_and_says_whether_anyone_answered() {
    let range = IdentifyRange {
        vendor: 0x2A,
        product: 7,
        revision_low: 0,
        revision_high: u32::MAX,
        serial_low: 0x1000,
        serial_high: 0x2000,
    };
    let mut w = Wire::new(
        master(),
        vec![slave(board(), 0xFF), slave(addr(0x2A, 7, 1, 0x1500), 4)],
    );
    w.master.identify_remote(Instant::ZERO, range).unwrap();
    w.run(10);
    // Six requests, two answers, the result at the timeout.
    assert_eq!(w.log.len(), 8);
    assert_eq!(w.log[6].1.data(), [0x4F, 0, 0, 0, 0, 0, 0, 0]);
    assert_eq!(w.now, Instant::from_millis(20));
    assert_eq!(
        w.take_events(),
        [K::Done(LssOutcome::Identified(
            LssService::IdentifyRemote,
            true
        ))]
    );
    w.master
        .identify_remote(
            w.now,
            IdentifyRange {
                serial_low: 0x3000,
                serial_high: 0x4000,
                ..range
            },
        )
        .unwrap();
    w.run(10);
    assert_eq!(
        w.take_events(),
        [K::Done(LssOutcome::Identified(
            LssService::IdentifyRemote,
            false
        ))]
    );
    w.master.identify_non_configured(w.now).unwrap();
    w.run(10);
    assert_eq!(
        w.take_events(),
        [K::Done(LssOutcome::Identified(
            LssService::IdentifyNonConfigured,
            true
        ))]
    );
}

#[test]
fn a_request_nobody_answers_times_out_exactly_at_its_deadline() {
    let mut w = Wire::new(master(), vec![]);
    let t0 = Instant::from_millis(5);
    w.now = t0;
    w.master.inquire(t0, Inquiry::Vendor).unwrap();
    assert_eq!(w.master.poll_timeout(), Some(Instant::from_millis(25)));
    w.run(10);
    let e = w.events.remove(0);
    assert_eq!(
        (e.at.as_micros(), e.kind),
        (
            25 * MS,
            K::Failed(LssError::Timeout(LssService::Inquire(Inquiry::Vendor)))
        )
    );
    assert!(w.master.is_idle());
    // A slave in waiting mode ignores configure node-ID: a timeout too.
    let mut w = one(0xFF);
    w.master.configure_node_id(Instant::ZERO, 5).unwrap();
    w.run(10);
    assert_eq!(
        w.take_events(),
        [K::Failed(LssError::Timeout(LssService::ConfigureNodeId))]
    );
}

#[test]
fn a_refusal_a_wrong_answer_and_a_malformed_answer_are_typed_errors() {
    // The slave refuses 1000 kbit/s.
    let mut w = Wire::new(master(), vec![slave(board(), 3).with_bit_rates(0b1000)]);
    w.master
        .switch_global(Instant::ZERO, LssMode::Configuration)
        .unwrap();
    w.run(10);
    let _ = w.take_events();
    w.master
        .configure_bit_timing(Instant::ZERO, BitTiming::standard(0))
        .unwrap();
    w.run(10);
    let refused = LssError::Refused {
        service: LssService::ConfigureBitTiming,
        error: 1,
        spec: 0,
    };
    assert_eq!(w.take_events(), [K::Failed(refused)]);
    assert_eq!(refused.to_string(), "configure bit timing: the slave refused with code 1 (out of range or not supported, spec 0)");

    // A slave that answers configure node-ID with a store answer, or with 3 bytes.
    let t = Instant::ZERO;
    let mut m = master();
    m.configure_node_id(t, 5).unwrap();
    m.handle_frame(t, &ans([0x17, 0, 0, 0, 0, 0, 0, 0]));
    let wrong = LssError::WrongAnswer {
        service: LssService::ConfigureNodeId,
        cs: 0x17,
    };
    assert_eq!(m.poll_event().unwrap().kind, K::Failed(wrong));
    m.store(t).unwrap();
    m.handle_frame(
        t,
        &duocan::Frame::new(duocan::Id::Standard(0x7E4), &[0x17, 0, 0]).unwrap(),
    );
    let e = m.poll_event().unwrap().kind;
    assert_eq!(
        e,
        K::Failed(LssError::Malformed {
            service: LssService::Store,
            error: LssFrameError::Length(3)
        })
    );
    // An inquiry answered with another part.
    m.inquire(t, Inquiry::Vendor).unwrap();
    m.handle_frame(t, &ans([0x5B, 1, 0, 0, 0, 0, 0, 0]));
    let wrong = LssError::WrongAnswer {
        service: LssService::Inquire(Inquiry::Vendor),
        cs: 0x5B,
    };
    assert_eq!(m.poll_event().unwrap().kind, K::Failed(wrong));
    // Answers while idle are counted, not taken.
    m.handle_frame(t, &ans([0x4F, 0, 0, 0, 0, 0, 0, 0]));
    assert_eq!((m.stats().unsolicited, m.poll_event()), (1, None));
}

#[test]
fn one_request_at_a_time_and_node_ids_are_checked_before_sending() {
    let mut m = master();
    let t = Instant::ZERO;
    assert_eq!(m.configure_node_id(t, 0), Err(LssError::InvalidNodeId(0)));
    assert_eq!(
        m.configure_node_id(t, 128),
        Err(LssError::InvalidNodeId(128))
    );
    assert!(m.poll_transmit().is_none());
    m.inquire(t, Inquiry::Product).unwrap();
    assert_eq!(m.store(t), Err(LssError::Busy));
    assert_eq!(m.fastscan(t, Default::default()), Err(LssError::Busy));
    assert_eq!(
        m.poll_transmit().unwrap().data(),
        [0x5B, 0, 0, 0, 0, 0, 0, 0]
    );
    assert!(m.poll_transmit().is_none());
    // 0xFF ("none") is a valid node-ID to configure.
    m.handle_timeout(Instant::from_millis(20));
    m.configure_node_id(Instant::from_millis(20), 0xFF).unwrap();
}

#[test]
fn a_clock_step_back_keeps_the_time_a_request_has_left() {
    let mut m = master();
    m.store(Instant::from_millis(100)).unwrap();
    // 5 ms pass, then the clock steps back by 50 ms: 15 ms are left.
    m.handle_timeout(Instant::from_millis(105));
    m.handle_timeout(Instant::from_millis(55));
    assert_eq!(m.poll_timeout(), Some(Instant::from_millis(70)));
}
