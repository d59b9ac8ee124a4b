//! Unit tests of the merger.

use super::*;
use duocan::Id;

fn f(id: u16, d: u8) -> Frame {
    Frame::from_array(Id::Standard(id), [d])
}
fn t(us: u64) -> Instant {
    Instant::from_micros(us)
}
const W: Duration = Duration::from_millis(10);

#[test]
fn twin_within_window_is_dropped_and_late_twin_is_delivered() {
    let mut m: Merger<16> = Merger::new(W);
    assert_eq!(m.arrive(t(0), 0, &f(1, 1)), Verdict::Deliver);
    assert_eq!(m.arrive(t(9_999), 1, &f(1, 1)), Verdict::Duplicate);
    assert_eq!(m.arrive(t(20_000), 0, &f(1, 1)), Verdict::Deliver);
    // Exactly one window later the record has expired: a new occurrence.
    assert_eq!(m.arrive(t(30_000), 1, &f(1, 1)), Verdict::Deliver);
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
    m.expire(t(10_000));
    assert_eq!((m.len(), m.keys()), (0, 0));
    // The index is empty again: everything can be re-inserted and found.
    for i in 0..12u8 {
        m.arrive(t(10_000), 0, &f(0x100, i));
    }
    for i in 0..12u8 {
        assert_eq!(m.arrive(t(10_001), 1, &f(0x100, i)), Verdict::Duplicate);
    }
}

#[test]
fn overflow_evicts_the_oldest_and_never_refuses_a_delivery() {
    let mut m: Merger<16> = Merger::new(W);
    assert_eq!(m.capacity(), 12);
    for i in 0..20u8 {
        assert_eq!(m.arrive(t(i as u64), 0, &f(0x100, i)), Verdict::Deliver);
    }
    assert_eq!(m.len(), 12);
    assert_eq!(m.stats().evicted, 8);
    // The twins of the kept ones are matched; those of the evicted ones (0..8) come back
    // as duplicates: one per eviction, no more.
    for i in 8..20u8 {
        assert_eq!(m.arrive(t(100), 1, &f(0x100, i)), Verdict::Duplicate);
    }
    for i in 0..8u8 {
        assert_eq!(m.arrive(t(100), 1, &f(0x100, i)), Verdict::Deliver);
    }
    assert_eq!(m.stats().evicted, 8);
}

#[test]
fn eviction_of_the_arrivals_own_key_keeps_the_slot() {
    let mut m: Merger<4> = Merger::new(W);
    assert_eq!(m.capacity(), 3);
    for i in 0..10 {
        assert_eq!(m.arrive(t(i), 0, &f(7, 7)), Verdict::Deliver);
    }
    assert_eq!(m.unmatched(&f(7, 7)), Some((0, 3)));
    assert_eq!(m.keys(), 1);
}

#[test]
fn match_only_consumes_but_never_records() {
    let mut m: Merger<16> = Merger::new(W);
    assert!(!m.match_only(t(0), 1, &f(1, 1)));
    assert!(m.is_empty());
    m.arrive(t(1), 0, &f(1, 1));
    assert!(m.match_only(t(2), 1, &f(1, 1)));
    assert_eq!(m.unmatched(&f(1, 1)), None);
}

const H: Duration = Duration::from_millis(80);

/// A merger with a horizon whose port 1 is known to lag (it matches late copies).
fn lagging_port_1() -> Merger<16> {
    let mut m = Merger::with_horizon(W, H);
    m.set_late_match(1, true);
    m
}
fn seen(lag_ms: u64) -> Option<Twin> {
    Some(Twin {
        lag: Some(Duration::from_millis(lag_ms)),
        late: true,
    })
}

#[test]
fn a_copy_after_the_window_is_seen_within_the_horizon_and_matched_once_its_port_lags() {
    let mut m: Merger<16> = Merger::with_horizon(W, H);
    assert_eq!(m.horizon(), H);
    assert!(!m.late_match(1));
    // Port 1 not known to lag: its copy 25 ms late is seen (and measured) but delivered, as
    // without a horizon; the late record is used up.
    assert_eq!(
        m.arrive_measured(t(0), 0, &f(1, 1)),
        (Verdict::Deliver, None)
    );
    assert_eq!(
        m.arrive_measured(t(25_000), 1, &f(1, 1)),
        (Verdict::Deliver, seen(25))
    );
    let s = m.stats();
    assert_eq!((s.expired, s.slipped, s.late, s.delivered), (1, 1, 0, 2));
    // Known to lag: the next one is matched.
    m.set_late_match(1, true);
    assert_eq!(m.arrive(t(40_000), 0, &f(1, 2)), Verdict::Deliver);
    assert_eq!(
        m.arrive_measured(t(65_000), 1, &f(1, 2)),
        (Verdict::Duplicate, seen(25))
    );
    assert_eq!((m.stats().late, m.stats().duplicates), (1, 1));
    // At the horizon it is gone: a copy 80 ms later is a new occurrence.
    assert_eq!(m.arrive(t(100_000), 0, &f(1, 3)), Verdict::Deliver);
    assert_eq!(m.arrive(t(180_000), 1, &f(1, 3)), Verdict::Deliver);
    assert_eq!(m.arrive(t(200_000), 0, &f(1, 4)), Verdict::Deliver);
    assert_eq!(m.arrive(t(279_999), 1, &f(1, 4)), Verdict::Duplicate);
    // Without a horizon (or one not beyond the window) nothing late is seen.
    let mut m: Merger<16> = Merger::with_horizon(W, W);
    assert_eq!(m.horizon(), Duration::ZERO);
    m.set_late_match(1, true);
    m.arrive(t(0), 0, &f(1, 1));
    assert_eq!(
        m.arrive_measured(t(25_000), 1, &f(1, 1)),
        (Verdict::Deliver, None)
    );
}

