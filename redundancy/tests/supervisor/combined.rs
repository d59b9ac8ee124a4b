//! Combined faults in every order: bus 1 cut, the active member of a pair killed, the strong
//! master killed. The system converges to one active master and one running member per pair.
//! On classic buses, and on CAN FD buses with FD process data flowing throughout.

use crate::net::*;
use duocan::{Duration, Instant, NmtState};
use duocan_redundancy::supervisor::flying_master::MasterRole;
use duocan_redundancy::Member;

#[derive(Clone, Copy, Debug)]
enum Fault {
    CutBus1,
    KillActiveSlave,
    KillStrong,
}

fn classic() -> Params {
    Params {
        pairs: 6,
        ..Params::default()
    }
}

fn run(order: [Fault; 3], spacing: Duration) {
    run_on(classic(), order, spacing);
}

fn run_on(p: Params, order: [Fault; 3], spacing: Duration) {
    let mut n = SupNet::new(p);
    let mut t = Instant::from_millis(1000);
    for f in order {
        match f {
            Fault::CutBus1 => {
                let b = n.buses[0];
                n.sim.at(t, move |sim| sim.bus_down(b));
            }
            Fault::KillActiveSlave => n.kill_slave_at(a(2), t),
            Fault::KillStrong => n.kill_master_at(STRONG, t),
        }
        t += spacing;
    }
    n.sim.run_until(t + Duration::from_millis(1500));
    let ctx = format!("{order:?} every {spacing}");
    assert_eq!(n.role(WEAK), MasterRole::Active, "{ctx}");
    for i in 0..6 {
        let want = if i == 2 { Member::B } else { Member::A };
        assert_eq!(n.active_member(WEAK, i), Some(want), "{ctx}: pair {i}");
        for (m, id) in [(Member::A, a(i)), (Member::B, b(i))] {
            if i == 2 && m == Member::A {
                continue;
            }
            let st = n.sim.device(n.slave(id)).machine.nmt_state();
            let want = if m == want {
                NmtState::Operational
            } else {
                NmtState::PreOperational
            };
            assert_eq!(st, want, "{ctx}: node {id:#x}");
        }
    }
    // Only the failed slave was reset; nobody rebooted.
    assert_eq!(
        n.resets_in(Instant::from_millis(1000), t + Duration::from_secs(2)),
        [a(2)],
        "{ctx}"
    );
    // The weak master's FD process data, through the bus cut, the takeover and pair 2's
    // switch: the active member's frames, each once (none on classic buses).
    for i in 0..6 {
        let [from_a, from_b] = n.assert_fd_exactly_once(WEAK, i, t + Duration::from_millis(1500));
        match (p.fd.is_some(), i) {
            (false, _) => assert_eq!([from_a, from_b], [0, 0], "{ctx}"),
            (true, 2) => assert!(from_a > 30 && from_b > 100, "{ctx}: {from_a} {from_b}"),
            (true, _) => assert!(from_a > 180 && from_b == 0, "{ctx}: {from_a} {from_b}"),
        }
    }
}

const ORDERS: [[Fault; 3]; 6] = [
    [Fault::CutBus1, Fault::KillActiveSlave, Fault::KillStrong],
    [Fault::CutBus1, Fault::KillStrong, Fault::KillActiveSlave],
    [Fault::KillActiveSlave, Fault::CutBus1, Fault::KillStrong],
    [Fault::KillActiveSlave, Fault::KillStrong, Fault::CutBus1],
    [Fault::KillStrong, Fault::CutBus1, Fault::KillActiveSlave],
    [Fault::KillStrong, Fault::KillActiveSlave, Fault::CutBus1],
];

#[test]
fn every_order_well_apart() {
    for o in ORDERS {
        run(o, Duration::from_millis(300));
    }
}

#[test]
fn every_order_within_one_timeout() {
    for o in ORDERS {
        run(o, Duration::from_millis(17));
    }
}

/// On CAN FD buses (1 Mbit/s nominal, 2 Mbit/s data), every member sending a 64-byte FD frame
/// on every SYNC.
#[test]
fn on_fd_buses_every_order_within_one_timeout() {
    for o in ORDERS {
        run_on(classic().on_fd(2_000_000, 6), o, Duration::from_millis(17));
    }
}

#[test]
fn all_at_once() {
    for o in ORDERS {
        run(o, Duration::ZERO);
    }
}
