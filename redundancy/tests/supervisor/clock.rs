//! The clock contract on a supervised master (supervisor, CiA 302-2 master, dual-bus layer): a
//! step back of a master's clock moves every time it holds back with it, so that a board or a
//! master that dies right after the step is failed over exactly when it would have been on a
//! clock that never stepped; a jump ahead is time that passed; a driver loop at the end of time
//! handles what is due and then waits instead of spinning.
//!
//! The stepped runs use [`ClockStep`]: both masters' clocks read an hour ahead of the simulated
//! time until 1.5 s and then step back to it, so the instants after the step are the simulated
//! ones and the wire's trace gives the exact expected figures.

use crate::net::*;
use crate::stepped::ClockStep;
use duocan::machine::Device;
use duocan::{Duration, Id, Instant, NodeId};
use duocan_redundancy::supervisor::flying_master::{
    FlyingMaster, FlyingMasterConfig, MasterReason, MasterRole, Rank,
};
use duocan_redundancy::supervisor::pairs::RoleReason;
use duocan_redundancy::Member;

const HOUR: Duration = Duration::from_secs(3600);
const STEP: Instant = Instant::from_millis(1500);

fn ms(x: u64) -> Instant {
    Instant::from_millis(x)
}

fn stepped() -> SupNet {
    SupNet::new(Params {
        clock_step: Some(ClockStep { at: STEP, by: HOUR }),
        ..Params::default()
    })
}

/// Neither master changed its role in `[t, 1 h)` (nothing fired an hour early or late; what
/// happened before a step is reported in the time line an hour ahead).
fn roles_unchanged_after(n: &SupNet, t: Instant) {
    for id in [STRONG, WEAK] {
        let late: Vec<_> = n
            .master_roles(id)
            .into_iter()
            .filter(|r| r.at >= t && r.at < Instant::ZERO + HOUR)
            .collect();
        assert!(late.is_empty(), "master {id}: {late:?}");
    }
}

/// Killed shortly before the step (its last heartbeat and its deadline in the old time line)
/// and shortly after it.
const KILLS: [Instant; 2] = [Instant::from_millis(1487), Instant::from_millis(1513)];

#[test]
fn an_active_board_silent_across_a_step_back_fails_over_at_its_last_heartbeat_plus_consumer_time() {
    for kill in KILLS {
        board_dies(kill);
    }
}

fn board_dies(kill: Instant) {
    let mut n = stepped();
    n.sim.run_until(ms(1480));
    assert_eq!(n.role(STRONG), MasterRole::Active);
    assert_eq!(n.active_member(STRONG, 0), Some(Member::A));
    n.kill_slave_at(a(0), kill);
    n.sim.run_until(ms(2000));

    let last = n.last_heartbeat(a(0), kill);
    let fail = n
        .pair_roles(STRONG, 0)
        .into_iter()
        .find(|r| r.at >= STEP && r.at < Instant::ZERO + HOUR)
        .expect("a failover in the new time line");
    assert_eq!(fail.to, Some(Member::B), "killed at {kill}");
    assert_eq!(fail.reason, RoleReason::ActiveSilent { last });
    assert_eq!(fail.at, last + n.p.consumer);
    // B is started on the wire within a millisecond.
    let start = n
        .nmt_first_copies()
        .into_iter()
        .find(|x| x.1 == STRONG && x.3 == b(0) && x.0 >= fail.at)
        .expect("B started");
    assert!(start.0 <= fail.at + Duration::from_millis(1), "{start:?}");
    // The other pairs kept their members, and the masters their roles.
    for p in 1..n.p.pairs {
        assert_eq!(n.active_member(STRONG, p), Some(Member::A), "pair {p}");
    }
    roles_unchanged_after(&n, STEP);
}

#[test]
fn an_active_master_silent_across_a_step_back_is_taken_over_at_its_last_heartbeat_plus_timeout() {
    for kill in KILLS {
        master_dies(kill);
    }
}

fn master_dies(kill: Instant) {
    let mut n = stepped();
    n.sim.run_until(ms(1480));
    assert_eq!(n.role(STRONG), MasterRole::Active);
    n.kill_master_at(STRONG, kill);
    n.sim.run_until(ms(2000));

    let last = n.last_heartbeat(STRONG, kill);
    let take = n
        .master_roles(WEAK)
        .into_iter()
        .find(|r| r.to == MasterRole::Active)
        .expect("a takeover");
    assert_eq!(take.at, last + n.p.master_timeout, "killed at {kill}");
    assert_eq!(
        take.reason,
        MasterReason::HeartbeatLost {
            master: NodeId::must(STRONG),
            last
        }
    );
    // SYNC continues: no gap longer than the timeout and a period across the takeover.
    let gap = n.max_sync_gap(ms(1400), ms(2000));
    assert!(gap <= n.p.master_timeout + n.p.sync, "{gap}");
}

