//! An active board that stops running by itself (its application, or its CiA 301 error
//! behaviour, puts it in pre-operational or stopped) while it goes on beating, on the simulated
//! dual bus with the supervised network of `net.rs` (slaves beat every 20 ms, consumer time
//! 50 ms, 1 Mbit/s). Before the fix the table still called it active (only a change *to*
//! operational was acted on) and the pair ran without a working board for the whole run.
//!
//! The rule: a heartbeat of the active member saying pre-operational or stopped, once it was
//! heard operational in its role, is a failure at that heartbeat: the standby is started at
//! once (on the bus within one frame: a millisecond), the board reset. A board this master
//! sent there itself (the application's NMT command through the supervisor) is left alone.

use crate::impostor::{heartbeat, inject};
use crate::net::*;
use duocan::nmt::NmtTarget;
use duocan::{Duration, Id, Instant, NmtCommand, NmtState};
use duocan_redundancy::supervisor::flying_master::MasterRole;
use duocan_redundancy::supervisor::pairs::{LossReason, PairsEvent, Phase, RoleReason};
use duocan_redundancy::{Member, PairId, SupervisorEvent};

const ONE_MS: Duration = Duration::from_millis(1);

fn ms(x: u64) -> Instant {
    Instant::from_millis(x)
}

/// Board `id` changes its own state to `state` at `t` (it announces it at once).
fn stops_itself_at(n: &mut SupNet, id: u8, state: NmtState, t: Instant) {
    let d = n.slave(id);
    n.sim.at(t, move |sim| {
        sim.device_mut(d).machine.set_nmt_state(t, state);
    });
}

fn running(n: &SupNet, id: u8) -> bool {
    n.sim.is_powered(n.slave(id))
        && n.sim.device(n.slave(id)).machine.nmt_state() == NmtState::Operational
}

/// The end of the first copy of `node`'s first heartbeat saying `state` after `t`: when the
/// masters learn it.
fn first_heartbeat_saying(n: &SupNet, node: u8, state: u8, t: Instant) -> Instant {
    n.delivered()
        .into_iter()
        .filter(|(e, _, s, f)| {
            *e > t
                && *s == node
                && f.id() == Id::Standard(0x700 + node as u16)
                && f.data() == [state]
        })
        .map(|x| x.0)
        .min()
        .expect("the heartbeat")
}

/// NMT commands (first copies) sent by master `from` after `t`: (end, command, target).
fn nmt_after(n: &SupNet, from: u8, t: Instant) -> Vec<(Instant, NmtCommand, u8)> {
    n.nmt_first_copies()
        .into_iter()
        .filter(|x| x.0 > t && x.1 == from)
        .map(|(e, _, c, node)| (e, c, node))
        .collect()
}

/// Pair 0 failed over from A to B by master `m` at `v` because A said `state`: the role change
/// and the loss at `v`, B started on the wire within a millisecond, then A reset.
fn assert_replaced_at(n: &SupNet, m: u8, v: Instant, state: NmtState) {
    let change = n
        .pair_roles(m, 0)
        .into_iter()
        .find(|r| r.at >= v - ONE_MS && r.from == Some(Member::A))
        .expect("a role change");
    assert_eq!(
        (change.at, change.to, change.reason),
        (
            v,
            Some(Member::B),
            RoleReason::ActiveNotOperational { state }
        )
    );
    let nmt = nmt_after(n, m, v - ONE_MS);
    assert_eq!((nmt[0].1, nmt[0].2), (NmtCommand::Start, b(0)), "{nmt:?}");
    assert!(nmt[0].0 > v && nmt[0].0 <= v + ONE_MS, "{nmt:?} vs {v}");
    assert_eq!(
        (nmt[1].1, nmt[1].2),
        (NmtCommand::ResetNode, a(0)),
        "{nmt:?}"
    );
    let lost = n.sup_events(m).into_iter().any(|e| {
        matches!(e, SupervisorEvent::Pairs(PairsEvent::Lost { at, node, reason: LossReason::NotOperational { state: s }, .. })
            if at == v && node.raw() == a(0) && s == state)
    });
    assert!(lost, "A lost as not operational at {v}");
}

