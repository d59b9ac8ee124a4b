//! Both buses cut between the two masters, each side keeping some slaves; then healed. Exactly
//! one active master within one detect cycle, no slave commanded by two masters in the overlap,
//! and every pair converges to one running member.

use crate::net::*;
use duocan::sim::{PortRef, TraceRecord, TxOutcome};
use duocan::{Duration, Id, Instant, NmtCommand, NmtState};
use duocan_redundancy::supervisor::flying_master::{MasterReason, MasterRole};
use duocan_redundancy::Member;

const CUT: Instant = Instant::from_millis(1003);
const HEAL: Instant = Instant::from_millis(2003);
const DETECT_CYCLE: Duration = Duration::from_millis(4000);

/// Strong side: both members of pair 0, A of pair 2, B of pair 3. Weak side: the rest.
fn sides() -> (Vec<u8>, Vec<u8>) {
    (
        vec![STRONG, a(0), b(0), a(2), b(3)],
        vec![WEAK, a(1), b(1), b(2), a(3)],
    )
}

fn ports(n: &SupNet, nodes: &[u8], port: usize) -> Vec<PortRef> {
    nodes
        .iter()
        .map(|&id| match id {
            STRONG | WEAK => n.master(id).port(port),
            s => n.slave(s).port(port),
        })
        .collect()
}

/// NMT commands that reached each slave: (end, sender, command), computed from the segments.
fn nmt_reaching(n: &SupNet, slave: u8) -> Vec<(Instant, u8, NmtCommand)> {
    let (strong_side, _) = sides();
    let mine = if strong_side.contains(&slave) { 1 } else { 2 };
    let mut v = vec![];
    for r in n.sim.trace() {
        let TraceRecord::Tx(x) = r else { continue };
        if !matches!(x.outcome, TxOutcome::Delivered { .. }) || x.frame.id() != Id::Standard(0) {
            continue;
        }
        let partitioned = x.end > CUT && x.start < HEAL;
        if partitioned && x.segment != mine {
            continue;
        }
        let Ok((cmd, target)) = duocan::nmt::parse_command(&x.frame) else {
            continue;
        };
        if target == slave || target == 0 {
            let sender = if x.sender.device == n.master(STRONG).erased() {
                STRONG
            } else {
                WEAK
            };
            v.push((x.end, sender, cmd));
        }
    }
    v
}

#[test]
fn partition_between_the_masters_then_heal() {
    let mut n = SupNet::new(Params::default());
    let (s, w) = sides();
    let groups: Vec<[Vec<PortRef>; 2]> = (0..2)
        .map(|p| [ports(&n, &s, p), ports(&n, &w, p)])
        .collect();
    let buses = n.buses;
    let g = groups.clone();
    n.sim.at(CUT, move |sim| {
        for (bus, g) in buses.iter().zip(&g) {
            sim.partition(*bus, &[&g[0], &g[1]]);
        }
    });
    n.sim.at(HEAL, move |sim| {
        for bus in buses {
            sim.heal(bus);
        }
    });
    n.sim.run_until(HEAL);
    // Behind the partition, both are active.
    assert_eq!(n.role(STRONG), MasterRole::Active);
    assert_eq!(n.role(WEAK), MasterRole::Active);
    n.sim.run_until(HEAL + DETECT_CYCLE);

    // Exactly one active master again, within one detect cycle of the heal.
    assert_eq!(n.role(STRONG), MasterRole::Active);
    assert!(matches!(n.role(WEAK), MasterRole::Standby(Some(r)) if r.node.raw() == STRONG));
    let demoted = n
        .master_roles(WEAK)
        .into_iter()
        .rfind(|r| r.from == MasterRole::Active)
        .unwrap();
    assert!(demoted.at > HEAL && demoted.at < HEAL + DETECT_CYCLE);
    assert!(matches!(demoted.reason, MasterReason::ConflictLost(_)));
    // In practice: within one master heartbeat period of the heal.
    assert!(
        demoted.at < HEAL + Duration::from_millis(21),
        "{}",
        demoted.at
    );

    // No slave got NMT commands from both masters between the cut and the resolution.
    for i in 0..4 {
        for slave in [a(i), b(i)] {
            let cmds: Vec<_> = nmt_reaching(&n, slave)
                .into_iter()
                .filter(|c| c.0 > CUT && c.0 <= demoted.at)
                .collect();
            let senders: std::collections::BTreeSet<u8> = cmds.iter().map(|c| c.1).collect();
            assert!(senders.len() <= 1, "slave {slave:#x}: {cmds:?}");
        }
    }
    // The check above is not vacuous: during the partition each side commanded its slaves.
    let during: Vec<_> = (0..4)
        .flat_map(|i| [a(i), b(i)])
        .flat_map(|sl| nmt_reaching(&n, sl))
        .filter(|c| c.0 > CUT && c.0 < HEAL)
        .collect();
    assert!(during
        .iter()
        .any(|c| c.1 == WEAK && c.2 == NmtCommand::Start));
    assert!(during
        .iter()
        .any(|c| c.1 == STRONG && c.2 == NmtCommand::Start));
    // Nothing was reset after the heal: the healed members were adopted, not rebooted.
    assert!(n.boot_ups_in(HEAL, HEAL + DETECT_CYCLE).is_empty());

    // Every pair: exactly one member running, the one both masters' tables name.
    for i in 0..4 {
        let states: Vec<NmtState> = [a(i), b(i)]
            .iter()
            .map(|id| n.sim.device(n.slave(*id)).machine.nmt_state())
            .collect();
        let running: Vec<Member> = [Member::A, Member::B]
            .into_iter()
            .zip(&states)
            .filter(|(_, s)| **s == NmtState::Operational)
            .map(|(m, _)| m)
            .collect();
        assert_eq!(running.len(), 1, "pair {i}: {states:?}");
        assert_eq!(n.active_member(STRONG, i), Some(running[0]), "pair {i}");
        assert_eq!(n.active_member(WEAK, i), Some(running[0]), "pair {i}");
    }
}
