//! The pair table and the dual-bus layer's verdicts on heartbeats (impostor, babbling
//! identifier, duplicate node-ID), and standbys started by someone else: as a pure machine, at
//! exact instants. `impostor.rs` shows the same on the wire.

use crate::pairs::{commands, events, ms, nmts, observe, roles, running, table, A, B};
use duocan::{Duration, NmtCommand, NmtState, NodeId};
use duocan_redundancy::supervisor::pairs::{
    Authority, LossReason, PairCommand, PairSupervisor, PairsConfig, PairsEvent, Phase, RoleReason,
};
use duocan_redundancy::{Member, PairId};
use proptest::prelude::*;

fn configures(cmds: &[PairCommand]) -> Vec<u8> {
    cmds.iter()
        .filter_map(|c| match c {
            PairCommand::Configure { node, .. } => Some(node.raw()),
            _ => None,
        })
        .collect()
}

/// Both members running (A active, B standby, both heard), then A found duplicated at 30 ms:
/// B started, A sent to pre-operational (the commands left to read).
fn a_duplicated_for_b() -> (PairSupervisor, PairId) {
    let (mut s, p) = running();
    commands(&mut s);
    s.heartbeat(ms(25), A, NmtState::Operational);
    s.heartbeat(ms(26), B, NmtState::PreOperational);
    s.suspect(ms(30), A, true, true);
    (s, p)
}

#[test]
fn a_suspect_active_member_is_replaced_at_once_and_its_heartbeats_count_for_nothing() {
    let (mut s, p) = running();
    commands(&mut s);
    events(&mut s);
    s.heartbeat(ms(25), A, NmtState::Operational);
    s.heartbeat(ms(26), B, NmtState::PreOperational);
    // The layer's verdict at 30 ms, well before A's deadline (75 ms).
    s.suspect(ms(30), A, true, false);
    assert!(s.is_suspect(A) && !s.is_suspect(B));
    let cmds = commands(&mut s);
    let ev: Vec<_> = core::iter::from_fn(|| s.poll_event()).collect();
    assert_eq!(
        cmds.iter()
            .filter_map(|c| match c {
                PairCommand::Nmt { cmd, node } => Some((*cmd, node.raw())),
                _ => None,
            })
            .collect::<Vec<_>>(),
        [(NmtCommand::Start, 0x11), (NmtCommand::ResetNode, 0x10)]
    );
    assert!(ev.iter().any(|e| matches!(e, PairsEvent::Role(r)
        if (r.at, r.from, r.to, r.reason) == (ms(30), Some(Member::A), Some(Member::B), RoleReason::ActiveSuspect))));
    assert!(ev.iter().any(|e| matches!(e, PairsEvent::Lost { at, member: Member::A, reason: LossReason::Suspect, .. } if *at == ms(30))));
    // The impostor goes on beating, booting: not adopted, not configured.
    for t in (45..400).step_by(20) {
        s.heartbeat(ms(t), A, NmtState::Operational);
        s.heartbeat(ms(t + 1), B, NmtState::Operational);
        s.handle_timeout(ms(t + 1));
    }
    s.boot_up(ms(100), A);
    s.handle_timeout(ms(400));
    assert!(configures(&commands(&mut s)).is_empty());
    let st = s.pair(p).unwrap();
    assert_eq!(st.member(Member::A).phase(), Phase::Waiting);
    assert_eq!(st.active, Some(Member::B));
    // Trusted again: its next heartbeat is news, adopted after the hold-off (200 ms).
    s.suspect(ms(400), A, false, false);
    assert!(commands(&mut s).is_empty());
    s.heartbeat(ms(405), A, NmtState::PreOperational);
    s.handle_timeout(ms(604));
    assert!(configures(&commands(&mut s)).is_empty());
    s.handle_timeout(ms(605));
    assert_eq!(configures(&commands(&mut s)), [0x10]);
}