#[test]
fn an_active_board_that_stops_by_itself_is_replaced_at_the_heartbeat_that_shows_it() {
    for (state, code) in [(NmtState::PreOperational, 0x7F), (NmtState::Stopped, 0x04)] {
        let mut n = SupNet::new(Params::default());
        stops_itself_at(&mut n, a(0), state, ms(1003));
        n.sim.run_until(ms(2000));
        let v = first_heartbeat_saying(&n, a(0), code, ms(1003));
        assert_replaced_at(&n, STRONG, v, state);
        // The weak master followed from the commands on the wire.
        assert_eq!(n.active_member(WEAK, 0), Some(Member::B));
        // The reset board booted and rejoined as the standby: one running board, the other
        // pairs untouched.
        let pair = *n.sup(STRONG).pair_supervisor().pair(PairId(0)).unwrap();
        assert_eq!(pair.active, Some(Member::B));
        assert_eq!(pair.member(Member::A).phase(), Phase::Joined);
        assert!(running(&n, b(0)) && !running(&n, a(0)), "{state}");
        assert_eq!(n.pair_roles(STRONG, 0).len(), 2);
        for i in 1..n.p.pairs {
            assert_eq!(n.pair_roles(STRONG, i).len(), 1, "pair {i}");
            assert!(running(&n, a(i)), "pair {i}");
        }
        // The audit trail says why.
        let mut text = String::new();
        n.sup(STRONG).audit().write_text(&mut text).unwrap();
        let why = format!("active A -> B: active member {state} without a command of this master");
        assert!(text.contains(&why), "{text}");
    }
}

#[test]
fn a_board_the_application_sends_to_pre_operational_through_the_master_is_not_replaced() {
    let mut n = SupNet::new(Params::default());
    n.sim.run_until(ms(1003));
    let m = n.master(STRONG);
    let target = NmtTarget::Node(duocan::NodeId::must(a(0)));
    n.sim
        .device_mut(m)
        .sup_mut()
        .nmt(ms(1003), NmtCommand::EnterPreOperational, target)
        .unwrap();
    n.sim.run_until(ms(1500));
    // Pre-operational as asked, still the active member: nothing started, nothing reset.
    assert_eq!(
        n.sim.device(n.slave(a(0))).machine.nmt_state(),
        NmtState::PreOperational
    );
    assert_eq!(n.active_member(STRONG, 0), Some(Member::A));
    assert_eq!(nmt_after(&n, STRONG, ms(1003)).len(), 1);
    assert!(!running(&n, b(0)));
    // Started again by the application, it is expected to run: stopping by itself later is a
    // failure again.
    n.sim
        .device_mut(m)
        .sup_mut()
        .nmt(ms(1500), NmtCommand::Start, target)
        .unwrap();
    stops_itself_at(&mut n, a(0), NmtState::Stopped, ms(1603));
    n.sim.run_until(ms(2500));
    let v = first_heartbeat_saying(&n, a(0), 0x04, ms(1603));
    assert_replaced_at(&n, STRONG, v, NmtState::Stopped);
}

#[test]
fn after_a_master_takeover_the_new_master_replaces_a_board_that_stops_by_itself() {
    let mut n = SupNet::new(Params::default());
    n.kill_master_at(STRONG, ms(1000));
    stops_itself_at(&mut n, a(0), NmtState::PreOperational, ms(1203));
    n.sim.run_until(ms(2000));
    assert_eq!(n.role(WEAK), MasterRole::Active);
    let v = first_heartbeat_saying(&n, a(0), 0x7F, ms(1203));
    assert_replaced_at(&n, WEAK, v, NmtState::PreOperational);
    assert!(running(&n, b(0)) && !running(&n, a(0)));
}

#[test]
fn revertive_a_board_that_stopped_by_itself_takes_the_role_back_once_rebooted_and_runs() {
    // A is replaced, reset, rejoins and takes the role back (revertive): its heartbeats still
    // saying pre-operational right after its start are no failure, it runs.
    let p = Params {
        revertive_pairs: true,
        ..Params::default()
    };
    let mut n = SupNet::new(p);
    stops_itself_at(&mut n, a(0), NmtState::PreOperational, ms(1003));
    n.sim.run_until(ms(2000));
    let v = first_heartbeat_saying(&n, a(0), 0x7F, ms(1003));
    let roles: Vec<_> = n
        .pair_roles(STRONG, 0)
        .into_iter()
        .map(|r| (r.from, r.to, r.reason))
        .collect();
    assert_eq!(
        roles,
        [
            (None, Some(Member::A), RoleReason::FirstJoined),
            (
                Some(Member::A),
                Some(Member::B),
                RoleReason::ActiveNotOperational {
                    state: NmtState::PreOperational
                }
            ),
            (Some(Member::B), Some(Member::A), RoleReason::Revert),
        ]
    );
    assert_eq!(n.pair_roles(STRONG, 0)[1].at, v);
    assert!(running(&n, a(0)) && !running(&n, b(0)));
}

#[test]
fn a_second_device_saying_the_active_member_is_pre_operational_is_a_failure_at_its_first_heartbeat()
{
    // A device set to node-ID 0x10 beats [7F] on both buses from 1007 ms while the real board
    // beats operational: the table cannot tell who sent it, and does not need to: the active
    // member is reported not running, replaced at once (the duplicate is found later by its
    // rate, `impostor.rs`).
    let mut n = SupNet::new(Params::default());
    let buses = n.buses;
    let dup = heartbeat(a(0), 0x7F);
    inject(
        &mut n,
        &buses,
        dup,
        Some(ms(1007)),
        Duration::from_millis(20),
    );
    n.sim.run_until(ms(1100));
    let v = n
        .delivered()
        .into_iter()
        .find(|x| x.0 > ms(1007) && x.3 == dup)
        .unwrap()
        .0;
    assert_replaced_at(&n, STRONG, v, NmtState::PreOperational);
}

