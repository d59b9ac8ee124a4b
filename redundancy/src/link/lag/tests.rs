//! The lag meter: samples, periods, windows, distrust, reports.

use super::*;
use duocan::Frame;

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
fn lag(port: u8, lag: Duration, window: Duration) -> LinkEventKind {
    LinkEventKind::Lag { port, lag, window }
}

#[test]
fn ordinary_skew_is_no_lag_and_one_sample_is_not_enough() {
    let mut m = meter();
    let mut out = Outbox::new();
    assert_eq!(m.horizon(), ms(80));
    for t in 0..50 {
        assert!(!m.sample(at(t * 10), 1, Duration::from_micros(4_999), &mut out));
    }
    assert_eq!((m.lag(1), m.window()), (Duration::ZERO, ms(10)));
    assert_eq!(m.poll_timeout(), None, "nothing held, no timer");
    // One large sample (a missed frame whose repeat came first looks like this): held, not used.
    assert!(!m.sample(at(530), 0, ms(30), &mut out));
    assert_eq!((m.lag(0), m.window()), (Duration::ZERO, ms(10)));
    assert!(events(&mut out).is_empty());
    // Forgotten when its period and the next one are over.
    assert_eq!(m.poll_timeout(), Some(at(600)));
    assert_eq!(m.handle_timeout(at(600), &mut out), None);
    assert_eq!(m.poll_timeout(), Some(at(700)));
    assert_eq!(m.handle_timeout(at(700), &mut out), None);
    assert_eq!(m.poll_timeout(), None);
    // A second one within the next period would have counted.
    m.sample(at(710), 0, ms(30), &mut out);
    assert!(m.sample(at(850), 0, ms(20), &mut out));
    assert_eq!((m.lag(0), m.window()), (ms(20), ms(30)));
}

#[test]
fn a_twin_of_a_frame_older_than_one_the_port_already_had_is_no_lag() {
    let mut m = meter();
    let mut out = Outbox::new();
    // Port 0 leads: port 1's twins of its copies say port 0 had the frames of 100..=140 ms.
    for t in [100, 110, 120, 130, 140] {
        m.sample(
            at(t) + Duration::from_micros(300),
            1,
            Duration::from_micros(300),
            &mut out,
        );
    }
    // Port 0 then matches a copy of 131 ms that port 1 got 20 ms ago: a repeat paired one
    // occurrence off (its own copy was missed), not a lag. Twice: still nothing.
    assert!(!m.sample(at(151), 0, ms(20), &mut out));
    assert!(!m.sample(at(152), 0, ms(20), &mut out));
    assert_eq!(m.lag(0), Duration::ZERO);
    assert_eq!(m.poll_timeout(), None);
    // Up to half the skew window of reordering between the buses is allowed: copies of 136 ms,
    // 4.3 ms before the newest frame port 0 is known to have had.
    assert!(!m.sample(at(150), 0, ms(14), &mut out));
    assert!(m.sample(at(151), 0, ms(15), &mut out));
    assert_eq!((m.lag(0), m.window()), (ms(14), ms(24)));
}

#[test]
fn the_lag_is_the_second_largest_sample_of_two_periods_and_the_window_follows_it() {
    let mut m = meter();
    let mut out = Outbox::new();
    m.sample(at(10), 1, Duration::from_micros(12_400), &mut out);
    assert!(m.sample(at(20), 1, Duration::from_micros(12_300), &mut out));
    // Rounded down to whole ms on top of the skew window.
    assert_eq!(m.window(), ms(22));
    assert_eq!(m.port_window(1), ms(22));
    assert_eq!(m.port_window(0), ms(10));
    // It grows at once with a second larger sample; smaller ones do not lower it.
    m.sample(at(30), 1, ms(18), &mut out);
    assert_eq!(m.lag(1), Duration::from_micros(12_400));
    m.sample(at(40), 1, ms(19), &mut out);
    assert_eq!((m.lag(1), m.window()), (ms(18), ms(28)));
    m.sample(at(50), 1, ms(6), &mut out);
    assert_eq!(m.lag(1), ms(18));
    assert_eq!(
        events(&mut out),
        [
            (at(20), lag(1, Duration::from_micros(12_300), ms(22))),
            (at(40), lag(1, ms(18), ms(28))),
        ]
    );
    // The lag goes away: the samples of period [0, 100) count until 200, then it is cleared,
    // at exactly that instant.
    m.sample(at(150), 1, Duration::from_micros(100), &mut out);
    assert_eq!(m.lag(1), ms(18));
    assert_eq!(m.poll_timeout(), Some(at(100)));
    assert_eq!(
        m.handle_timeout(at(100), &mut out),
        None,
        "still the previous period"
    );
    assert_eq!(m.poll_timeout(), Some(at(200)));
    assert_eq!(m.handle_timeout(at(230), &mut out), Some(at(200)));
    assert_eq!(m.window(), ms(10));
    assert_eq!(
        events(&mut out),
        [(at(200), LinkEventKind::LagCleared { port: 1 })]
    );
    assert_eq!(m.poll_timeout(), None);
}

