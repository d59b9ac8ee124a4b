//! Unit tests of the merger.

use super::*;
use duocan::Id;

fn f(id: u16, d: u8) -> Frame {
    Frame::from_array(Id::Standard(id), [d])
}
fn t(us: u64) -> Instant {
    Instant::from_micros(us)
}
fn ms(v: u64) -> Instant {
    Instant::from_millis(v)
}
const W: Duration = Duration::from_millis(10);

/// An arrival on a trusted port, stamped `at`, handled at `now`.
fn arr<const N: usize>(
    m: &mut Merger<N>,
    now: Instant,
    at: Instant,
    p: usize,
    fr: &Frame,
) -> Verdict {
    m.arrive_at(now, at, p, fr, Trust::Trusted).0
}

#[test]
fn twin_within_window_is_dropped_and_a_copy_the_other_port_passed_is_new() {
    let mut m: Merger<16> = Merger::new(W);
    assert_eq!(m.arrive(t(0), 0, &f(1, 1)), Verdict::Deliver);
    assert_eq!(m.arrive(t(9_999), 1, &f(1, 1)), Verdict::Duplicate);
    assert_eq!(m.arrive(t(20_000), 0, &f(1, 1)), Verdict::Deliver);
    // Port 1 heard something else stamped more than a window later: it passed the copy.
    assert_eq!(m.arrive(t(30_001), 1, &f(2, 2)), Verdict::Deliver);
    assert_eq!(m.arrive(t(30_002), 1, &f(1, 1)), Verdict::Deliver);
    // The record of 20 ms was skipped: its twin never came.
    assert_eq!(m.stats().expired, 1);
}

#[test]
fn repeats_on_one_port_are_all_delivered_and_matched_one_for_one() {
    let mut m: Merger<16> = Merger::new(W);
    for i in 0..3 {
        assert_eq!(m.arrive(t(i), 0, &f(1, 1)), Verdict::Deliver);
    }
    assert_eq!(m.unmatched(&f(1, 1)), Some((0, 3)));
    for i in 0..3 {
        assert_eq!(m.arrive(t(5 + i), 1, &f(1, 1)), Verdict::Duplicate);
    }
    // A fourth copy on port 1 has no twin left: new occurrence, recorded for port 1.
    assert_eq!(m.arrive(t(9), 1, &f(1, 1)), Verdict::Deliver);
    assert_eq!(m.unmatched(&f(1, 1)), Some((1, 1)));
}

#[test]
fn different_data_or_dlc_or_rtr_is_a_different_key() {
    let mut m: Merger<16> = Merger::new(W);
    let a = Frame::new(Id::Standard(5), &[0]).unwrap();
    let b = Frame::new(Id::Standard(5), &[]).unwrap();
    let r = Frame::remote(Id::Standard(5), 0).unwrap();
    let x = Frame::new(Id::Extended(5), &[]).unwrap();
    for fr in [a, b, r, x] {
        assert_eq!(m.arrive(t(0), 0, &fr), Verdict::Deliver);
    }
    assert_eq!(m.keys(), 4);
    for fr in [a, b, r, x] {
        assert_eq!(m.arrive(t(1), 1, &fr), Verdict::Duplicate);
    }
}

#[test]
fn slots_are_freed_when_records_leave() {
    let mut m: Merger<16> = Merger::new(W);
    for i in 0..12u8 {
        m.arrive(t(0), 0, &f(0x100, i));
    }
    assert_eq!(m.keys(), 12);
    for i in 0..12u8 {
        assert_eq!(m.arrive(t(1), 1, &f(0x100, i)), Verdict::Duplicate);
    }
    m.expire(t(2));
    assert_eq!((m.len(), m.keys()), (0, 0));
}

#[test]
fn a_reader_far_behind_still_finds_every_twin_by_its_stamp() {
    // SYNC every 10 ms; port 1's reader hands its copies over 35 ms late (stamps on time).
    let mut m: Merger<64> = Merger::new(W);
    let sync = Frame::from_array(Id::Standard(0x80), []);
    for k in 0..50u64 {
        assert_eq!(
            arr(&mut m, ms(10 * k), ms(10 * k), 0, &sync),
            Verdict::Deliver
        );
        if k >= 3 {
            let (j, now) = (k - 3, ms(10 * k) + Duration::from_millis(5));
            let v = arr(
                &mut m,
                now,
                ms(10 * j) + Duration::from_micros(200),
                1,
                &sync,
            );
            assert_eq!(v, Verdict::Duplicate, "copy {j}");
        }
    }
    assert_eq!(m.stats().delivered, 50);
    assert_eq!(m.stats().expired, 0);
}

