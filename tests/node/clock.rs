//! The clock contract (`duocan::frame::instant`): a time far ahead, a step back and the end of
//! time, fed to nodes on a zero-latency wire. Every figure is exact: a step back moves every time a
//! node holds back by the size of the step.

use crate::common::{node, Wire};
use duocan::node::NodeEventKind as K;
use duocan::od::comm;
use duocan::{Duration, Instant, Machine};
use proptest::prelude::*;

const MASTER: usize = 0;
const SLAVE: usize = 1;
const HOUR: Duration = Duration::from_secs(3600);

fn ms(v: u64) -> Instant {
    Instant::from_millis(v)
}

/// Master 1 produces SYNC every 10 ms and a heartbeat every 100 ms and consumes the slave's (250
/// ms); slave 5 beats every 100 ms. Booted at 0, run to 1 s.
fn running() -> Wire {
    let mut w = Wire::new(vec![node(1, true), node(5, false)]);
    let m = &mut w.nodes[MASTER];
    m.set(ms(0), comm::SYNC_COB_ID, 0, 0x4000_0080u32).unwrap();
    m.set(ms(0), comm::SYNC_PERIOD, 0, 10_000u32).unwrap();
    m.set(ms(0), comm::HEARTBEAT_PRODUCER, 0, 100u16).unwrap();
    m.set(ms(0), comm::HEARTBEAT_CONSUMER, 1, (5u32 << 16) | 250)
        .unwrap();
    w.nodes[SLAVE]
        .set(ms(0), comm::HEARTBEAT_PRODUCER, 0, 100u16)
        .unwrap();
    w.boot_all();
    w.run_until(ms(1000));
    w
}

/// When node `i` sent on `raw` within `(from, to]`.
fn sent_between(w: &Wire, i: usize, raw: u16, from: Instant, to: Instant) -> Vec<Instant> {
    w.sent(i, raw)
        .into_iter()
        .map(|(t, _)| t)
        .filter(|t| *t > from && *t <= to)
        .collect()
}

/// One `handle_timeout` an hour ahead, on the master only (what a glitching timer does).
fn glitch_master(w: &mut Wire) -> Instant {
    let saved = w.now;
    let ahead = saved + HOUR;
    w.now = ahead;
    w.nodes[MASTER].handle_timeout(ahead);
    w.flush();
    w.now = saved;
    ahead
}

#[test]
fn a_glitch_an_hour_ahead_costs_one_period_when_the_driver_reports_the_step_back() {
    let mut w = running();
    let glitch = glitch_master(&mut w);
    // In the glitch the master sent what was due then, once each (not an hour of backlog).
    let at_glitch = |raw| {
        w.sent(MASTER, raw)
            .iter()
            .filter(|(t, _)| *t == glitch)
            .count()
    };
    assert_eq!((at_glitch(0x701), at_glitch(0x080)), (1, 1));
    // The clock is back at 1 s + 1 ms; the driver says so once.
    let back = ms(1001);
    w.now = back;
    w.nodes[MASTER].handle_timeout(back);
    w.flush();
    w.run_until(ms(2001));
    // The heartbeat sent in the glitch was due 100 ms later: 100 ms after the step back.
    let hb = sent_between(&w, MASTER, 0x701, back, ms(2001));
    assert_eq!(hb.first(), Some(&ms(1101)));
    assert_eq!(hb.len(), 10, "every 100 ms from 1.101 s to 2.001 s: {hb:?}");
    let sync = sent_between(&w, MASTER, 0x080, back, ms(2001));
    assert_eq!(sync.first(), Some(&ms(1011)));
    assert_eq!(sync.len(), 100, "every 10 ms again");
}

#[test]
fn a_frame_at_the_earlier_time_is_enough_to_re_anchor() {
    let mut w = running();
    glitch_master(&mut w);
    // Nobody tells the master; the slave (whose clock never jumped) beats at 1.1 s.
    w.run_until(ms(2000));
    let slave_hb = sent_between(&w, SLAVE, 0x705, ms(1000), ms(2000));
    assert_eq!(slave_hb.first(), Some(&ms(1100)));
    // At that frame the master noticed the step back (from 3601 s to 1.1 s): its next heartbeat,
    // due 100 ms after the glitch, comes 100 ms after the frame.
    let hb = sent_between(&w, MASTER, 0x701, ms(1000), ms(2000));
    assert_eq!(hb.first(), Some(&ms(1200)));
    assert_eq!(hb.len(), 9, "1.2 s to 2.0 s: {hb:?}");
}