#[test]
fn beyond_the_maximum_a_port_is_distrusted_and_trusted_again_when_its_lag_is_within() {
    let mut m = meter();
    let mut out = Outbox::new();
    // 30 ms: window 40, the maximum: trusted.
    m.sample(at(40), 0, ms(30), &mut out);
    m.sample(at(50), 0, ms(30), &mut out);
    assert_eq!((m.window(), m.distrusted(0)), (ms(40), false));
    // 31 ms: beyond. Its window still covers the lag, up to the horizon (80 ms).
    m.sample(at(60), 0, ms(31), &mut out);
    assert!(m.sample(at(70), 0, ms(31), &mut out));
    assert_eq!((m.window(), m.distrusted(0)), (ms(41), true));
    m.sample(at(110), 0, ms(75), &mut out);
    m.sample(at(120), 0, ms(75), &mut out);
    assert_eq!(m.window(), ms(80));
    // The other port cannot be distrusted as well: it keeps the maximum. (Port 0's twins say
    // port 1 had the frames port 0 got up to 120 ms: port 1's twins are of copies from 155 ms.)
    m.sample(at(190), 1, ms(35), &mut out);
    m.sample(at(195), 1, ms(40), &mut out);
    assert_eq!((m.port_window(1), m.distrusted(1)), (ms(40), false));
    assert_eq!(
        events(&mut out),
        [
            (at(50), lag(0, ms(30), ms(40))),
            (at(70), lag(0, ms(31), ms(41))),
            (at(120), lag(0, ms(75), ms(80))),
            (at(195), lag(1, ms(35), ms(40))),
        ]
    );
    // Nothing more: at 200 the samples of [0, 100) are forgotten (port 0 still has those of
    // [100, 200)); at 300 all are, and both ports clear, port 0 trusted again.
    assert_eq!(m.handle_timeout(at(200), &mut out), None);
    assert!(m.distrusted(0));
    assert_eq!(m.handle_timeout(at(300), &mut out), Some(at(300)));
    assert!(!m.distrusted(0));
    assert_eq!(
        events(&mut out),
        [
            (at(300), LinkEventKind::LagCleared { port: 0 }),
            (at(300), LinkEventKind::LagCleared { port: 1 }),
        ]
    );
}

#[test]
fn the_other_port_is_silent_once_the_lagging_one_has_caught_up_with_it_or_after_its_window() {
    let mut m = meter();
    let mut out = Outbox::new();
    m.sample(at(100), 1, ms(50), &mut out);
    m.sample(at(120), 1, ms(50), &mut out);
    assert!(m.distrusted(1));
    assert_eq!(m.port_window(1), ms(60));
    // Port 1's last twin was port 0's copy of 70 ms; port 0 heard something at 80 ms: not silent.
    assert!(!m.other_silent(at(125), 1, Some(at(80))));
    // Port 0 heard nothing after the copy port 1 caught up with: silent, once it has been quiet
    // for half a skew window.
    assert!(m.other_silent(at(125), 1, Some(at(70))));
    assert!(!m.other_silent(at(74), 1, Some(at(70))));
    assert!(m.other_silent(at(75), 1, Some(at(70))));
    // Nothing heard for the window: silent whatever the twins.
    assert!(!m.other_silent(at(139), 1, Some(at(80))));
    assert!(m.other_silent(at(140), 1, Some(at(80))));
    assert!(m.other_silent(at(125), 1, None));
}

#[test]
fn a_step_back_moves_the_periods_and_a_jump_ahead_costs_three_rounds_at_most() {
    const HOUR: Duration = Duration::from_secs(3600);
    let mut m = meter();
    let mut out = Outbox::new();
    let t0 = Instant::ZERO + HOUR;
    // Periods of 100 ms: the samples fall in the one ending at 1 h + 100 ms.
    m.sample(t0 + ms(10), 1, ms(20), &mut out);
    assert!(m.sample(t0 + ms(30), 1, ms(20), &mut out));
    assert_eq!(m.poll_timeout(), Some(t0 + ms(100)));
    // At 1 h + 30 ms the clock steps back to 80 ms: the period still has 70 ms to run.
    m.step_back(HOUR - ms(50));
    assert_eq!(m.poll_timeout(), Some(at(150)));
    m.handle_timeout(at(150), &mut out);
    assert_eq!(m.lag(1), ms(20), "held for the next period");
    // An hour ahead: forgotten at the end of the next period, once.
    events(&mut out);
    let ahead = at(150) + HOUR;
    assert_eq!(m.handle_timeout(ahead, &mut out), Some(at(250)));
    assert_eq!(
        events(&mut out),
        [(at(250), LinkEventKind::LagCleared { port: 1 })]
    );
    assert_eq!(m.poll_timeout(), None);
    // New samples there, on the same grid; at the end of time nothing stays due.
    m.sample(ahead + ms(10), 1, ms(20), &mut out);
    m.sample(ahead + ms(20), 1, ms(20), &mut out);
    assert_eq!(m.poll_timeout(), Some(ahead + ms(100)));
    m.handle_timeout(Instant::MAX, &mut out);
    assert_eq!(m.poll_timeout(), None);
}