#[test]
fn a_glitch_an_hour_ahead_costs_one_period_not_an_hour() {
    let mut n = SupNet::new(Params::default());
    n.sim.run_until(STEP);
    let m = n.master(STRONG);
    let glitch = STEP + HOUR;
    {
        let d = n.sim.device_mut(m);
        let mut rounds = 0;
        let (mut syncs, mut beats) = (0, 0);
        while d.poll_timeout().is_some_and(|t| t <= glitch) {
            assert!(rounds < 3, "still due after {rounds} rounds");
            d.handle_timeout(glitch);
            while let Some((port, f)) = d.poll_transmit() {
                syncs += usize::from(port == 0 && f.id() == Id::Standard(0x80));
                beats += usize::from(port == 0 && f.id() == Id::Standard(0x700 + STRONG as u16));
            }
            while d.poll_port_request().is_some() {}
            rounds += 1;
        }
        // What was due in the hour is done once: one SYNC, one heartbeat, not 360,000.
        assert!(
            syncs <= 1 && beats <= 1,
            "{syncs} SYNCs, {beats} heartbeats"
        );
    }
    // The clock comes back: SYNC and heartbeat go on at once, nobody takes over.
    n.sim.run_until(ms(2000));
    let gap = n.max_sync_gap(STEP, ms(2000));
    assert!(gap <= n.p.sync + n.p.sync, "{gap}");
    assert!(n.last_heartbeat(STRONG, ms(2000)) >= ms(1980));
    roles_unchanged_after(&n, STEP);
    for p in 0..n.p.pairs {
        assert_eq!(n.active_member(STRONG, p), Some(Member::A), "pair {p}");
    }
}

#[test]
fn a_flying_master_keeps_the_time_left_of_its_detection_cycle_and_suspension() {
    let rank = |p, n| Rank::new(p, NodeId::must(n));
    let cfg = FlyingMasterConfig::new(0, NodeId::must(1), Duration::from_millis(50));
    let mut fm = FlyingMaster::new(cfg);
    fm.add_peer(rank(1, 2)).unwrap();
    let t0 = Instant::ZERO + HOUR;
    fm.start(t0);
    // Alone: it negotiates and wins.
    for _ in 0..4 {
        if let Some(t) = fm.poll_timeout() {
            fm.handle_timeout(t);
        }
    }
    assert_eq!(fm.role(), MasterRole::Active);
    // The peer returns after a loss while this one is active: commands suspended.
    let now = fm.poll_timeout().unwrap() - Duration::from_millis(1);
    fm.heartbeat(now, NodeId::must(2), false);
    fm.handle_timeout(now + HOUR); // a gap: the peer's heartbeat counted as lost
    let back = now + HOUR + Duration::from_millis(10);
    fm.heartbeat(back, NodeId::must(2), false);
    assert!(!fm.may_command(back));
    let due = fm.poll_timeout().unwrap();
    assert!(due > back);

    fm.step_back(HOUR);
    let back = back - HOUR;
    assert_eq!(fm.poll_timeout(), Some(due - HOUR));
    assert!(!fm.may_command(due - HOUR - Duration::from_micros(1)));
    fm.handle_timeout(due - HOUR);
    assert_eq!(fm.peers()[0].last, Some(back));
    while let Some(t) = fm
        .poll_timeout()
        .filter(|t| *t <= back + Duration::from_secs(1))
    {
        fm.handle_timeout(t);
    }
    assert!(fm.may_command(back + Duration::from_secs(1)));
}

#[test]
fn a_supervised_master_at_the_end_of_time_does_not_spin() {
    let mut n = SupNet::new(Params::default());
    n.sim.run_until(Instant::from_millis(1500));
    for id in [STRONG, WEAK] {
        let dev = n.master(id);
        let d = n.sim.device_mut(dev);
        let mut rounds = 0;
        while let Some(t) = d.poll_timeout() {
            assert!(
                rounds < 3,
                "master {id} still due at {t:?} after {rounds} rounds"
            );
            d.handle_timeout(Instant::MAX);
            while d.poll_transmit().is_some() {}
            while d.poll_port_request().is_some() {}
            while d.poll_event().is_some() {}
            rounds += 1;
        }
        assert_eq!(d.poll_timeout(), None, "master {id}");
    }
}