#[test]
fn a_consumer_timed_out_by_a_glitch_resumes_and_keeps_watching() {
    let mut w = running();
    let glitch = glitch_master(&mut w);
    let timeouts = |w: &Wire| {
        w.events[MASTER]
            .iter()
            .filter(|e| matches!(e.kind, K::HeartbeatTimeout { .. }))
            .map(|e| e.at)
            .collect::<Vec<_>>()
    };
    // An hour without a heartbeat, as far as the master could tell: one timeout, at the glitch.
    assert_eq!(timeouts(&w), vec![glitch]);
    w.run_until(ms(3000));
    assert_eq!(timeouts(&w), vec![glitch], "heard again, watched again");
    // The slave goes silent at 3 s (last beat at 3.0 s): the timeout is exact again.
    w.alive[SLAVE] = false;
    w.run_until(ms(4000));
    assert_eq!(timeouts(&w), vec![glitch, ms(3250)]);
}

#[test]
fn at_the_end_of_time_a_driver_loop_does_not_spin_and_time_can_come_back() {
    let mut w = running();
    for i in 0..w.nodes.len() {
        w.now = Instant::MAX;
        let mut rounds = 0;
        while let Some(t) = w.nodes[i].poll_timeout() {
            assert!(t <= Instant::MAX);
            w.nodes[i].handle_timeout(Instant::MAX);
            w.flush();
            rounds += 1;
            assert!(rounds <= 2, "node {i} still due at Instant::MAX: {t:?}");
        }
    }
    assert_eq!(w.nodes[MASTER].poll_timeout(), None);
    // The clock comes back to normal: everything runs again within a period.
    let back = ms(1001);
    w.now = back;
    for i in 0..w.nodes.len() {
        w.nodes[i].handle_timeout(back);
    }
    w.flush();
    w.run_until(ms(1500));
    let hb = sent_between(&w, MASTER, 0x701, back, ms(1500));
    assert!(
        hb.first()
            .is_some_and(|t| *t <= back + Duration::from_millis(100)),
        "{hb:?}"
    );
    let sync = sent_between(&w, MASTER, 0x080, back, ms(1500));
    assert!(sync.len() >= 49, "{} SYNCs", sync.len());
}

/// A step of the caller's clock in a random sequence.
#[derive(Clone, Debug)]
enum Step {
    Ahead(u64),
    Back(u64),
    FarAhead,
    End,
}

fn step() -> impl Strategy<Value = Step> {
    prop_oneof![
        8 => (0u64..50_000).prop_map(Step::Ahead),
        2 => (0u64..5_000_000).prop_map(Step::Back),
        1 => Just(Step::FarAhead),
        1 => Just(Step::End),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// Whatever the caller's clock did, a driver loop never finds a deadline still due after
    /// handling it twice, and once the clock runs normally again (with the step reported) both
    /// nodes beat within one period and the master produces SYNC within one SYNC period.
    #[test]
    fn any_clock_misbehaviour_costs_at_most_one_period(steps in prop::collection::vec(step(), 1..24)) {
        let mut w = running();
        let mut now = w.now;
        for s in steps {
            now = match s {
                Step::Ahead(us) => now + Duration::from_micros(us),
                Step::Back(us) => now - Duration::from_micros(us),
                Step::FarAhead => now + HOUR,
                Step::End => Instant::MAX,
            };
            w.now = now;
            for i in 0..w.nodes.len() {
                let mut rounds = 0;
                while w.nodes[i].poll_timeout().is_some_and(|t| t <= now) {
                    w.nodes[i].handle_timeout(now);
                    w.flush();
                    rounds += 1;
                    prop_assert!(rounds <= 2, "node {} spins at {:?}", i, now);
                }
            }
        }
        // Normal time again, from a point of our choosing; the driver reports the step once.
        let back = ms(10_000);
        w.now = back;
        for i in 0..w.nodes.len() {
            w.nodes[i].handle_timeout(back);
        }
        w.flush();
        let until = back + Duration::from_millis(1000);
        w.run_until(until);
        for (i, raw) in [(MASTER, 0x701), (SLAVE, 0x705)] {
            let hb = sent_between(&w, i, raw, back, until);
            prop_assert!(hb.len() >= 9, "node {} sent {} heartbeats", i, hb.len());
            prop_assert!(hb[0] <= back + Duration::from_millis(100));
        }
        let sync = sent_between(&w, MASTER, 0x080, back, until);
        prop_assert!(sync.len() >= 99, "{} SYNCs", sync.len());
    }
}
