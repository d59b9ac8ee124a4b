//! Heartbeat-only error control on CAN FD buses: the supervised network of `net.rs` on FD
//! buses (1 Mbit/s nominal, 2 Mbit/s data, the members of every pair sending FD process data
//! on every SYNC), where node guarding cannot run (no remote frames; the rig's masters pass
//! `Supervisor::check_fd`). The dual-bus layers' port self-diagnosis, their plausibility watch
//! and the pair failover work from heartbeats alone, at the instants the classic twin of the
//! test (the same scenario on classic buses) gives:
//!
//! - bus 2's transceiver of board B, the standby of pair 0, dies (its port unplugged, nothing
//!   reported): the board's own layer fails that port (its sends unacknowledged, the bus
//!   silent), the masters' ports stay ok and hear B on bus 1 only; the plausibility watch
//!   makes B suspect exactly one reachability window after its last heartbeat on bus 2 (rule
//!   2, "on one bus only": seen from the masters, what an impostor on bus 1 would be), so it is
//!   reset as a failed standby, and rejoins; the pair stays up, A active throughout, its FD
//!   process data delivered once;
//! - then A dies: B, on bus 1 alone, is started exactly the consumer time after A's last
//!   heartbeat, on the bus within a millisecond, and its FD process data delivered from then.

use crate::impostor::{arrivals, suspects_of};
use crate::net::*;
use duocan::machine::StationEvent;
use duocan::{Duration, Instant, NmtCommand, NodeId};
use duocan_redundancy::supervisor::pairs::{PairsEvent, RoleReason};
use duocan_redundancy::{LinkEventKind, Member, PairId, PortState, SupervisorEvent, Suspicion};

const CONSUMER: Duration = Duration::from_millis(50);
/// The layer's reachability window: 3 guarding periods of 20 ms.
const WINDOW: Duration = Duration::from_millis(60);
const ONE_MS: Duration = Duration::from_millis(1);

fn ms(x: u64) -> Instant {
    Instant::from_millis(x)
}

#[test]
fn on_fd_buses_a_dead_transceiver_fails_its_port_the_pair_stays_up_and_a_dead_board_fails_over_on_time(
) {
    let classic = transceiver_then_board(Params::default());
    let fd = transceiver_then_board(Params::default().on_fd(2_000_000, 4));
    // The same verdicts at the same instants, relative to the heartbeats they judge.
    assert_eq!(fd, classic);
}

