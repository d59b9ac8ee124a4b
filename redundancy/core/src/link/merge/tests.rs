//! Unit tests of the merger.

use super::*;
use duocan_core::{Frame, Id};

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
/// horizon after it was handed over, or later while the other port's reader runs further
/// behind than that: until it would have shown the twin.
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
    // Port 1's reader ran 140.89 ms behind at its newest copy (stamped 19.3 ms, handed over at
    // 160.19 ms): a twin stamped up to 210 ms (the stamp plus the window) may come from it until
    // 350.89 ms, past the horizon (350 ms).
    m.expire(ms(350));
    assert_eq!(m.unmatched(&f(3, 3)), Some((0, 1)));
    m.expire(ms(350) + us(890));
    assert_eq!(m.unmatched(&f(3, 3)), None);
    assert_eq!(m.stats().forgotten, 1);
}

/// One port's reader falls behind the other's, by a quarter of a millisecond every
/// millisecond, to 200 ms (four horizons), handing its copies over all along: SYNC every
/// millisecond (a repeat ten times faster than the window) and a counter frame between. The other port's copies are kept until that reader has shown their
/// twins, so every copy finds its own: none given up, none dropped as late, none twice. A
/// horizon after they were handed over, they would be forgotten long before their twins came.
#[test]
fn a_reader_far_behind_while_it_hands_over_finds_every_twin() {
    let mut m: Merger<1024> = Merger::with_horizon(W, Duration::from_millis(50));
    let sync = Frame::from_array(Id::Standard(0x80), []);
    let mut arrivals = vec![];
    for k in 0..2_000u64 {
        let (s, c) = (ms(k), ms(k) + Duration::from_micros(400));
        let behind = Duration::from_micros((k * 250).min(200_000));
        let counter = Frame::from_array(Id::Standard(0x281), (k as u32).to_le_bytes());
        arrivals.extend([(s, 0, s, sync), (c, 0, c, counter)]);
        arrivals.extend([(s + behind, 1, s, sync), (c + behind, 1, c, counter)]);
    }
    arrivals.sort_by_key(|a| (a.0, a.1));
    for (now, p, at, fr) in arrivals {
        let want = [Verdict::Deliver, Verdict::Duplicate][p];
        assert_eq!(
            arr(&mut m, now, at, p, &fr),
            want,
            "{fr:?} stamped {at}, port {p}"
        );
    }
    let s = m.stats();
    assert_eq!((s.delivered, s.duplicates), (4_000, 4_000));
    assert_eq!((s.late, s.forgotten, s.evicted), (0, 0, 0));
}

/// The same with many keys at once: 400 counter frames, each its own content, stamped 100 µs
/// apart, handed over 150 ms later by port 0 and 10 ms after that by port 1. Each finds its twin
/// among the records: every occurrence delivered once. (Kept from their stamps, the copies
/// would be forgotten as they arrived and their twins left to the memory of forgotten keys,
/// whose sets of two lines do not hold 400 keys: some would be delivered twice.)
#[test]
fn a_receiver_held_up_as_a_whole_delivers_many_keys_once() {
    let mut m: Merger<1024> = Merger::with_horizon(W, Duration::from_millis(50));
    let counter = |k: u64| Frame::from_array(Id::Standard(0x281), (k as u32).to_le_bytes());
    for (p, handed) in [(0, ms(150)), (1, ms(160))] {
        for k in 0..400u64 {
            arr(
                &mut m,
                handed + Duration::from_micros(k),
                t(100 * k),
                p,
                &counter(k),
            );
        }
    }
    let s = m.stats();
    assert_eq!((s.delivered, s.duplicates, s.late), (400, 400, 0));
    assert_eq!((s.forgotten, s.evicted), (0, 0));
}