fn frame(id: u16, b: u8) -> Frame {
    Frame::from_array(duocan::Id::Standard(id), [b])
}

#[test]
fn a_copy_on_the_other_port_soon_after_withdraws_the_sample_of_its_repeat() {
    let mut m = meter();
    let mut out = Outbox::new();
    let (normal, inverted) = (frame(0x103, 1), frame(0x104, 0xFE));
    // Port 0 back from an outage: its copies of two unchanged repeats find port 1's copies of
    // the occurrences 60 ms earlier. Two samples: a lag, known at once, beyond the maximum.
    assert!(!m.sample_frame(at(521), 0, ms(60), &normal, &mut out));
    assert!(m.sample_frame(at(521), 0, ms(60), &inverted, &mut out));
    assert_eq!((m.lag(0), m.distrusted(0)), (ms(60), true));
    assert!(m.withdrawable(0) && !m.withdrawable(1));
    // Port 1's copy of another frame, or one of them on the same port, withdraws nothing.
    assert!(!m.contradicted(at(521), 1, &frame(0x702, 5), &mut out));
    assert!(!m.contradicted(at(521), 0, &normal, &mut out));
    // Port 1's copies of the same frames arrive with them: no lag at all.
    assert!(m.contradicted(at(521) + Duration::from_micros(70), 1, &normal, &mut out));
    assert_eq!(
        (m.lag(0), m.distrusted(0), m.window()),
        (Duration::ZERO, false, ms(10))
    );
    assert!(
        !m.contradicted(at(522), 1, &inverted, &mut out),
        "nothing changes any more"
    );
    assert!(!m.withdrawable(0));
    assert_eq!(
        events(&mut out),
        [
            (at(521), lag(0, ms(60), ms(70))),
            (
                at(521) + Duration::from_micros(70),
                LinkEventKind::LagCleared { port: 0 }
            ),
        ]
    );
    assert_eq!(m.poll_timeout(), None, "no sample held");
}

#[test]
fn a_copy_half_a_skew_window_later_withdraws_nothing() {
    let mut m = meter();
    let mut out = Outbox::new();
    let f = frame(0x181, 7);
    m.sample_frame(at(100), 1, ms(15), &f, &mut out);
    m.sample_frame(at(110), 1, ms(15), &frame(0x182, 1), &mut out);
    assert_eq!(m.lag(1), ms(15));
    // 5 ms after: the skew it would mean is not ordinary; the sample stays, and is forgotten.
    assert!(!m.contradicted(at(105), 0, &f, &mut out));
    assert_eq!(m.lag(1), ms(15));
    assert!(!m.contradicted(at(116), 0, &frame(0x182, 1), &mut out));
    assert!(!m.withdrawable(1), "both too old now");
}

#[test]
fn withdrawing_a_repeat_keeps_the_lag_its_changing_frames_show() {
    let mut m = meter();
    let mut out = Outbox::new();
    let repeat = frame(0x281, 0);
    // A real 40 ms lag, shown by two changing frames; then a frame repeating every 20 ms is
    // paired one occurrence off, with every changing one.
    m.sample_frame(at(10), 1, ms(40), &frame(0x181, 0xA0), &mut out);
    m.sample_frame(at(20), 1, ms(40), &frame(0x181, 0xA1), &mut out);
    assert_eq!((m.lag(1), m.distrusted(1)), (ms(40), true));
    for (i, t) in [30u64, 50, 70].into_iter().enumerate() {
        m.sample_frame(at(t), 1, ms(40), &frame(0x181, i as u8), &mut out);
        m.sample_frame(at(t), 1, ms(40), &repeat, &mut out);
        m.contradicted(at(t + 1), 0, &repeat, &mut out);
        assert_eq!((m.lag(1), m.distrusted(1)), (ms(40), true), "at {t} ms");
    }
    // The period ends: the samples of the changing frames carry it.
    m.handle_timeout(at(100), &mut out);
    m.sample_frame(at(110), 1, ms(40), &repeat, &mut out);
    m.contradicted(at(111), 0, &repeat, &mut out);
    assert_eq!(m.lag(1), ms(40));
}

#[test]
fn a_port_remembers_its_newest_samples_and_the_clock_steps_back_with_them() {
    let mut m = meter();
    let mut out = Outbox::new();
    for i in 0..5u8 {
        m.sample_frame(
            at(200),
            0,
            ms(20),
            &frame(0x100 + u16::from(i), i),
            &mut out,
        );
    }
    // Four held: the oldest one (0x100) was replaced and cannot be withdrawn.
    assert!(!m.contradicted(at(201), 1, &frame(0x100, 0), &mut out));
    m.step_back(ms(150));
    assert!(m.withdrawable(0));
    for i in 1..5u8 {
        m.contradicted(at(52), 1, &frame(0x100 + u16::from(i), i), &mut out);
    }
    assert!(!m.withdrawable(0));
}