#[test]
fn a_suspect_standby_is_reset_the_active_keeps_running() {
    let (mut s, p) = running();
    commands(&mut s);
    events(&mut s);
    s.suspect(ms(30), B, true, false);
    assert_eq!(nmts(&mut s), [(NmtCommand::ResetNode, 0x11)]);
    assert!(roles(&mut s).is_empty());
    assert_eq!(s.pair(p).unwrap().active, Some(Member::A));
    // A verdict repeated changes nothing.
    s.suspect(ms(31), B, true, false);
    assert!(commands(&mut s).is_empty());
}

#[test]
fn a_suspect_only_member_is_reset_and_the_pair_has_none() {
    let (mut s, p) = table(PairsConfig::default());
    s.boot_up(ms(0), A);
    s.configured(ms(5), A, true);
    commands(&mut s);
    events(&mut s);
    s.suspect(ms(30), A, true, false);
    assert_eq!(nmts(&mut s), [(NmtCommand::ResetNode, 0x10)]);
    assert_eq!(
        roles(&mut s),
        [(ms(30), Some(Member::A), None, RoleReason::ActiveSuspect)]
    );
    assert_eq!(s.pair(p).unwrap().active, None);
}

#[test]
fn a_suspect_standby_never_takes_the_role_even_for_an_instant() {
    // A's deadline (55 ms) falls due in the same handling as the verdict on B (at 60 ms, its
    // own deadline moved to then): B is not alive, so A's silence leaves the pair without an
    // active member at once, rather than handing it to B for the next deadline to take back.
    let (mut s, p) = running();
    commands(&mut s);
    events(&mut s);
    s.heartbeat(ms(30), B, NmtState::PreOperational);
    s.suspect(ms(60), B, true, false);
    assert_eq!(
        roles(&mut s),
        [(
            ms(55),
            Some(Member::A),
            None,
            RoleReason::OnlyMemberSilent { last: ms(5) }
        )]
    );
    assert_eq!(
        nmts(&mut s),
        [(NmtCommand::ResetNode, 0x10), (NmtCommand::ResetNode, 0x11)]
    );
    assert_eq!(s.pair(p).unwrap().active, None);
}

#[test]
fn a_duplicated_active_member_is_replaced_and_sent_to_pre_operational_not_reset() {
    // A second device beats A's heartbeat on both buses: A's own board may well run, so it is
    // not reset (its boot-up would be dropped as the duplicate's twin); it is stopped, the
    // standby started, and once trusted its heartbeats adopt it again without a reboot.
    let (mut s, p) = running();
    commands(&mut s);
    events(&mut s);
    s.heartbeat(ms(25), A, NmtState::Operational);
    s.heartbeat(ms(26), B, NmtState::PreOperational);
    s.suspect(ms(30), A, true, true);
    assert!(s.is_duplicated(A));
    assert_eq!(
        nmts(&mut s),
        [
            (NmtCommand::Start, 0x11),
            (NmtCommand::EnterPreOperational, 0x10)
        ]
    );
    assert_eq!(
        roles(&mut s),
        [(
            ms(30),
            Some(Member::A),
            Some(Member::B),
            RoleReason::ActiveSuspect
        )]
    );
    // The duplicate's "operational" and A's "pre-operational" count for nothing meanwhile.
    for t in (45..400).step_by(10) {
        s.heartbeat(ms(t), A, NmtState::Operational);
        s.heartbeat(ms(t + 1), B, NmtState::Operational);
        s.handle_timeout(ms(t + 1));
    }
    assert!(nmts(&mut s).is_empty());
    s.suspect(ms(400), A, false, false);
    assert!(!s.is_duplicated(A) && !s.is_suspect(A));
    for t in (405..620).step_by(20) {
        s.heartbeat(ms(t), A, NmtState::PreOperational);
        s.heartbeat(ms(t + 1), B, NmtState::Operational);
    }
    s.handle_timeout(ms(605));
    assert_eq!(configures(&commands(&mut s)), [0x10]);
    events(&mut s);
    s.configured(ms(610), A, true);
    assert_eq!(s.pair(p).unwrap().member(Member::A).phase(), Phase::Joined);
    // Back in its pair as the standby.
    assert!(roles(&mut s).is_empty());
    assert_eq!(s.pair(p).unwrap().active, Some(Member::B));
}