#[test]
fn the_lag_of_a_twin_is_exact_when_it_matched_the_only_pending_copy() {
    let mut m: Merger<16> = Merger::new(W);
    let twin = |m: &mut Merger<16>, us, frame| m.arrive_measured(t(us), 1, &frame).1.unwrap();
    m.arrive(t(1_000), 0, &f(1, 1));
    let one = twin(&mut m, 4_500, f(1, 1));
    assert_eq!(
        (one.lag, one.late),
        (Some(Duration::from_micros(3_500)), false)
    );
    // Two pending copies of one key: which one the twin is, is a convention; no figure.
    m.arrive(t(5_000), 0, &f(2, 2));
    m.arrive(t(6_000), 0, &f(2, 2));
    assert_eq!(twin(&mut m, 7_000, f(2, 2)).lag, None);
    assert_eq!(
        twin(&mut m, 8_000, f(2, 2)).lag,
        Some(Duration::from_millis(2))
    );
    // A clock that went backwards measures zero, not an hour.
    m.arrive(t(9_000), 0, &f(3, 3));
    assert_eq!(twin(&mut m, 8_500, f(3, 3)).lag, Some(Duration::ZERO));
}

#[test]
fn a_live_twin_comes_first_and_late_copies_are_taken_oldest_first() {
    let mut m = lagging_port_1();
    // Port 0 carries three copies of one frame; port 1 missed the first two.
    m.arrive(t(0), 0, &f(1, 1));
    m.arrive(t(20_000), 0, &f(1, 1));
    m.arrive(t(40_000), 0, &f(1, 1));
    // Its copy of the third comes in time: matched with the live record, not a late one.
    let (v, twin) = m.arrive_measured(t(41_000), 1, &f(1, 1));
    assert_eq!(v, Verdict::Duplicate);
    assert_eq!(
        twin,
        Some(Twin {
            lag: Some(Duration::from_millis(1)),
            late: false
        })
    );
    // Two more copies on port 1 with nothing live pending: the late ones, oldest first.
    assert_eq!(
        m.arrive_measured(t(45_000), 1, &f(1, 1)),
        (Verdict::Duplicate, seen(45))
    );
    assert_eq!(
        m.arrive_measured(t(46_000), 1, &f(1, 1)),
        (Verdict::Duplicate, seen(26))
    );
    // None left: a fourth is a first copy.
    assert_eq!(m.arrive(t(47_000), 1, &f(1, 1)), Verdict::Deliver);
    assert_eq!(m.stats().late, 2);
}

#[test]
fn late_records_live_behind_the_ring_until_new_arrivals_overwrite_them() {
    let mut m: Merger<16> = Merger::with_horizon(W, Duration::from_secs(1));
    m.set_late_match(1, true);
    // Six records on port 0 (ring positions 0..6), all left unmatched by the window.
    for i in 0..6u8 {
        m.arrive(t(i as u64), 0, &f(0x100, i));
    }
    m.expire(t(20_000));
    assert_eq!((m.len(), m.late_records()), (0, 6));
    assert_eq!(m.keys(), 6, "late records keep their key's slot");
    // Twelve copies of one other frame fill the ring from position 6 on: 6..16, then 0 and 1.
    for _ in 0..12 {
        m.arrive(t(30_000), 0, &f(0x300, 0));
    }
    assert_eq!((m.len(), m.late_records(), m.keys()), (12, 4, 5));
    // Records 2..6 are still there and matched late; 0 and 1 were overwritten: delivered
    // (asked for last: a delivery takes the next position, and the oldest record with it).
    for i in (0..6u8).rev() {
        let v = m.arrive(t(31_000), 1, &f(0x100, i));
        let want = if i >= 2 {
            Verdict::Duplicate
        } else {
            Verdict::Deliver
        };
        assert_eq!(v, want, "record {i}");
    }
    assert_eq!(m.stats().late, 4);
}

#[test]
fn a_new_key_takes_the_slot_of_the_oldest_late_record_when_the_table_is_three_quarters_full() {
    let mut m: Merger<16> = Merger::with_horizon(W, Duration::from_secs(1));
    m.set_late_match(1, true);
    for i in 0..12u8 {
        m.arrive(t(i as u64), 0, &f(0x100, i));
    }
    m.expire(t(20_000));
    assert_eq!((m.keys(), m.late_records()), (12, 12));
    // Three new keys: the three oldest late records give their slots back.
    for i in 0..3u8 {
        m.arrive(t(30_000), 0, &f(0x200, i));
    }
    assert_eq!((m.keys(), m.late_records()), (12, 9));
    for i in (0..12u8).rev() {
        let want = if i >= 3 {
            Verdict::Duplicate
        } else {
            Verdict::Deliver
        };
        assert_eq!(m.arrive(t(31_000), 1, &f(0x100, i)), want, "record {i}");
    }
}

