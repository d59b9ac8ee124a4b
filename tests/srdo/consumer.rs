//! The consumer's rules one by one, with the frames on the wire (`SrdoConsumer` alone): SCT
//! 50 ms, SRVT 10 ms, two bytes on 0x101/0x102, started at 0 ms.

use duocan::cia304::srdo::consumer::{ConsumerStep, SrdoCause, SrdoConsumer, SrdoFault};
use duocan::{Duration, Frame, Id, Instant};

fn ms(v: u64) -> Instant {
    Instant::from_millis(v)
}
fn normal(d: [u8; 2]) -> Frame {
    Frame::from_array(Id::Standard(0x101), d)
}
fn inverted(d: [u8; 2]) -> Frame {
    Frame::from_array(Id::Standard(0x102), [!d[0], !d[1]])
}
fn started() -> SrdoConsumer {
    let (sct, srvt) = (Duration::from_millis(50), Duration::from_millis(10));
    let mut c = SrdoConsumer::new(0x101, 0x102, sct, srvt, 2);
    c.start(ms(0));
    c
}
fn deliver(d: [u8; 2]) -> Option<ConsumerStep> {
    Some(ConsumerStep::Deliver([d[0], d[1], 0, 0, 0, 0, 0, 0]))
}
fn trip(cause: SrdoCause, at: u64, measured: u64) -> Option<ConsumerStep> {
    Some(ConsumerStep::Trip(SrdoFault {
        cause,
        at: ms(at),
        measured: Duration::from_millis(measured),
    }))
}

#[test]
fn a_pair_within_srvt_is_delivered_and_only_then() {
    let mut c = started();
    assert_eq!(
        c.handle_frame(ms(3), &normal([1, 2])),
        Some(ConsumerStep::Held)
    );
    assert_eq!(c.poll_timeout(), Some(ms(13)));
    // 9.999 ms after the normal frame: in time.
    let t = Instant::from_micros(12_999);
    assert_eq!(c.handle_frame(t, &inverted([1, 2])), deliver([1, 2]));
    // The SCT now runs from the completed pair.
    assert_eq!(c.poll_timeout(), Some(Instant::from_micros(62_999)));
}

#[test]
fn the_inverse_exactly_srvt_late_is_late() {
    let mut c = started();
    c.handle_frame(ms(3), &normal([1, 2]));
    assert_eq!(
        c.handle_frame(ms(13), &inverted([1, 2])),
        trip(SrdoCause::Validation, 13, 10)
    );
    assert_eq!(c.fault().unwrap().cause, SrdoCause::Validation);
}

#[test]
fn a_missing_inverse_trips_at_srvt() {
    let mut c = started();
    c.handle_frame(ms(3), &normal([1, 2]));
    assert_eq!(c.handle_timeout(Instant::from_micros(12_999)), None);
    assert_eq!(
        c.handle_timeout(ms(13)),
        trip(SrdoCause::Validation, 13, 10)
    );
    assert_eq!(c.poll_timeout(), None, "the safe state waits for nothing");
}

#[test]
fn one_bit_wrong_in_the_inverse_trips_at_once() {
    let mut c = started();
    c.handle_frame(ms(3), &normal([0x12, 0x34]));
    let mut bad = inverted([0x12, 0x34]);
    bad = Frame::new(bad.id(), &[bad.data()[0], bad.data()[1] ^ 0x08]).unwrap();
    assert_eq!(
        c.handle_frame(ms(4), &bad),
        trip(SrdoCause::NotInverted, 4, 1)
    );
}

#[test]
fn a_corrupt_normal_frame_never_gets_through() {
    let mut c = started();
    // The normal frame was hit on the way (bit 0), the inverse was not: they disagree.
    c.handle_frame(ms(3), &normal([0x13, 0x34]));
    assert_eq!(
        c.handle_frame(ms(4), &inverted([0x12, 0x34])),
        trip(SrdoCause::NotInverted, 4, 1)
    );
}

#[test]
fn a_short_frame_trips() {
    let mut c = started();
    let short = Frame::from_array(Id::Standard(0x101), [1]);
    assert_eq!(c.handle_frame(ms(3), &short), trip(SrdoCause::Length, 3, 0));
    // Longer frames carry the SRDO's bytes first: taken.
    let mut c = started();
    c.handle_frame(ms(3), &Frame::from_array(Id::Standard(0x101), [1, 2, 9]));
    assert_eq!(c.handle_frame(ms(4), &inverted([1, 2])), deliver([1, 2]));
}

#[test]
fn two_different_normal_frames_in_a_row_trip() {
    let mut c = started();
    c.handle_frame(ms(3), &normal([1, 2]));
    assert_eq!(
        c.handle_frame(ms(5), &normal([1, 3])),
        trip(SrdoCause::Sequence, 5, 2)
    );
}

