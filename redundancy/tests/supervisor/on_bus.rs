//! Slave-pair supervision on the simulated dual bus, with the NMT frames on the wire: the published
//! design's cases at exact instants. Slaves beat every 20 ms; consumer time 50 ms; 1 Mbit/s.

use crate::net::*;
use duocan::{Duration, Instant, NmtCommand};
use duocan_redundancy::supervisor::flying_master::MasterRole;
use duocan_redundancy::supervisor::pairs::{PairsEvent, RoleReason};
use duocan_redundancy::{Member, PairId, SupervisorEvent};

const CONSUMER: Duration = Duration::from_millis(50);
const ONE_MS: Duration = Duration::from_millis(1);

fn ms(x: u64) -> Instant {
    Instant::from_millis(x)
}

/// NMT commands (first copies) after `from`: (end, command, target).
fn nmt_after(n: &SupNet, from: Instant) -> Vec<(Instant, NmtCommand, u8)> {
    n.nmt_first_copies()
        .into_iter()
        .filter(|x| x.0 > from)
        .map(|(t, s, c, node)| {
            assert_eq!(s, STRONG, "only the active master commands");
            (t, c, node)
        })
        .collect()
}

#[test]
fn start_up_strong_master_active_first_members_active_weak_shadows() {
    let mut n = SupNet::new(Params::default());
    n.sim.run_until(ms(2000));
    assert_eq!(n.role(STRONG), MasterRole::Active);
    assert!(matches!(n.role(WEAK), MasterRole::Standby(Some(_))));
    for i in 0..4 {
        assert_eq!(n.active_member(STRONG, i), Some(Member::A), "pair {i}");
        assert_eq!(n.active_member(WEAK, i), Some(Member::A), "pair {i}");
        let r = n.pair_roles(STRONG, i);
        assert_eq!(r.len(), 1);
        assert_eq!(r[0].reason, RoleReason::FirstJoined);
    }
    // The strong master won the power-on negotiation at 610 ms and started the A boards.
    let nmt = nmt_after(&n, Instant::ZERO);
    assert_eq!(
        nmt.iter().map(|x| (x.1, x.2)).collect::<Vec<_>>(),
        (0..4)
            .map(|i| (NmtCommand::Start, a(i)))
            .collect::<Vec<_>>()
    );
    assert!(nmt.iter().all(|x| x.0 > ms(610) && x.0 < ms(615)));
    let status = n.sim.device(n.master(STRONG)).status(ms(2000)).to_string();
    assert!(status.contains("master node 0x01 (0): active"), "{status}");
    assert!(
        status.contains(
            "0     A       0x10    operational      joined       0x50    pre-operational  joined"
        ),
        "{status}"
    );
}

#[test]
fn active_member_killed_standby_started_within_consumer_time_plus_1ms_then_rejoins_as_standby() {
    active_member_killed(Params::default());
}

/// The same on CAN FD buses (1 Mbit/s nominal, 2 Mbit/s data), every member sending a 64-byte
/// FD frame on every SYNC: the same instants (heartbeats, classic frames, still drive the
/// supervisor), and the masters' layers deliver A's process data until the switch and B's
/// from then on, each frame once.
#[test]
fn on_fd_buses_active_member_killed_standby_started_and_its_fd_process_data_delivered_once() {
    active_member_killed(Params::default().on_fd(2_000_000, 4));
}

fn active_member_killed(p: Params) {
    let mut n = SupNet::new(p);
    n.kill_slave_at(a(0), ms(1003));
    n.revive_slave_at(a(0), ms(1500));
    n.sim.run_until(ms(2500));
    let last = n.last_heartbeat(a(0), ms(1003));
    let deadline = last + CONSUMER;
    let nmt = nmt_after(&n, ms(1000));
    // At the deadline: start B (on the bus within one frame), then reset A.
    assert_eq!(nmt[0].1, NmtCommand::Start);
    assert_eq!(nmt[0].2, b(0));
    assert!(
        nmt[0].0 > deadline && nmt[0].0 <= deadline + ONE_MS,
        "{:?} vs {deadline}",
        nmt[0]
    );
    assert_eq!((nmt[1].1, nmt[1].2), (NmtCommand::ResetNode, a(0)));
    assert!(nmt[1].0 <= deadline + ONE_MS);
    // A was dead: nothing more. It rejoins as standby (configured, not started: non-revertive).
    assert_eq!(nmt.len(), 2, "{nmt:?}");
    let roles = n.pair_roles(STRONG, 0);
    assert_eq!(roles.len(), 2);
    assert_eq!(roles[1].at, deadline);
    assert_eq!(
        (roles[1].from, roles[1].to),
        (Some(Member::A), Some(Member::B))
    );
    assert_eq!(roles[1].reason, RoleReason::ActiveSilent { last });
    assert_eq!(n.active_member(STRONG, 0), Some(Member::B));
    let pair = *n.sup(STRONG).pair_supervisor().pair(PairId(0)).unwrap();
    assert!(pair.member(Member::A).joined());
    assert_eq!(
        pair.member(Member::A).nmt,
        Some(duocan::NmtState::PreOperational)
    );
    // Revived at a SYNC: on FD buses its boot-up waits behind that SYNC's process data.
    assert!(n
        .boot_ups_in(ms(1500), ms(1501) + p.fd_burst())
        .contains(&a(0)));
    // The weak master followed from the NMT commands on the wire.
    assert_eq!(n.active_member(WEAK, 0), Some(Member::B));
    let w = n.pair_roles(WEAK, 0);
    assert_eq!(w.last().unwrap().to, Some(Member::B));
    assert_eq!(w.last().unwrap().reason, RoleReason::Observed);
    // The dual-bus layer of both masters delivers B's process data.
    for m in [STRONG, WEAK] {
        assert_eq!(
            n.sim.device(n.master(m)).link.pairs().active(PairId(0)),
            Some(Member::B),
            "master {m}"
        );
    }
    // The audit trail has the change with its reason and time.
    let mut text = String::new();
    n.sup(STRONG).audit().write_text(&mut text).unwrap();
    assert!(
        text.contains("active A -> B: active member silent since"),
        "{text}"
    );
    for m in [STRONG, WEAK] {
        let [from_a, from_b] = n.assert_fd_exactly_once(m, 0, ms(2500));
        let [steady, none] = n.assert_fd_exactly_once(m, 1, ms(2500));
        if p.fd.is_some() {
            // A's until it died (about 40 cycles from the start at 610 ms), B's from the switch
            // at about 1.05 s to the end (about 140 cycles); pair 1 A's all along.
            assert!(from_a > 30 && from_b > 130, "master {m}: {from_a} {from_b}");
            assert!(steady > 180 && none == 0, "master {m}: {steady} {none}");
        } else {
            assert_eq!([from_a, from_b, steady, none], [0; 4]);
        }
    }
}