#[test]
fn a_duplicated_only_member_is_started_as_the_last_resort_until_the_other_takes_over() {
    // B is dead when A's heartbeat is duplicated: A is started, not reset (its board may be the
    // pair's only running one), and the pair has no active member in the table. When B comes
    // back and is started, A is sent to pre-operational: one running board.
    let (mut s, p) = running();
    commands(&mut s);
    events(&mut s);
    s.heartbeat(ms(25), A, NmtState::Operational);
    s.handle_timeout(ms(56));
    assert_eq!(
        nmts(&mut s),
        [(NmtCommand::ResetNode, 0x11)],
        "B silent at 56 ms"
    );
    s.heartbeat(ms(45), A, NmtState::Operational);
    s.suspect(ms(60), A, true, true);
    assert_eq!(nmts(&mut s), [(NmtCommand::Start, 0x10)]);
    assert_eq!(
        roles(&mut s),
        [(ms(60), Some(Member::A), None, RoleReason::ActiveSuspect)]
    );
    s.boot_up(ms(100), B);
    commands(&mut s);
    s.configured(ms(110), B, true);
    assert_eq!(
        nmts(&mut s),
        [
            (NmtCommand::Start, 0x11),
            (NmtCommand::EnterPreOperational, 0x10)
        ]
    );
    assert_eq!(s.pair(p).unwrap().active, Some(Member::B));
}

#[test]
fn a_duplicated_member_stopped_for_a_live_standby_is_started_when_that_one_dies() {
    let (mut s, p) = a_duplicated_for_b();
    assert_eq!(
        nmts(&mut s),
        [
            (NmtCommand::Start, 0x11),
            (NmtCommand::EnterPreOperational, 0x10)
        ]
    );
    s.heartbeat(ms(40), B, NmtState::Operational);
    events(&mut s);
    // B silent from 40 ms: its deadline at 90 ms. A is the last resort.
    s.handle_timeout(ms(90));
    assert_eq!(
        nmts(&mut s),
        [(NmtCommand::ResetNode, 0x11), (NmtCommand::Start, 0x10)]
    );
    assert_eq!(
        roles(&mut s),
        [(
            ms(90),
            Some(Member::B),
            None,
            RoleReason::OnlyMemberSilent { last: ms(40) }
        )]
    );
    assert_eq!(s.pair(p).unwrap().active, None);
}

#[test]
fn a_member_found_duplicated_again_after_it_left_is_started_when_the_pair_has_none() {
    // A duplicated, stopped for B; its verdict ends (the bus that carried the duplicate was
    // cut) and it has left the pair; B dies; then A is found duplicated again (on the other
    // bus). No member was running: A is the last resort.
    let (mut s, p) = a_duplicated_for_b();
    nmts(&mut s);
    s.heartbeat(ms(40), B, NmtState::Operational);
    s.suspect(ms(50), A, false, false);
    s.handle_timeout(ms(90));
    assert_eq!(nmts(&mut s), [(NmtCommand::ResetNode, 0x11)], "B silent");
    assert_eq!(s.pair(p).unwrap().active, None);
    s.suspect(ms(95), A, true, true);
    assert_eq!(nmts(&mut s), [(NmtCommand::Start, 0x10)]);
    // Found duplicated while B runs: nothing (B is alive).
    let (mut s, _) = a_duplicated_for_b();
    nmts(&mut s);
    s.heartbeat(ms(40), B, NmtState::Operational);
    s.suspect(ms(50), A, false, false);
    s.suspect(ms(60), A, true, true);
    assert_eq!(nmts(&mut s), []);
}

