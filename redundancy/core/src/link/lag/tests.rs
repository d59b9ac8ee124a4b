//! The lag meter: samples that count, the correction, reports.

use super::*;

fn ms(x: u64) -> Duration {
    Duration::from_millis(x)
}
fn at(x: u64) -> Instant {
    Instant::from_millis(x)
}
fn meter() -> LagMeter {
    LagMeter::new(ms(10), ms(40), ms(100))
}
fn events(out: &mut Outbox) -> Vec<(Instant, LinkEventKind)> {
    core::iter::from_fn(|| out.pop_event())
        .map(|e| (e.at, e.kind))
        .collect()
}
fn matched(skew_ms: i64) -> Sample {
    Sample {
        skew: skew_ms * 1_000,
        late: false,
    }
}
fn late(skew_ms: i64) -> Sample {
    Sample {
        skew: skew_ms * 1_000,
        late: true,
    }
}

#[test]
fn ordinary_skew_is_no_lag_and_one_late_sample_is_not_enough() {
    let mut m = meter();
    let mut out = Outbox::new();
    assert_eq!(m.horizon(), ms(80));
    for t in 0..50 {
        assert!(!m.sample(
            at(t * 10),
            1,
            Sample {
                skew: 4_999,
                late: false
            },
            &mut out
        ));
    }
    assert_eq!((m.lag(1), m.window()), (Duration::ZERO, ms(10)));
    // One late sample (a missed frame whose repeat came first looks like this): held only.
    assert!(!m.sample(at(530), 0, late(30), &mut out));
    assert_eq!(m.lag(0), Duration::ZERO);
    // A second one that disagrees replaces it; one that agrees, in time, sets the lag.
    assert!(!m.sample(at(540), 0, late(20), &mut out));
    assert!(
        !m.sample(at(700), 0, late(20), &mut out),
        "too long after the first"
    );
    assert!(m.sample(at(720), 0, late(24), &mut out));
    assert_eq!(
        (m.lag(0), m.lag(1), m.window()),
        (ms(24), Duration::ZERO, ms(34))
    );
    assert_eq!(
        events(&mut out),
        [(
            at(720),
            LinkEventKind::Lag {
                port: 0,
                lag: ms(24),
                window: ms(34)
            }
        )]
    );
}

#[test]
fn matched_twins_start_a_correction_only_near_the_windows_edge() {
    let mut m = meter();
    let mut out = Outbox::new();
    // Twins within three quarters of the window, however skewed and however often they
    // agree: the window takes them as they are, no correction (a skew that changes from frame
    // to frame, taken for a lag, put twins beyond the window once the other bus was the late
    // one).
    for k in 0..4 {
        assert!(!m.sample(at(k), 1, matched(7), &mut out));
    }
    assert_eq!(m.lag(1), Duration::ZERO);
    // Nearer the edge (a lag that drifts out of the window): corrected before it leaves.
    let mut near = meter();
    assert!(!near.sample(at(0), 1, matched(8), &mut out));
    assert!(near.sample(at(1), 1, matched(8), &mut out));
    assert_eq!(near.lag(1), ms(8));
    out = Outbox::new();
    // A lag beyond the window (two late samples) is corrected...
    assert!(!m.sample(at(10), 1, late(12), &mut out));
    assert!(m.sample(at(11), 1, late(12), &mut out));
    assert_eq!(m.lag(1), ms(12));
    assert_eq!(m.correct(1, at(100)), at(88));
    assert_eq!(m.correct(0, at(100)), at(100));
    // ...and followed by matched twins from then on: a lag that grows slowly, another 6 ms.
    assert!(!m.sample(at(20), 1, matched(6), &mut out));
    assert!(m.sample(at(21), 1, matched(6), &mut out));
    assert_eq!(m.lag(1), ms(18));
    // The lag shrinks again: port 1's corrected copies come early.
    assert!(!m.sample(at(30), 1, matched(-9), &mut out));
    assert!(m.sample(at(31), 1, matched(-9), &mut out));
    assert_eq!(m.lag(1), ms(9));
    assert!(!m.sample(at(40), 1, matched(-9), &mut out));
    assert!(m.sample(at(41), 1, matched(-9), &mut out));
    assert_eq!(m.lag(1), Duration::ZERO);
    assert_eq!(
        events(&mut out),
        [
            (
                at(11),
                LinkEventKind::Lag {
                    port: 1,
                    lag: ms(12),
                    window: ms(22)
                }
            ),
            (
                at(21),
                LinkEventKind::Lag {
                    port: 1,
                    lag: ms(18),
                    window: ms(28)
                }
            ),
            (
                at(31),
                LinkEventKind::Lag {
                    port: 1,
                    lag: ms(9),
                    window: ms(19)
                }
            ),
            (at(41), LinkEventKind::LagCleared { port: 1 }),
        ]
    );
}

#[test]
fn the_lag_changes_sides_and_stays_within_the_horizon() {
    let mut m = meter();
    let mut out = Outbox::new();
    m.sample(at(0), 0, late(30), &mut out);
    m.sample(at(1), 0, late(30), &mut out);
    assert!(m.lagging(0) && !m.lagging(1));
    // Port 1's copies, corrected, come 60 ms after port 0's: port 1 lags 30 ms now.
    m.sample(at(2), 1, late(60), &mut out);
    m.sample(at(3), 1, late(60), &mut out);
    assert_eq!((m.lag(0), m.lag(1)), (Duration::ZERO, ms(30)));
    // Far beyond the horizon: held at it, and beyond the maximum.
    m.sample(at(4), 1, late(500), &mut out);
    m.sample(at(5), 1, late(500), &mut out);
    assert_eq!(m.lag(1), ms(80));
    assert!(m.beyond(1) && !m.beyond(0));
}

#[test]
fn a_copy_stamped_before_its_twin_only_shrinks_this_ports_own_correction() {
    let mut m = meter();
    let mut out = Outbox::new();
    // Port 0's copies come after port 1's stamped 40 ms later, twice: port 0's reader runs
    // behind and bus 1 missed two frames (their senders' ports back only for the repeat).
    // Port 0 has no correction to shrink: no lag of port 1.
    assert!(!m.sample(at(0), 0, late(-40), &mut out));
    assert!(!m.sample(at(1), 0, late(-40), &mut out));
    assert_eq!((m.lag(0), m.lag(1)), (Duration::ZERO, Duration::ZERO));
    // Port 1 corrected by 30 ms; its copies now come 40 ms early: the correction goes, and
    // port 0 is not made to lag for the rest.
    m.sample(at(10), 1, late(30), &mut out);
    assert!(m.sample(at(11), 1, late(30), &mut out));
    assert_eq!(m.lag(1), ms(30));
    assert!(!m.sample(at(20), 1, late(-40), &mut out));
    assert!(m.sample(at(21), 1, late(-40), &mut out));
    assert_eq!((m.lag(0), m.lag(1)), (Duration::ZERO, Duration::ZERO));
}

#[test]
fn a_step_back_keeps_a_held_sample_waiting() {
    let mut m = meter();
    let mut out = Outbox::new();
    m.sample(at(1_000), 1, late(20), &mut out);
    m.step_back(ms(900));
    assert!(m.sample(at(150), 1, late(20), &mut out));
    assert_eq!(m.lag(1), ms(20));
}
