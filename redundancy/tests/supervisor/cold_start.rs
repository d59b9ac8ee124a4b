//! Member A first at a cold start: with both boards present, A runs even when B's configuration
//! ends first. B waits for A while A is being configured and trusted, for the pair's consumer
//! time from its own configuration at most (50 ms here: B configured at 5 ms runs at 55 ms at
//! the latest); A's failed configuration or its heartbeats in doubt end the wait at once; a pair
//! whose A was never heard runs B at its configuration, as before.

use crate::pairs::{commands, events, ms, nmts, roles, table, A, B};
use duocan::{Duration, NmtCommand, NmtState};
use duocan_redundancy::supervisor::pairs::{PairSupervisor, PairsConfig, RoleReason};
use duocan_redundancy::{Member, PairId};

/// Both boards boot at 0; B's configuration ends at 5 ms, A's is still running.
fn b_configured_first() -> (PairSupervisor, PairId) {
    let (mut s, p) = table(PairsConfig::default());
    s.boot_up(ms(0), A);
    s.boot_up(ms(0), B);
    s.configured(ms(5), B, true);
    commands(&mut s);
    assert!(roles(&mut s).is_empty(), "B waits for A");
    assert_eq!(s.pair(p).unwrap().active, None);
    (s, p)
}

#[test]
fn both_present_a_runs_although_b_was_configured_first() {
    let (mut s, p) = b_configured_first();
    s.heartbeat(ms(7), B, NmtState::PreOperational);
    s.configured(ms(8), A, true);
    assert_eq!(nmts(&mut s), [(NmtCommand::Start, 0x10)], "A alone started");
    assert_eq!(
        roles(&mut s),
        [(ms(8), None, Some(Member::A), RoleReason::FirstJoined)]
    );
    assert_eq!(s.pair(p).unwrap().active, Some(Member::A));
    // The bound passes with nothing to do: B stays standby.
    s.handle_timeout(ms(55));
    assert!(nmts(&mut s).is_empty());
    assert_eq!(s.pair(p).unwrap().active, Some(Member::A));
}

#[test]
fn a_slow_to_configure_within_the_bound_still_runs() {
    let (mut s, p) = b_configured_first();
    for t in [25, 45] {
        s.heartbeat(ms(t), B, NmtState::PreOperational);
    }
    // The table wakes for the bound, which has not come yet.
    assert!(s.poll_timeout().is_some_and(|t| t <= ms(55)));
    s.handle_timeout(ms(55) - Duration::from_micros(1));
    assert!(commands(&mut s).is_empty());
    s.configured(ms(55) - Duration::from_micros(1), A, true);
    assert_eq!(nmts(&mut s), [(NmtCommand::Start, 0x10)]);
    s.handle_timeout(ms(55));
    assert!(nmts(&mut s).is_empty());
    assert_eq!(s.pair(p).unwrap().active, Some(Member::A));
}

#[test]
fn a_never_configured_b_runs_exactly_at_the_bound() {
    let (mut s, p) = b_configured_first();
    for t in [25, 45] {
        s.heartbeat(ms(t), B, NmtState::PreOperational);
    }
    s.handle_timeout(ms(55) - Duration::from_micros(1));
    assert!(commands(&mut s).is_empty());
    s.handle_timeout(ms(55));
    assert_eq!(nmts(&mut s), [(NmtCommand::Start, 0x11)]);
    assert_eq!(
        roles(&mut s),
        [(ms(55), None, Some(Member::B), RoleReason::FirstJoined)]
    );
    // Started, B has the consumer time from its start to be heard running.
    let b = s.pair(p).unwrap().member(Member::B);
    assert_eq!(b.deadline(), Some(ms(105)));
    // A configured late joins as standby (non-revertive): never two running.
    s.heartbeat(ms(65), B, NmtState::Operational);
    s.configured(ms(70), A, true);
    assert!(nmts(&mut s).is_empty());
    assert_eq!(s.pair(p).unwrap().active, Some(Member::B));
}

#[test]
fn a_failed_configuration_ends_the_wait_at_once() {
    let (mut s, p) = b_configured_first();
    s.configured(ms(20), A, false);
    assert_eq!(
        nmts(&mut s),
        [(NmtCommand::Start, 0x11), (NmtCommand::ResetNode, 0x10)]
    );
    assert_eq!(
        roles(&mut s),
        [(ms(20), None, Some(Member::B), RoleReason::FirstJoined)]
    );
    assert_eq!(s.pair(p).unwrap().active, Some(Member::B));
}

#[test]
fn a_rejected_ends_the_wait_at_once() {
    let (mut s, p) = b_configured_first();
    s.rejected(ms(12), A);
    assert_eq!(nmts(&mut s), [(NmtCommand::Start, 0x11)]);
    assert_eq!(s.pair(p).unwrap().active, Some(Member::B));
}

#[test]
fn a_in_doubt_is_not_waited_for() {
    let (mut s, p) = b_configured_first();
    s.suspect(ms(15), A, true, false);
    assert_eq!(nmts(&mut s), [(NmtCommand::Start, 0x11)]);
    assert_eq!(
        roles(&mut s),
        [(ms(15), None, Some(Member::B), RoleReason::FirstJoined)]
    );
    assert_eq!(s.pair(p).unwrap().active, Some(Member::B));
}

#[test]
fn a_dead_b_runs_at_its_configuration_as_before() {
    let (mut s, p) = table(PairsConfig::default());
    s.boot_up(ms(0), B);
    s.configured(ms(5), B, true);
    assert_eq!(nmts(&mut s), [(NmtCommand::Start, 0x11)]);
    assert_eq!(
        roles(&mut s),
        [(ms(5), None, Some(Member::B), RoleReason::FirstJoined)]
    );
    assert_eq!(s.pair(p).unwrap().active, Some(Member::B));
}

#[test]
fn a_silent_b_at_the_bound_is_reset_not_started() {
    // B never beats after its configuration: its deadline is the bound itself.
    let (mut s, p) = b_configured_first();
    s.handle_timeout(ms(55));
    assert_eq!(nmts(&mut s), [(NmtCommand::ResetNode, 0x11)]);
    assert!(roles(&mut s).is_empty());
    assert_eq!(s.pair(p).unwrap().active, None);
    // A, configured later, runs.
    s.configured(ms(60), A, true);
    assert_eq!(nmts(&mut s), [(NmtCommand::Start, 0x10)]);
    events(&mut s);
}

#[test]
fn a_booting_again_during_the_wait_does_not_extend_it() {
    let (mut s, p) = b_configured_first();
    s.heartbeat(ms(25), B, NmtState::PreOperational);
    s.boot_up(ms(40), A);
    s.heartbeat(ms(45), B, NmtState::PreOperational);
    s.handle_timeout(ms(55));
    assert_eq!(nmts(&mut s), [(NmtCommand::Start, 0x11)]);
    assert_eq!(s.pair(p).unwrap().active, Some(Member::B));
}