#[test]
fn standby_killed_is_reset_the_active_keeps_running() {
    let mut n = SupNet::new(Params::default());
    n.kill_slave_at(b(1), ms(1007));
    n.sim.run_until(ms(1500));
    let deadline = n.last_heartbeat(b(1), ms(1007)) + CONSUMER;
    let nmt = nmt_after(&n, ms(1000));
    assert_eq!(nmt.len(), 1);
    assert_eq!((nmt[0].1, nmt[0].2), (NmtCommand::ResetNode, b(1)));
    assert!(nmt[0].0 > deadline && nmt[0].0 <= deadline + ONE_MS);
    assert_eq!(n.active_member(STRONG, 1), Some(Member::A));
    assert_eq!(n.pair_roles(STRONG, 1).len(), 1);
    let lost = n.sup_events(STRONG).into_iter().any(|e| {
        matches!(e, SupervisorEvent::Pairs(PairsEvent::Lost { at, node, .. }) if at == deadline && node.raw() == b(1))
    });
    assert!(lost);
}

#[test]
fn both_killed_both_reset_no_active_member() {
    let mut n = SupNet::new(Params::default());
    n.kill_slave_at(a(2), ms(1011));
    n.kill_slave_at(b(2), ms(1011));
    n.sim.run_until(ms(1500));
    let da = n.last_heartbeat(a(2), ms(1011)) + CONSUMER;
    let db = n.last_heartbeat(b(2), ms(1011)) + CONSUMER;
    let nmt: Vec<_> = nmt_after(&n, ms(1000))
        .into_iter()
        .filter(|x| x.1 == NmtCommand::ResetNode)
        .collect();
    assert_eq!(nmt.len(), 2, "{nmt:?}");
    for (node, d) in [(a(2), da), (b(2), db)] {
        let r = nmt.iter().find(|x| x.2 == node).unwrap();
        assert!(r.0 > d && r.0 <= d + ONE_MS, "{r:?} {d}");
    }
    assert_eq!(n.active_member(STRONG, 2), None);
    assert_eq!(n.active_member(WEAK, 2), None);
    // A start of B may precede its own reset when A's deadline came first (B was still alive
    // then); never a start after both deadlines.
    let last_deadline = da.max(db);
    assert!(nmt_after(&n, last_deadline + ONE_MS).is_empty());
}

#[test]
fn configured_member_that_never_boots_is_reported_missing_and_never_commanded() {
    let mut n = SupNet::new(Params::default());
    // B of pair 3 is dead from the start.
    n.kill_slave_at(b(3), Instant::ZERO);
    n.sim.run_until(ms(7000));
    assert_eq!(n.active_member(STRONG, 3), Some(Member::A));
    let missing: Vec<_> = n
        .sup_events(STRONG)
        .into_iter()
        .filter_map(|e| match e {
            SupervisorEvent::Pairs(PairsEvent::Missing { at, node, .. }) => Some((at, node.raw())),
            _ => None,
        })
        .collect();
    // Awaited from power-on: 5 s boot timeout.
    assert_eq!(missing, [(ms(5000), b(3))]);
    assert!(n.nmt_first_copies().iter().all(|x| x.3 != b(3)));
    let status = n.sim.device(n.master(STRONG)).status(ms(7000)).to_string();
    assert!(
        status.contains("0x53    unknown          missing"),
        "{status}"
    );
}
