//! A master's clock jumps an hour ahead while the network runs (an RTC set forward), during a
//! pair switch-over and during a master takeover, on the supervised network of `net.rs`
//! (heartbeats every 20 ms, consumer time 50 ms, master timeout 50 ms). Before the fix the
//! master found every member's deadline an hour overdue and reset every live board of the
//! network, the standby it had just started included.
//!
//! The rule (the supervisor's clock contract): an input at least `clock_jump` (1 s by default,
//! and at least two heartbeat periods of the master) after the latest one is a jump; every member
//! whose deadline falls after that latest input is observed again, judged silent only if it stays
//! so for its consumer time after the jump. Each run is compared with the same run (same seed)
//! without the jump, to place the jump exactly in the switch-over or the takeover.

use crate::net::*;
use crate::stepped::ClockJump;
use duocan::{Duration, Instant, NmtCommand, NmtState};
use duocan_redundancy::supervisor::flying_master::MasterRole;
use duocan_redundancy::supervisor::pairs::RoleReason;
use duocan_redundancy::Member;

const HOUR: Duration = Duration::from_secs(3600);
const ONE_MS: Duration = Duration::from_millis(1);

fn ms(x: u64) -> Instant {
    Instant::from_millis(x)
}

fn running(n: &SupNet, id: u8) -> bool {
    n.sim.is_powered(n.slave(id))
        && n.sim.device(n.slave(id)).machine.nmt_state() == NmtState::Operational
}

/// Master `m`'s NMT resets on the wire after `t` (first copies): their targets.
fn resets_by(n: &SupNet, m: u8, t: Instant) -> Vec<u8> {
    n.nmt_first_copies()
        .into_iter()
        .filter(|x| x.0 > t && x.1 == m)
        .filter(|x| matches!(x.2, NmtCommand::ResetNode | NmtCommand::ResetCommunication))
        .map(|x| x.3)
        .collect()
}

/// No live board was reset after `t`, none booted again; every pair runs one board.
fn nothing_alive_reset(n: &SupNet, t: Instant, end: Instant, dead: &[u8]) {
    for m in [STRONG, WEAK] {
        let r = resets_by(n, m, t);
        assert!(r.iter().all(|x| dead.contains(x)), "master {m} reset {r:?}");
    }
    assert_eq!(n.boot_ups_in(t, end), Vec::<u8>::new());
    for i in 0..n.p.pairs {
        let running_boards = [a(i), b(i)].iter().filter(|x| running(n, **x)).count();
        assert_eq!(running_boards, 1, "pair {i}");
    }
}

#[test]
fn a_jump_ahead_during_a_pair_switch_over_resets_no_live_board() {
    // Without the jump: A of pair 0 dies at 1003 ms, B is started at its deadline.
    let run = |jump: Option<ClockJump>| {
        let mut n = SupNet::new(Params {
            clock_jump: jump.map(|j| (STRONG, j)),
            ..Params::default()
        });
        n.kill_slave_at(a(0), ms(1003));
        n.sim.run_until(ms(2000));
        n
    };
    let plain = run(None);
    let fail = plain
        .pair_roles(STRONG, 0)
        .into_iter()
        .find(|r| r.to == Some(Member::B))
        .unwrap();
    // The jump: 200 µs after B's start was handed over, before B is heard running; an hour,
    // the default threshold (1 s), and jumps shorter than it that still hide a member's
    // consumer time: 70 ms, and 45 ms (its deadline came before and is 35 ms overdue: more than
    // the slack of 30 ms, consumer time less producer time).
    let at = fail.at + Duration::from_micros(200);
    for by in [
        HOUR,
        Duration::from_secs(1),
        Duration::from_millis(70),
        Duration::from_millis(45),
    ] {
        switch_over_jumped(run(Some(ClockJump { at, by })), fail.at, at);
    }
}

fn switch_over_jumped(n: SupNet, fail: Instant, at: Instant) {
    let roles = n.pair_roles(STRONG, 0);
    assert_eq!((roles[1].at, roles[1].to), (fail, Some(Member::B)));
    nothing_alive_reset(&n, at, ms(2000), &[a(0)]);
    assert!(running(&n, b(0)));
    // Nothing changed role after the jump: B stays active, the other pairs keep A.
    for i in 0..n.p.pairs {
        let want = if i == 0 { 2 } else { 1 };
        assert_eq!(n.pair_roles(STRONG, i).len(), want, "pair {i}");
    }
    assert_eq!(n.active_member(STRONG, 0), Some(Member::B));
    assert_eq!(n.role(STRONG), MasterRole::Active);
}

#[test]
fn a_jump_ahead_during_a_master_takeover_resets_no_live_board() {
    let run = |jump: Option<ClockJump>| {
        let mut n = SupNet::new(Params {
            clock_jump: jump.map(|j| (WEAK, j)),
            ..Params::default()
        });
        n.kill_master_at(STRONG, ms(1000));
        n.sim.run_until(ms(2000));
        n
    };
    let plain = run(None);
    let take = plain
        .master_roles(WEAK)
        .into_iter()
        .find(|r| r.to == MasterRole::Active)
        .unwrap();
    // Just after the takeover (the table commanding), and just before it (it takes over at the
    // jump: the dead master's heartbeat is overdue too).
    for (at, by) in [
        (take.at + Duration::from_micros(200), HOUR),
        (take.at - ONE_MS, HOUR),
        (
            take.at + Duration::from_micros(200),
            Duration::from_millis(70),
        ),
    ] {
        let n = run(Some(ClockJump { at, by }));
        assert_eq!(n.role(WEAK), MasterRole::Active, "jump at {at}");
        nothing_alive_reset(&n, at, ms(2000), &[]);
        for i in 0..n.p.pairs {
            assert_eq!(n.active_member(WEAK, i), Some(Member::A), "pair {i}");
            assert!(running(&n, a(i)), "pair {i}, jump at {at}");
        }
    }
}