#[test]
fn the_closest_twin_is_taken_so_a_copy_one_bus_missed_does_not_shift_the_pairing() {
    let mut m: Merger<64> = Merger::new(W);
    let pdo = f(0x181, 7);
    // A PDO every 20 ms; port 0 missed the copy at 20.
    arr(&mut m, ms(0), ms(0), 0, &pdo);
    arr(&mut m, ms(40), ms(40), 0, &pdo);
    arr(&mut m, ms(60), ms(60), 0, &pdo);
    // Port 1's reader hands its copies of 0, 20, 40, 60 over late; the one of 20 has no twin.
    assert_eq!(arr(&mut m, ms(61), ms(0), 1, &pdo), Verdict::Duplicate);
    assert_eq!(arr(&mut m, ms(62), ms(20), 1, &pdo), Verdict::Deliver);
    assert_eq!(arr(&mut m, ms(63), ms(40), 1, &pdo), Verdict::Duplicate);
    assert_eq!(arr(&mut m, ms(64), ms(60), 1, &pdo), Verdict::Duplicate);
    // Then port 0 dies: port 1's copy of 80 is new, not the twin of an earlier record.
    assert_eq!(arr(&mut m, ms(85), ms(80), 1, &pdo), Verdict::Deliver);
    assert_eq!(m.stats().delivered, 5);
}

#[test]
fn a_record_stays_until_the_other_port_passes_it_or_the_horizon() {
    let mut m: Merger<64> = Merger::with_horizon(W, Duration::from_millis(50));
    arr(&mut m, ms(0), ms(0), 0, &f(1, 1));
    // Port 1 silent: the record waits for its twin up to the horizon, then is forgotten.
    m.expire(ms(49));
    assert_eq!(m.unmatched(&f(1, 1)), Some((0, 1)));
    m.expire(ms(50));
    assert_eq!(m.unmatched(&f(1, 1)), None);
    assert_eq!(m.stats().forgotten, 1);
    // Port 1 receiving frames stamped a window past it: its twin was lost, the record goes.
    arr(&mut m, ms(60), ms(60), 0, &f(1, 2));
    arr(&mut m, ms(70), ms(70), 1, &f(9, 9));
    m.expire(ms(70));
    assert_eq!(m.unmatched(&f(1, 2)), None);
    assert_eq!(m.stats().expired, 1);
    // Unless port 1 stamps frames when it hands them over: its stamps may run ahead of its
    // copies (a lag not measured yet), the record stays to the horizon.
    m.set_stamped(1, false);
    arr(&mut m, ms(100), ms(100), 0, &f(1, 3));
    arr(&mut m, ms(111), ms(111), 1, &f(9, 8));
    m.expire(ms(149));
    assert_eq!(m.unmatched(&f(1, 3)), Some((0, 1)));
    m.expire(ms(150));
    assert_eq!(m.unmatched(&f(1, 3)), None);
    // (Port 1's own record of 70 ms went too: port 0 passed it.)
    assert_eq!((m.stats().expired, m.stats().forgotten), (3, 1));
    // A later copy of the same content skips a record a window older at once.
    arr(&mut m, ms(200), ms(200), 0, &f(1, 4));
    assert_eq!(arr(&mut m, ms(211), ms(211), 1, &f(1, 4)), Verdict::Deliver);
    assert_eq!(m.unmatched(&f(1, 4)), Some((1, 1)));
}

#[test]
fn a_copy_older_than_what_is_remembered_is_late_and_dropped() {
    let mut m: Merger<64> = Merger::with_horizon(W, Duration::from_millis(50));
    for k in 0..10u64 {
        arr(&mut m, ms(10 * k), ms(10 * k), 0, &f(1, k as u8));
    }
    // Port 1's reader wakes 100 ms late with its backlog: past the horizon for the oldest.
    let mut late = 0;
    for k in 0..10u64 {
        match arr(&mut m, ms(100 + k), ms(10 * k), 1, &f(1, k as u8)) {
            Verdict::Late => late += 1,
            Verdict::Duplicate => {}
            v => panic!("copy {k}: {v:?}"),
        }
    }
    assert!(late >= 5, "{late}");
    assert_eq!(m.stats().delivered, 10);
}

/// A receiver held up as a whole (both reader threads starved on a loaded machine) hands over
/// copies stamped 150 ms earlier, three horizons; port 1's come 10 ms after port 0's. A copy is
/// kept for the horizon after it was handed over, so each finds its twin, unchanged repeats
/// too (kept for the horizon after its stamp, each would be forgotten as it arrived, its twin
/// left to the memory of forgotten keys). A copy whose twin never comes is forgotten one
/// horizon after it was handed over.
#[test]
fn a_receiver_held_up_as_a_whole_still_finds_every_twin() {
    let mut m: Merger<256> = Merger::with_horizon(W, Duration::from_millis(50));
    let sync = Frame::from_array(Id::Standard(0x80), []);
    let us = Duration::from_micros;
    for (p, handed) in [(0, ms(150)), (1, ms(160))] {
        let want = [Verdict::Deliver, Verdict::Duplicate][p];
        for k in 0..20u64 {
            let now = handed + us(10 * k);
            assert_eq!(
                arr(&mut m, now, ms(k), p, &sync),
                want,
                "SYNC {k}, port {p}"
            );
            let counter = f(2, k as u8);
            assert_eq!(arr(&mut m, now, ms(k) + us(300), p, &counter), want);
        }
    }
    let s = m.stats();
    assert_eq!((s.delivered, s.duplicates, s.late), (40, 40, 0));
    assert_eq!((s.forgotten, s.expired, s.slipped), (0, 0, 0));
    arr(&mut m, ms(300), ms(200), 0, &f(3, 3));
    m.expire(ms(349));
    assert_eq!(m.unmatched(&f(3, 3)), Some((0, 1)));
    m.expire(ms(350));
    assert_eq!(m.unmatched(&f(3, 3)), None);
    assert_eq!(m.stats().forgotten, 1);
}