// The same rules on the pair table alone (`pairs.rs`: A and B configured at 5 and 6 ms, A
// started at 5 ms, consumer time 50 ms).

use crate::pairs::{commands, events, nmts, roles, A, B};

#[test]
fn a_started_member_never_heard_running_fails_at_its_start_plus_the_consumer_time() {
    let (mut s, _) = crate::pairs::running();
    assert_eq!(nmts(&mut s), [(NmtCommand::Start, 0x10)]);
    events(&mut s);
    // A beats, but never says operational (its start refused); B stands by.
    for t in [10, 30, 50] {
        s.heartbeat(ms(t), A, NmtState::PreOperational);
        s.heartbeat(ms(t + 1), B, NmtState::PreOperational);
    }
    s.handle_timeout(ms(55) - Duration::from_micros(1));
    assert_eq!(nmts(&mut s), []);
    s.handle_timeout(ms(55));
    assert_eq!(
        nmts(&mut s),
        [(NmtCommand::Start, 0x11), (NmtCommand::ResetNode, 0x10)]
    );
    assert_eq!(
        roles(&mut s),
        [(
            ms(55),
            Some(Member::A),
            Some(Member::B),
            RoleReason::ActiveNotOperational {
                state: NmtState::PreOperational
            }
        )]
    );
}

#[test]
fn a_heartbeat_in_flight_at_the_start_is_no_failure_a_later_one_is() {
    let (mut s, p) = crate::pairs::running();
    commands(&mut s);
    events(&mut s);
    // Sent before the start reached it, then the announcement of the start.
    s.heartbeat(ms(6), A, NmtState::PreOperational);
    s.heartbeat(ms(7), A, NmtState::Operational);
    for t in [27, 47] {
        s.heartbeat(ms(t), A, NmtState::Operational);
        s.heartbeat(ms(t), B, NmtState::PreOperational);
        s.handle_timeout(ms(t));
    }
    assert_eq!(nmts(&mut s), []);
    s.heartbeat(ms(60), A, NmtState::Stopped);
    assert_eq!(
        nmts(&mut s),
        [(NmtCommand::Start, 0x11), (NmtCommand::ResetNode, 0x10)]
    );
    assert_eq!(
        roles(&mut s),
        [(
            ms(60),
            Some(Member::A),
            Some(Member::B),
            RoleReason::ActiveNotOperational {
                state: NmtState::Stopped
            }
        )]
    );
    assert!(events(&mut s).is_empty());
    assert_eq!(s.pair(p).unwrap().member(Member::A).phase(), Phase::Waiting);
}

#[test]
fn the_only_member_stopping_by_itself_is_reset_and_the_pair_has_no_active_member() {
    let (mut s, p) = crate::pairs::table(Default::default());
    s.boot_up(ms(0), A);
    s.configured(ms(3), A, true);
    s.heartbeat(ms(4), A, NmtState::Operational);
    commands(&mut s);
    events(&mut s);
    s.heartbeat(ms(24), A, NmtState::PreOperational);
    assert_eq!(nmts(&mut s), [(NmtCommand::ResetNode, 0x10)]);
    assert_eq!(
        roles(&mut s),
        [(
            ms(24),
            Some(Member::A),
            None,
            RoleReason::ActiveNotOperational {
                state: NmtState::PreOperational
            }
        )]
    );
    assert_eq!(s.pair(p).unwrap().active, None);
}

#[test]
fn a_member_held_by_the_application_is_still_judged_by_its_silence() {
    let (mut s, p) = crate::pairs::running();
    s.heartbeat(ms(7), A, NmtState::Operational);
    commands(&mut s);
    events(&mut s);
    s.application_nmt(NmtCommand::Stop, 0);
    assert!(s.is_held(A) && s.is_held(B));
    for t in [20, 40, 60] {
        s.heartbeat(ms(t), A, NmtState::Stopped);
        s.heartbeat(ms(t), B, NmtState::Stopped);
        s.handle_timeout(ms(t));
    }
    assert_eq!(nmts(&mut s), []);
    assert_eq!(s.pair(p).unwrap().active, Some(Member::A));
    // Silent: replaced at its last heartbeat + the consumer time, as any member.
    s.heartbeat(ms(80), B, NmtState::Stopped);
    s.handle_timeout(ms(110));
    assert_eq!(
        nmts(&mut s),
        [(NmtCommand::Start, 0x11), (NmtCommand::ResetNode, 0x10)]
    );
    assert_eq!(
        roles(&mut s)[0].3,
        RoleReason::ActiveSilent { last: ms(60) }
    );
    // The table started B: B is no longer held, its stopping is a failure again.
    assert!(!s.is_held(B));
}