#[test]
fn a_copy_of_the_normal_frame_is_the_same_frame_and_srvt_runs_from_the_first() {
    let mut c = started();
    c.handle_frame(ms(3), &normal([1, 2]));
    assert_eq!(
        c.handle_frame(ms(5), &normal([1, 2])),
        Some(ConsumerStep::Held)
    );
    assert_eq!(c.poll_timeout(), Some(ms(13)));
    assert_eq!(c.handle_frame(ms(12), &inverted([1, 2])), deliver([1, 2]));
    // And it does not stretch the SRVT.
    let mut c = started();
    c.handle_frame(ms(3), &normal([1, 2]));
    c.handle_frame(ms(11), &normal([1, 2]));
    assert_eq!(
        c.handle_frame(ms(14), &inverted([1, 2])),
        trip(SrdoCause::Validation, 13, 10)
    );
}

#[test]
fn a_swapped_pair_is_checked_the_same_and_delivers_the_normal_data() {
    let mut c = started();
    // The inverse first (a dual-bus layer handing over halves from two buses): it waits.
    assert_eq!(
        c.handle_frame(ms(3), &inverted([1, 2])),
        Some(ConsumerStep::Held)
    );
    assert_eq!(c.poll_timeout(), Some(ms(13)));
    assert_eq!(c.handle_frame(ms(4), &normal([1, 2])), deliver([1, 2]));
    // Swapped and wrong is wrong; swapped and late is late.
    let mut c = started();
    c.handle_frame(ms(3), &inverted([1, 2]));
    assert_eq!(
        c.handle_frame(ms(4), &normal([1, 3])),
        trip(SrdoCause::NotInverted, 4, 1)
    );
    let mut c = started();
    c.handle_frame(ms(3), &inverted([1, 2]));
    assert_eq!(
        c.handle_frame(ms(13), &normal([1, 2])),
        trip(SrdoCause::Validation, 13, 10)
    );
    // Two different inverses in a row.
    let mut c = started();
    c.handle_frame(ms(3), &inverted([1, 2]));
    assert_eq!(
        c.handle_frame(ms(5), &inverted([1, 3])),
        trip(SrdoCause::Sequence, 5, 2)
    );
}

#[test]
fn no_pair_within_sct_trips_at_sct_from_the_start_and_from_each_pair() {
    let mut c = started();
    assert_eq!(c.poll_timeout(), Some(ms(50)));
    assert_eq!(c.handle_timeout(ms(50)), trip(SrdoCause::CycleTime, 50, 50));

    let mut c = started();
    c.handle_frame(ms(20), &normal([1, 2]));
    c.handle_frame(ms(21), &inverted([1, 2]));
    assert_eq!(c.handle_timeout(ms(70)), None);
    assert_eq!(c.handle_timeout(ms(71)), trip(SrdoCause::CycleTime, 71, 50));
}

#[test]
fn a_late_frame_reports_the_deadline_it_missed_not_its_arrival() {
    let mut c = started();
    // Nobody drove the timeout; the next frame comes at 80 ms. The trip is at 50 ms.
    assert_eq!(
        c.handle_frame(ms(80), &normal([1, 2])),
        trip(SrdoCause::CycleTime, 50, 50)
    );
}

#[test]
fn srvt_running_into_sct_reports_the_earlier_deadline() {
    let mut c = started();
    c.handle_frame(ms(45), &normal([1, 2]));
    // SCT at 50 comes before SRVT at 55.
    assert_eq!(c.handle_timeout(ms(60)), trip(SrdoCause::CycleTime, 50, 50));
}

#[test]
fn the_safe_state_holds_until_acknowledged_and_a_new_pair_arrives() {
    let mut c = started();
    c.handle_timeout(ms(50));
    // Intact pairs no longer count: the consumer ignores the bus.
    assert_eq!(c.handle_frame(ms(60), &normal([1, 2])), None);
    assert_eq!(c.handle_frame(ms(61), &inverted([1, 2])), None);
    assert!(c.fault().is_some());
    // The acknowledgement re-arms; the SCT runs from it.
    assert!(c.acknowledge(ms(100)));
    assert!(!c.acknowledge(ms(100)), "only a safe state is acknowledged");
    assert_eq!(c.poll_timeout(), Some(ms(150)));
    c.handle_frame(ms(110), &normal([3, 4]));
    assert_eq!(c.handle_frame(ms(111), &inverted([3, 4])), deliver([3, 4]));
}

#[test]
fn stopped_consumers_and_other_identifiers_take_nothing() {
    let mut c = started();
    assert_eq!(
        c.handle_frame(ms(1), &Frame::from_array(Id::Standard(0x103), [1, 2])),
        None
    );
    c.stop();
    assert_eq!(c.handle_frame(ms(2), &normal([1, 2])), None);
    assert_eq!(c.poll_timeout(), None);
    let rtr = Frame::remote(Id::Standard(0x101), 2).unwrap();
    c.start(ms(3));
    assert_eq!(c.handle_frame(ms(4), &rtr), None);
}