#[test]
fn with_a_horizon_an_evicted_record_stays_matchable_behind_the_ring() {
    let mut m = lagging_port_1();
    for i in 0..12u8 {
        assert_eq!(m.arrive(t(i as u64), 0, &f(0x100, i)), Verdict::Deliver);
    }
    // Two more copies of the last frame: the ring is full, the two oldest records are evicted.
    m.arrive(t(12), 0, &f(0x100, 11));
    m.arrive(t(13), 0, &f(0x100, 11));
    assert_eq!(m.stats().evicted, 2);
    // The twins of all fourteen are matched: the two evicted ones as late records.
    for i in (0..12u8).chain([11, 11]) {
        assert_eq!(m.arrive(t(100), 1, &f(0x100, i)), Verdict::Duplicate, "{i}");
    }
    assert_eq!(m.stats().late, 2);
}

#[test]
fn a_port_that_cannot_deliver_twins_leaves_no_late_records() {
    let mut m = lagging_port_1();
    m.arrive(t(0), 0, &f(1, 1));
    // Port 1 fails: port 0's late copies are forgotten, and those arriving meanwhile not kept.
    m.keep_late(0, false, t(5_000));
    assert!(!m.keeps_late(0));
    m.arrive(t(6_000), 0, &f(1, 2));
    // Port 1 works again from 30 ms: only copies from then on become late records.
    m.keep_late(0, true, t(30_000));
    m.arrive(t(30_000), 0, &f(1, 3));
    assert_eq!(m.arrive(t(50_000), 1, &f(1, 1)), Verdict::Deliver);
    assert_eq!(m.arrive(t(50_000), 1, &f(1, 2)), Verdict::Deliver);
    assert_eq!(m.arrive(t(50_000), 1, &f(1, 3)), Verdict::Duplicate);
}

#[test]
fn match_only_takes_a_late_twin_only_on_a_lagging_port_and_clear_keeps_the_settings() {
    let mut m: Merger<16> = Merger::with_horizon(W, H);
    m.arrive(t(0), 0, &f(1, 1));
    assert!(!m.match_only(t(30_000), 1, &f(1, 1)));
    m.set_late_match(1, true);
    let twin = m.match_measured(t(30_000), 1, &f(1, 1));
    assert_eq!(twin, seen(30));
    assert!(!m.match_only(t(30_001), 1, &f(1, 1)));
    m.clear();
    assert_eq!((m.window(), m.horizon(), m.late_match(1)), (W, H, true));
    assert_eq!(m.stats().late, 1, "counters kept");
}

#[test]
fn late_copies_of_a_key_on_both_ports_keep_the_newer_side() {
    let mut m: Merger<16> = Merger::with_horizon(W, H);
    m.set_late_match(1, true);
    // Port 1 holds an unmatched copy (port 0 missed it); long after, past the horizon (but not
    // overwritten), port 0 holds one of the same frame.
    m.arrive(t(0), 1, &f(1, 1));
    m.expire(t(10_000));
    m.arrive(t(100_000), 0, &f(1, 1));
    m.expire(t(110_000));
    assert_eq!(m.late_records(), 1, "port 1's is given up");
    // Port 1's lagging twin of the newer copy is matched.
    assert_eq!(m.arrive(t(130_000), 1, &f(1, 1)), Verdict::Duplicate);
    assert_eq!(m.stats().late, 1);
}

#[test]
fn a_step_back_keeps_each_record_s_window_and_horizon() {
    const HOUR: Duration = Duration::from_secs(3600);
    let mut m: Merger<16> = Merger::with_horizon(W, Duration::from_millis(80));
    let t0 = Instant::ZERO + HOUR;
    assert_eq!(m.arrive(t0, 0, &f(1, 1)), Verdict::Deliver);
    assert_eq!(m.arrive(t0 + W, 0, &f(2, 1)), Verdict::Deliver);
    // The caller's clock steps back an hour 1 ms after the second arrival.
    m.step_back(HOUR - Duration::from_millis(1));
    // The first record left its window 10 ms after its arrival (now at 1 ms): its twin 30 ms
    // after it is late, seen as such, not matched in the window.
    let (v, twin) = m.arrive_measured(t(31_000), 1, &f(1, 1));
    assert_eq!(v, Verdict::Deliver);
    assert_eq!(
        twin,
        Some(Twin {
            lag: Some(Duration::from_millis(30)),
            late: true
        })
    );
    // The second one (now at 11 ms) is late too, and matched once its port may match late ones.
    m.set_late_match(1, true);
    assert_eq!(m.arrive(t(40_000), 1, &f(2, 1)), Verdict::Duplicate);
    assert_eq!(m.stats().late, 1);
}