#[test]
fn a_board_dead_across_the_jump_is_replaced_its_consumer_time_after_the_jump() {
    // A of pair 1 dies at 1480 ms; the active master's clock jumps an hour ahead at 1500 ms,
    // before A's deadline. Observed again from the jump, A is found silent its consumer time
    // after it: B started on the wire within the consumer time + 1 ms of the jump.
    let jump = ClockJump {
        at: ms(1500),
        by: HOUR,
    };
    let mut n = SupNet::new(Params {
        clock_jump: Some((STRONG, jump)),
        ..Params::default()
    });
    n.kill_slave_at(a(1), ms(1480));
    n.sim.run_until(ms(2000));
    let last = n.last_heartbeat(a(1), ms(1480));
    assert!(
        last + n.p.consumer > jump.at,
        "A's deadline falls after the jump"
    );
    // The jump's end: the master's first input after it, when it was woken at 1500 ms.
    let end = jump.at + HOUR;
    let fail = n
        .pair_roles(STRONG, 1)
        .into_iter()
        .find(|r| r.to == Some(Member::B))
        .expect("a failover");
    assert_eq!(
        (fail.at, fail.reason),
        (end + n.p.consumer, RoleReason::ActiveSilent { last: end })
    );
    let start = n
        .nmt_first_copies()
        .into_iter()
        .find(|x| x.1 == STRONG && x.2 == NmtCommand::Start && x.3 == b(1))
        .unwrap();
    let due = jump.at + n.p.consumer;
    assert!(
        start.0 > due && start.0 <= due + ONE_MS,
        "{start:?} vs {due}"
    );
    // Only the dead board is reset; everything alive runs on.
    nothing_alive_reset(&n, jump.at, ms(2000), &[a(1)]);
    assert!(running(&n, b(1)));
}

#[test]
fn the_table_observes_again_what_fell_due_in_the_jump_and_acts_on_what_was_due_before() {
    // The pair table alone (`pairs.rs`): A and B configured at 5 and 6 ms, A started.
    use crate::pairs::{commands, nmts, running as configured, A, B};
    let (mut s, p) = configured();
    s.heartbeat(ms(7), A, NmtState::Operational);
    s.heartbeat(ms(20), B, NmtState::PreOperational);
    s.heartbeat(ms(40), A, NmtState::Operational);
    commands(&mut s);
    // B's deadline (70 ms) falls before the latest input (80 ms), A's (90 ms) after it. The clock
    // jumps from 80 ms to an hour: B stays due (its silence was watched), A is observed again.
    let to = ms(80) + HOUR;
    s.jumped(ms(80), to);
    let st = s.pair(p).unwrap();
    assert_eq!(st.member(Member::B).deadline(), Some(ms(70)));
    assert_eq!(
        st.member(Member::A).deadline(),
        Some(to + Duration::from_millis(50))
    );
    s.handle_timeout(to);
    assert_eq!(nmts(&mut s), [(NmtCommand::ResetNode, 0x11)]);
    s.heartbeat(to + ONE_MS, A, NmtState::Operational);
    s.handle_timeout(to + Duration::from_millis(50));
    assert_eq!(nmts(&mut s), []);
    assert_eq!(s.pair(p).unwrap().active, Some(Member::A));
}

#[test]
fn a_receive_path_running_behind_for_a_moment_is_no_silence() {
    // A master hears one bus only (its port on bus 2 unplugged at 1000 ms); from 1200 ms that
    // port hands its frames over 46 ms after they were on the wire (a reader held up, a gateway
    // queue), on time again from 1500 ms. At the onset it hears nothing at all for 46 ms, then
    // everything at once: handed over, the other master's heartbeat and every board's come
    // 66 ms apart, past the 50 ms timeouts. Before, the weak master behind that path took over
    // and reset every board; the strong one behind it reset every board too. Now the silence of
    // the whole network is observed again (30 ms, the smallest slack: 50 ms less 20 ms), and
    // the frames that come after it show every node alive.
    for m in [STRONG, WEAK] {
        let mut n = SupNet::new(Params::default());
        let port = |k| n.master(m).port(k);
        let (p0, p1) = (port(0), port(1));
        n.sim.run_until(ms(1000));
        assert_eq!(n.role(STRONG), MasterRole::Active);
        n.sim.disconnect(p1);
        n.sim.run_until(ms(1200));
        n.sim.set_port_latency(p0, Duration::from_millis(46));
        n.sim.run_until(ms(1500));
        n.sim.set_port_latency(p0, Duration::ZERO);
        n.sim.run_until(ms(2000));
        assert_eq!(n.role(STRONG), MasterRole::Active, "master {m} behind");
        assert_eq!(
            n.master_roles(WEAK).last().map(|r| r.at < ms(1000)),
            Some(true)
        );
        nothing_alive_reset(&n, ms(1000), ms(2000), &[]);
    }
}