/// A record is 16 bytes, as the module documentation says: how late it was handed over fits in
/// what its alignment leaves.
#[test]
fn a_record_is_16_bytes() {
    assert_eq!(core::mem::size_of::<Record>(), 16);
}

#[test]
fn an_unproven_port_gives_only_what_the_other_port_has_not_passed() {
    let mut m: Merger<64> = Merger::new(W);
    let u =
        |m: &mut Merger<64>, now, at, fr: &Frame| m.arrive_at(now, at, 1, fr, Trust::Unproven).0;
    arr(&mut m, ms(0), ms(0), 0, &f(1, 1));
    arr(&mut m, ms(5), ms(5), 0, &f(2, 2));
    // A frame queued before the fault, flushed by the repaired bus: port 0 passed its time.
    assert_eq!(u(&mut m, ms(5), ms(3), &f(7, 7)), Verdict::Unproven);
    // A twin is still a twin.
    assert_eq!(u(&mut m, ms(5), ms(5), &f(2, 2)), Verdict::Duplicate);
    // Port 0 falls silent at 5: what port 1 carries from then on is delivered at once.
    assert_eq!(u(&mut m, ms(6), ms(6), &f(3, 3)), Verdict::Deliver);
    assert_eq!(u(&mut m, ms(7), ms(7), &f(3, 3)), Verdict::Deliver);
    assert_eq!(m.stats().unproven, 1);
}

#[test]
fn a_full_ring_evicts_and_remembers_what_it_forgot() {
    let mut m: Merger<16> = Merger::new(W);
    for i in 0..13u8 {
        arr(&mut m, t(i as u64), t(i as u64), 0, &f(0x100, i));
    }
    assert_eq!(m.len(), m.capacity());
    assert_eq!(m.stats().evicted, 1);
    // The evicted copy's twin is dropped as late, the others matched.
    assert_eq!(arr(&mut m, t(20), t(0), 1, &f(0x100, 0)), Verdict::Late);
    assert_eq!(
        arr(&mut m, t(21), t(12), 1, &f(0x100, 12)),
        Verdict::Duplicate
    );
}

#[test]
fn only_a_fresh_single_copy_measures_a_lag() {
    let mut m: Merger<64> = Merger::new(W);
    let a =
        |m: &mut Merger<64>, now, at, p, fr: &Frame| m.arrive_at(now, at, p, fr, Trust::Trusted);
    // A fresh frame, its twin 4 ms later: a sample.
    a(&mut m, ms(0), ms(0), 0, &f(1, 1));
    assert_eq!(
        a(&mut m, ms(4), ms(4), 1, &f(1, 1)),
        (
            Verdict::Duplicate,
            Some(Sample {
                skew: 4_000,
                late: false
            })
        )
    );
    // Its repeat 20 ms later is no sample: it could be paired one period off.
    a(&mut m, ms(20), ms(20), 0, &f(1, 1));
    assert_eq!(
        a(&mut m, ms(24), ms(24), 1, &f(1, 1)),
        (Verdict::Duplicate, None)
    );
    // A fresh frame whose twin comes beyond the window, port 1 (stamping on hand-over)
    // receiving meanwhile: delivered, with a late sample.
    m.set_stamped(1, false);
    a(&mut m, ms(40), ms(40), 0, &f(2, 2));
    a(&mut m, ms(50), ms(50), 1, &f(3, 3));
    assert_eq!(
        a(&mut m, ms(65), ms(65), 1, &f(2, 2)),
        (
            Verdict::Deliver,
            Some(Sample {
                skew: 25_000,
                late: true
            })
        )
    );
    assert_eq!(m.stats().slipped, 1);
    // The same after a silence of port 1 (an outage): what it missed was lost, not late.
    a(&mut m, ms(100), ms(100), 0, &f(4, 4));
    assert_eq!(
        a(&mut m, ms(125), ms(125), 1, &f(4, 4)),
        (Verdict::Deliver, None)
    );
}

#[test]
fn a_step_back_keeps_what_each_record_has_left() {
    let mut m: Merger<16> = Merger::new(W);
    arr(&mut m, ms(1_000), ms(1_000), 0, &f(1, 1));
    m.step_back(Duration::from_millis(990));
    assert_eq!(arr(&mut m, ms(15), ms(15), 1, &f(1, 1)), Verdict::Duplicate);
}

#[test]
fn a_bad_port_is_delivered_and_counted() {
    let mut m: Merger<16> = Merger::new(W);
    assert_eq!(m.arrive(t(0), 2, &f(1, 1)), Verdict::Deliver);
    assert_eq!(m.stats().bad_port, 1);
    assert!(m.is_empty());
}