#[test]
fn a_duplicated_standby_is_left_alone() {
    let (mut s, p) = running();
    commands(&mut s);
    events(&mut s);
    s.suspect(ms(30), B, true, true);
    assert!(nmts(&mut s).is_empty());
    assert!(roles(&mut s).is_empty());
    let st = s.pair(p).unwrap();
    assert_eq!(
        (st.member(Member::B).phase(), st.active),
        (Phase::Waiting, Some(Member::A))
    );
}

#[test]
fn a_member_configured_while_suspect_waits_unstarted_and_unreset() {
    let (mut s, p) = table(PairsConfig::default());
    s.boot_up(ms(0), A);
    s.suspect(ms(2), A, true, false);
    s.configured(ms(5), A, true);
    s.handle_timeout(ms(5));
    assert!(nmts(&mut s).is_empty());
    assert_eq!(s.pair(p).unwrap().member(Member::A).phase(), Phase::Waiting);
    assert_eq!(s.pair(p).unwrap().active, None);
}

#[test]
fn a_shadow_records_the_verdict_and_acts_on_it_when_it_takes_command() {
    let (mut s, p) = running();
    s.set_authority(ms(20), Authority::Shadow);
    commands(&mut s);
    events(&mut s);
    s.suspect(ms(30), A, true, false);
    assert!(commands(&mut s).is_empty());
    // Its heartbeats (the impostor's) no longer keep it alive in the shadow table either.
    s.heartbeat(ms(45), A, NmtState::Operational);
    s.heartbeat(ms(46), B, NmtState::PreOperational);
    s.set_authority(ms(60), Authority::Command);
    assert_eq!(
        nmts(&mut s),
        [(NmtCommand::Start, 0x11), (NmtCommand::ResetNode, 0x10)]
    );
    assert_eq!(
        roles(&mut s),
        [(
            ms(30),
            Some(Member::A),
            Some(Member::B),
            RoleReason::ActiveSuspect
        )]
    );
    assert_eq!(s.pair(p).unwrap().active, Some(Member::B));
}

#[test]
fn a_standby_started_by_someone_else_goes_back_at_its_first_operational_heartbeat() {
    let (mut s, p) = running();
    commands(&mut s);
    events(&mut s);
    s.heartbeat(ms(25), A, NmtState::Operational);
    s.heartbeat(ms(26), B, NmtState::PreOperational);
    // A rogue start: B's heartbeat says operational while A is alive.
    s.heartbeat(ms(30), B, NmtState::Operational);
    assert_eq!(nmts(&mut s), [(NmtCommand::EnterPreOperational, 0x11)]);
    // A heartbeat sent before the command arrived says operational still: nothing more.
    s.heartbeat(ms(31), B, NmtState::Operational);
    assert!(commands(&mut s).is_empty());
    s.heartbeat(ms(45), A, NmtState::Operational);
    s.heartbeat(ms(50), B, NmtState::PreOperational);
    // Started again later: sent back again.
    s.heartbeat(ms(60), B, NmtState::Operational);
    assert_eq!(nmts(&mut s), [(NmtCommand::EnterPreOperational, 0x11)]);
    s.heartbeat(ms(65), A, NmtState::Operational);
    s.heartbeat(ms(70), B, NmtState::PreOperational);
    // The application starts B through this master: both may run.
    s.application_nmt(NmtCommand::Start, 0x11);
    s.heartbeat(ms(80), B, NmtState::Operational);
    assert!(commands(&mut s).is_empty());
    // A switch-over by this table: the old active's heartbeat in flight says operational; no
    // command but the switch's own.
    s.heartbeat(ms(85), A, NmtState::Operational);
    s.switch_over(ms(90), p, Member::B).unwrap();
    assert_eq!(
        nmts(&mut s),
        [
            (NmtCommand::Start, 0x11),
            (NmtCommand::EnterPreOperational, 0x10)
        ],
        "B runs already, started all the same (harmless to it), first"
    );
    s.heartbeat(ms(91), A, NmtState::Operational);
    assert!(commands(&mut s).is_empty());
    // A, now the standby, started by someone else: back.
    s.heartbeat(ms(100), B, NmtState::Operational);
    s.heartbeat(ms(105), A, NmtState::PreOperational);
    s.heartbeat(ms(110), A, NmtState::Operational);
    assert_eq!(nmts(&mut s), [(NmtCommand::EnterPreOperational, 0x10)]);
    // Not while the active member is silent: then the standby running is the remedy, and the
    // silence is handled at its deadline.
    let (mut s, _) = running();
    commands(&mut s);
    s.heartbeat(ms(26), B, NmtState::PreOperational);
    s.heartbeat(ms(56), B, NmtState::Operational);
    assert!(commands(&mut s).is_empty(), "A's deadline was 55 ms");
}