/// A receiver held up as a whole, and a heartbeat's repeat 3 ms after it that only port 1
/// carried (port 0's bus missed it): port 1's first copy finds its twin held, the repeat none,
/// and is delivered. (Kept from its stamp, port 0's copy would be forgotten before port 1's
/// came, and both of those taken for late twins of it: an occurrence lost.)
#[test]
fn a_repeat_one_bus_missed_behind_a_receiver_held_up_as_a_whole_is_delivered() {
    let mut m: Merger<64> = Merger::with_horizon(W, Duration::from_millis(50));
    let hb = f(0x70, 5);
    let got = [(150, 0, 0), (160, 0, 1), (160, 3, 1)]
        .map(|(now, at, p)| arr(&mut m, ms(now), ms(at), p, &hb));
    assert_eq!(
        got,
        [Verdict::Deliver, Verdict::Duplicate, Verdict::Deliver]
    );
    assert_eq!(m.stats().delivered, 2);
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
    // Horizon 80 ms: records of port 0 from 70 ms before a copy on are all still held.
    arr(&mut m, ms(0), ms(0), 0, &f(1, 1));
    arr(&mut m, ms(5), ms(5), 0, &f(2, 2));
    arr(&mut m, ms(95), ms(95), 0, &f(4, 4));
    // A frame queued before the fault, flushed by the repaired bus: port 0 passed its time,
    // and its twin may be one the merger no longer holds.
    assert_eq!(u(&mut m, ms(95), ms(3), &f(7, 7)), Verdict::Unproven);
    // Its reader 60 ms behind: port 0's records of that time are all held, and hold no twin
    // (the other bus did not carry it).
    assert_eq!(u(&mut m, ms(95), ms(35), &f(8, 8)), Verdict::Deliver);
    // A twin is still a twin.
    assert_eq!(u(&mut m, ms(95), ms(95), &f(4, 4)), Verdict::Duplicate);
    // Port 0 falls silent at 95: what port 1 carries from then on is delivered at once.
    assert_eq!(u(&mut m, ms(96), ms(96), &f(3, 3)), Verdict::Deliver);
    assert_eq!(u(&mut m, ms(97), ms(97), &f(3, 3)), Verdict::Deliver);
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
#[cfg(feature = "alloc")]
fn a_port_on_time_after_a_record_measures_no_lag_from_it() {
    // A layer that starts between a frame's two copies: port 0's copy of the cyclic frame 1
    // (its port 1 copy came before the start) is the first; port 1 then meets a fresh twin on
    // time (frame 2, no lag there), and its copy of frame 1's next occurrence, 15 ms after
    // port 0's, is no late sample: a port hands its copies over in order, and it did not lag
    // after the record's time.
    let mut m: Merger<64> = Merger::new(W);
    let a =
        |m: &mut Merger<64>, now, at, p, fr: &Frame| m.arrive_at(now, at, p, fr, Trust::Trusted);
    a(&mut m, ms(2), ms(2), 0, &f(1, 1));
    a(&mut m, ms(3), ms(3), 0, &f(2, 2));
    assert_eq!(a(&mut m, ms(3), ms(3), 1, &f(2, 2)).0, Verdict::Duplicate);
    assert_eq!(
        a(&mut m, ms(17), ms(17), 1, &f(1, 1)),
        (Verdict::Deliver, None)
    );
    // Without the twin on time, the same copy is a late sample.
    let mut m: Merger<64> = Merger::new(W);
    a(&mut m, ms(2), ms(2), 0, &f(1, 1));
    a(&mut m, ms(3), ms(3), 1, &f(3, 3));
    assert_eq!(
        a(&mut m, ms(17), ms(17), 1, &f(1, 1)),
        (
            Verdict::Deliver,
            Some(Sample {
                skew: 15_000,
                late: true
            })
        )
    );
}

#[test]
fn a_record_made_before_the_correction_changed_measures_no_lag() {
    let mut m: Merger<64> = Merger::new(W);
    let a =
        |m: &mut Merger<64>, now, at, p, fr: &Frame| m.arrive_at(now, at, p, fr, Trust::Trusted);
    // Port 1's reader runs 20 ms behind. Port 0 hands over two fresh frames at 0 and 1 ms;
    // at 3 ms the layer corrects port 0's stamps by 6 ms (port 0 is found to lag).
    a(&mut m, ms(0), ms(0), 0, &f(1, 1));
    a(&mut m, ms(1), ms(1), 0, &f(2, 2));
    a(&mut m, ms(3), ms(3), 0, &f(9, 9));
    m.shift(0, 6_000);
    a(&mut m, ms(10), ms(4), 0, &f(3, 3));
    // Port 1's copies of the two frames, handed over after the change, are matched; their
    // records were stamped with the old correction, so they measure nothing: taken, they
    // would show the 6 ms already corrected once more.
    assert_eq!(
        a(&mut m, ms(20), ms(6), 1, &f(1, 1)),
        (Verdict::Duplicate, None)
    );
    assert_eq!(
        a(&mut m, ms(21), ms(7), 1, &f(2, 2)),
        (Verdict::Duplicate, None)
    );
    // A record made after the change (port 0's copy, handed over at 10 ms) measures again.
    assert_eq!(
        a(&mut m, ms(22), ms(8), 1, &f(3, 3)),
        (
            Verdict::Duplicate,
            Some(Sample {
                skew: 4_000,
                late: false
            })
        )
    );
}

#[test]
fn a_repeat_a_late_reader_still_holds_back_measures_no_lag() {
    // The layer's timing: window 5 ms, horizon 80 ms. Two unchanged TPDOs every 10 ms; port
    // 1's reader hands its copies over 71 ms late (stamps on time); bus 0 is back at 336 ms
    // after an outage. Port 0's first copies of the TPDOs look fresh by what has arrived (port
    // 1 has shown copies only up to 269 ms, the last one 80.1 ms before), but port 1 still
    // holds their repeats: a copy of port 1 stamped 70 ms before one of port 0 is no twin
    // lagging 70 ms, and nothing here is a lag (taken for one, it had port 1's copies of 270
    // to 330 ms, which bus 0 never carried, matched with port 0's of 340 to 400 and dropped).
    let mut m: Merger<256> =
        Merger::with_horizon(Duration::from_millis(5), Duration::from_millis(80));
    let pdos = [f(0x190, 0xA5), f(0x191, 0xA5)];
    let hb = f(0x77A, 5);
    // (handed over, stamp, port, frame)
    let mut arrivals = vec![(ms(336), ms(336), 0, hb)];
    for k in 0..60u64 {
        for (i, pdo) in pdos.iter().enumerate() {
            let at = ms(10 * k) + Duration::from_micros(100 + 60 * i as u64);
            arrivals.push((at + Duration::from_millis(71), at, 1, *pdo));
            // Bus 0 carries it 100 µs later (arbitration).
            let at0 = at + Duration::from_micros(100);
            if at0 >= ms(336) {
                arrivals.push((at0, at0, 0, *pdo));
            }
        }
    }
    arrivals.sort_by_key(|a| a.0);
    for (now, at, p, fr) in arrivals {
        let (v, sample) = m.arrive_at(now, at, p, &fr, Trust::Trusted);
        assert_eq!(
            sample.filter(|s| s.late || s.skew != 0),
            None,
            "{fr:?} at {at} on {p}: {v:?}"
        );
    }
    // Every occurrence once.
    assert_eq!(m.stats().delivered, 121);
}

#[test]
fn a_frame_one_bus_missed_behind_a_late_reader_measures_no_lag() {
    // Window 5 ms, horizon 80 ms. A heartbeat every 20 ms with a new state from 349 ms on, on
    // bus 0 only until its sender's port on bus 1 is back (409 ms); port 0's reader hands its
    // copies over 52 ms late; port 1 also hears a SYNC every 10 ms. Port 1's copy of 409 ms
    // comes before port 0's of 369 and 389 ms: the record of 349 ms is no lagging twin of it
    // (port 0 has not handed over what it holds up to 409 ms yet), and no lag shows.
    let mut m: Merger<256> =
        Merger::with_horizon(Duration::from_millis(5), Duration::from_millis(80));
    let (hb, sync) = (f(0x711, 0x7F), Frame::from_array(Id::Standard(0x80), []));
    // (handed over, stamp, port, frame)
    let mut arrivals = vec![];
    for k in 0..20u64 {
        let at = ms(300 + 10 * k);
        arrivals.push((at + Duration::from_millis(52), at, 0, sync));
        arrivals.push((at, at, 1, sync));
    }
    for k in 0..6u64 {
        let at = ms(349 + 20 * k);
        arrivals.push((at + Duration::from_millis(52), at, 0, hb));
        if at >= ms(409) {
            arrivals.push((at, at, 1, hb));
        }
    }
    arrivals.sort_by_key(|a| a.0);
    for (now, at, p, fr) in arrivals {
        let (v, sample) = m.arrive_at(now, at, p, &fr, Trust::Trusted);
        assert_eq!(
            sample.filter(|s| s.late),
            None,
            "{fr:?} at {at} on {p}: {v:?}"
        );
    }
    assert_eq!(m.stats().delivered, 20 + 6);
}

#[test]
fn a_step_back_keeps_what_each_record_has_left() {
    let mut m: Merger<16> = Merger::new(W);
    arr(&mut m, ms(1_000), ms(1_000), 0, &f(1, 1));
    m.step_back(Duration::from_millis(990));
    assert_eq!(arr(&mut m, ms(15), ms(15), 1, &f(1, 1)), Verdict::Duplicate);
}

/// A record stamped long before it was handed over keeps the horizon from its hand-over through
/// a step back that puts its stamp before the new origin.
#[test]
fn a_step_back_keeps_what_a_late_record_has_left() {
    let mut m: Merger<16> = Merger::with_horizon(W, Duration::from_millis(50));
    // Stamped at 100 ms, handed over at 1 s: kept until 1.05 s.
    arr(&mut m, ms(1_000), ms(100), 0, &f(1, 1));
    m.step_back(Duration::from_millis(990));
    // Its stamp on the origin, its hand-over at 10 ms: kept until 60 ms.
    m.expire(ms(59));
    assert_eq!(m.unmatched(&f(1, 1)), Some((0, 1)));
    m.expire(ms(60));
    assert_eq!(m.unmatched(&f(1, 1)), None);
}

#[test]
fn a_bad_port_is_delivered_and_counted() {
    let mut m: Merger<16> = Merger::new(W);
    assert_eq!(m.arrive(t(0), 2, &f(1, 1)), Verdict::Deliver);
    assert_eq!(m.stats().bad_port, 1);
    assert!(m.is_empty());
}

#[test]
fn a_copy_stamped_before_a_jump_of_the_clock_is_known_for_a_late_twin_after_it() {
    let mut m: Merger<64> = Merger::new(W);
    let hour = 3_600_000;
    let hb = f(0x70, 5);
    // Port 1 delivers a heartbeat at 1 s; port 0's reader runs 30 ms behind.
    assert_eq!(arr(&mut m, ms(1000), ms(1000), 1, &hb), Verdict::Deliver);
    // The clock jumps an hour ahead: the record is forgotten (its horizon passed), and a frame
    // stamped after the jump comes first, far beyond what the merger's memory of keys counts.
    assert_eq!(
        arr(&mut m, ms(hour + 1010), ms(hour + 1010), 1, &f(0x71, 1)),
        Verdict::Deliver
    );
    assert_eq!(m.stats().forgotten, 1);
    // Port 0's copy of the heartbeat, stamped before the jump, handed over after it: late.
    assert_eq!(
        arr(&mut m, ms(hour + 1030), ms(1000), 0, &hb),
        Verdict::Late
    );
    // A copy of it stamped after the jump is a new occurrence.
    assert_eq!(
        arr(&mut m, ms(hour + 1040), ms(hour + 1040), 0, &hb),
        Verdict::Deliver
    );
}