/// The scenario on `p`'s buses; returns (B suspect − B's last heartbeat on bus 2, B's start −
/// A's last heartbeat).
fn transceiver_then_board(p: Params) -> (Duration, Duration) {
    let mut n = SupNet::new(p);
    for m in [STRONG, WEAK] {
        n.sup(m).check_fd().expect("heartbeats only");
    }
    let port = n.slave(b(0)).port(1);
    n.sim.at(ms(1003), move |sim| sim.disconnect(port));
    n.kill_slave_at(a(0), ms(1503));
    n.sim.run_until(ms(1500));

    // The board's own layer: bus 2 failed, bus 1 working.
    let board = n.sim.device(n.slave(b(0)));
    assert_eq!(board.link.port_state(0), PortState::Ok);
    assert_ne!(board.link.port_state(1), PortState::Ok);
    let changes: Vec<_> = n
        .sim
        .events(n.slave(b(0)))
        .iter()
        .filter_map(|(_, e)| match e {
            StationEvent::Link(l) => match l.kind {
                LinkEventKind::Port { port, to, .. } => Some((l.at, port, to)),
                _ => None,
            },
            _ => None,
        })
        .collect();
    assert!(
        changes
            .iter()
            .any(|&(at, port, to)| port == 1 && to == PortState::Failed && at > ms(1003)),
        "{changes:?}"
    );
    assert!(changes.iter().all(|&(_, port, _)| port == 1), "{changes:?}");
    // The masters: both buses working (every other device beats on both), B heard on bus 1
    // only and suspect exactly one window after its last heartbeat on bus 2.
    let h = *arrivals(&n, 1, 0x700 + b(0) as u16)
        .iter()
        .rfind(|t| **t < ms(1003))
        .unwrap();
    for m in [STRONG, WEAK] {
        let st = n.sim.device(n.master(m));
        assert_eq!(st.link.port_state(0), PortState::Ok, "master {m}");
        assert_eq!(st.link.port_state(1), PortState::Ok, "master {m}");
        assert_eq!(
            st.link.reach().heard(NodeId::must(b(0))),
            Some([true, false]),
            "master {m}"
        );
        assert_eq!(
            suspects_of(&n, m, b(0)).first(),
            Some(&(h + WINDOW, Suspicion::OneBus { heard: 0 })),
            "master {m}"
        );
    }
    let suspect = suspects_of(&n, STRONG, b(0))[0].0;
    // The strong master reset B, the failed standby, at the verdict; B rejoined (its new life
    // began with a boot-up: judged again once heard on both buses). A ran throughout.
    let lost: Vec<_> = n
        .sup_events(STRONG)
        .into_iter()
        .filter_map(|e| match e {
            SupervisorEvent::Pairs(PairsEvent::Lost { at, node, .. }) => Some((at, node.raw())),
            _ => None,
        })
        .collect();
    assert_eq!(lost, [(h + WINDOW, b(0))]);
    let nmt: Vec<_> = n
        .nmt_first_copies()
        .into_iter()
        .filter(|x| x.0 > ms(1000))
        .map(|x| (x.1, x.2, x.3))
        .collect();
    assert_eq!(nmt, [(STRONG, NmtCommand::ResetNode, b(0))]);
    for m in [STRONG, WEAK] {
        assert_eq!(n.active_member(m, 0), Some(Member::A), "master {m}");
        assert_eq!(n.pair_roles(m, 0).len(), 1, "master {m}");
    }
    let pair = *n.sup(STRONG).pair_supervisor().pair(PairId(0)).unwrap();
    assert!(pair.member(Member::A).joined() && pair.member(Member::B).joined());
    assert!(!n
        .sup(STRONG)
        .pair_supervisor()
        .is_suspect(NodeId::must(b(0))));

    // A dies: its last heartbeat + the consumer time, B started on bus 1 alone.
    n.sim.run_until(ms(2500));
    let last = n.last_heartbeat(a(0), ms(1503));
    let deadline = last + CONSUMER;
    let nmt: Vec<_> = n
        .nmt_first_copies()
        .into_iter()
        .filter(|x| x.0 > ms(1500))
        .collect();
    assert_eq!(
        nmt.iter().map(|x| (x.1, x.2, x.3)).collect::<Vec<_>>(),
        [
            (STRONG, NmtCommand::Start, b(0)),
            (STRONG, NmtCommand::ResetNode, a(0))
        ]
    );
    assert!(
        nmt[0].0 > deadline && nmt[0].0 <= deadline + ONE_MS,
        "{:?} vs {deadline}",
        nmt[0]
    );
    let roles = n.pair_roles(STRONG, 0);
    assert_eq!(roles.len(), 2);
    assert_eq!(roles[1].at, deadline);
    assert_eq!(
        (roles[1].from, roles[1].to, roles[1].reason),
        (
            Some(Member::A),
            Some(Member::B),
            RoleReason::ActiveSilent { last }
        )
    );
    assert_eq!(n.active_member(WEAK, 0), Some(Member::B));
    // A's FD process data until it died, then B's, each once at both masters.
    for m in [STRONG, WEAK] {
        let [from_a, from_b] = n.assert_fd_exactly_once(m, 0, ms(2500));
        if p.fd.is_some() {
            assert!(from_a > 60 && from_b > 80, "master {m}: {from_a} {from_b}");
        }
    }
    (suspect - h, nmt[0].0 - last)
}