proptest! {
    /// Whatever the observations and verdicts, with a commanding table: a suspect member is
    /// never joined nor active once the instant is handled, and no start goes to it but the
    /// last resort's (its heartbeats shared, the pair without an active member).
    #[test]
    fn a_suspect_member_never_runs_for_the_table(
        ops in prop::collection::vec((0u8..9, any::<bool>(), 1u64..40), 1..200)
    ) {
        let (mut s, p) = table(PairsConfig::default());
        let mut t = ms(0);
        for (op, which, dt) in ops {
            t += Duration::from_millis(dt);
            let n = if which { A } else { B };
            match op {
                5 => s.suspect(t, n, true, false),
                6 => s.suspect(t, n, false, false),
                8 => s.suspect(t, n, true, true),
                op => observe(&mut s, op, n, t),
            }
            s.handle_timeout(t);
            let st = *s.pair(p).unwrap();
            for m in [Member::A, Member::B] {
                let node: NodeId = st.spec.node(m);
                if s.is_suspect(node) {
                    prop_assert!(!st.member(m).joined(), "{m} joined while suspect");
                    prop_assert_ne!(st.active, Some(m));
                }
            }
            for c in commands(&mut s) {
                if let PairCommand::Nmt { cmd: NmtCommand::Start, node } = c {
                    // Only the last resort starts one: a member a second device shares
                    // heartbeats with, in a pair that has no active member.
                    prop_assert!(
                        !s.is_suspect(node) || (s.is_duplicated(node) && s.pair(p).unwrap().active.is_none()),
                        "start of a suspect member"
                    );
                }
            }
        }
    }
}

#[test]
fn a_member_made_active_is_started_even_when_a_heartbeat_says_it_runs() {
    // A board boots and is configured while a second device with its node-ID, not yet found
    // out, beats "operational": the board itself is pre-operational and only a start runs it
    // (campaign seed 129: without the start the pair had no running board for 0.4 s at a
    // time).
    let (mut s, p) = table(PairsConfig::default());
    s.boot_up(ms(0), A);
    commands(&mut s);
    s.heartbeat(ms(5), A, NmtState::Operational);
    s.configured(ms(10), A, true);
    assert_eq!(nmts(&mut s), [(NmtCommand::Start, 0x10)]);
    assert_eq!(s.pair(p).unwrap().active, Some(Member::A));
    // Its own heartbeat sent before the start arrived says pre-operational: no failure.
    s.heartbeat(ms(20), A, NmtState::PreOperational);
    assert!(commands(&mut s).is_empty());
    s.heartbeat(ms(30), A, NmtState::Operational);
    s.heartbeat(ms(50), A, NmtState::Operational);
    assert!(commands(&mut s).is_empty());
    assert_eq!(s.pair(p).unwrap().active, Some(Member::A));
}
