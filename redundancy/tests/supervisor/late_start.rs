//! A pair's last member started while its start reaches it late (its receive path running
//! behind past the consumer time): heard alive but not running at its deadline, it is started
//! once more and given one more consumer time, not reset (campaign seed 179: a reset left the
//! pair without a board for 0.4 s). With a live standby it is replaced at that deadline, as
//! before; one still not running after the second start fails.

use crate::pairs::{commands, events, ms, nmts, roles, table, A, B};
use duocan::{NmtCommand, NmtState};
use duocan_redundancy::supervisor::pairs::{PairsConfig, RoleReason};
use duocan_redundancy::Member;

/// A active (started at 5 ms, heard running), B standby beating; A dies after its heartbeat at
/// 25 ms,
/// B is started at A's deadline (75 ms) and, its start reaching it `late`, beats
/// pre-operational until then. B's heartbeats at 81, 101, … as `runs_from` says.
fn b_started_late(
    runs_from: u64,
) -> (
    duocan_redundancy::supervisor::pairs::PairSupervisor,
    duocan_redundancy::PairId,
) {
    let (mut s, p) = table(PairsConfig::default());
    s.boot_up(ms(0), A);
    s.boot_up(ms(0), B);
    s.configured(ms(5), A, true);
    s.configured(ms(6), B, true);
    s.heartbeat(ms(12), A, NmtState::Operational);
    s.heartbeat(ms(25), A, NmtState::Operational);
    for t in [13, 33, 53, 73] {
        s.heartbeat(ms(t), B, NmtState::PreOperational);
    }
    commands(&mut s);
    s.handle_timeout(ms(75));
    assert_eq!(
        nmts(&mut s),
        [(NmtCommand::Start, 0x11), (NmtCommand::ResetNode, 0x10)]
    );
    events(&mut s);
    for t in (81..400).step_by(20) {
        let state = if t >= runs_from {
            NmtState::Operational
        } else {
            NmtState::PreOperational
        };
        s.handle_timeout(ms(t) - duocan::Duration::from_micros(1));
        s.heartbeat(ms(t), B, state);
    }
    (s, p)
}

#[test]
fn the_last_member_not_running_at_its_deadline_is_started_again_not_reset() {
    // B's start reaches it 55 ms late: operational from its heartbeat at 141 ms on.
    let (mut s, p) = b_started_late(141);
    // At B's deadline (75 + 50 = 125 ms) it was heard alive, pre-operational: started again.
    let cmds = nmts(&mut s);
    assert_eq!(
        cmds,
        [(NmtCommand::Start, 0x11)],
        "a second start, no reset"
    );
    assert_eq!(s.pair(p).unwrap().active, Some(Member::B));
    assert!(roles(&mut s).is_empty());
}

#[test]
fn one_still_not_running_after_its_second_start_fails_then() {
    let (mut s, p) = b_started_late(u64::MAX);
    // Started again at 125 ms; not running at 125 + 50 = 175 ms: reset then, once.
    let cmds = nmts(&mut s);
    assert_eq!(
        cmds,
        [(NmtCommand::Start, 0x11), (NmtCommand::ResetNode, 0x11)]
    );
    assert_eq!(s.pair(p).unwrap().active, None);
    assert_eq!(
        roles(&mut s),
        [(
            ms(175),
            Some(Member::B),
            None,
            RoleReason::ActiveNotOperational {
                state: NmtState::PreOperational
            }
        )]
    );
}
