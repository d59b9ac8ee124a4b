//! Fastscan after a stray scan answer (a late copy from the other bus, as a busy dual-port slave
//! writes them): the scan notices at the confirmation or the configure node-ID step, starts
//! over, and still gives every slave the node-ID the plan has for it, at the protocol's cost
//! plus exactly what the attempts given up cost.

use super::fastscan::{cfg, cost, counts};
use super::wire::{addr, ans, slave, Wire};
use duocan::cia305::{
    fastscan::RESTARTS, LssAddress, LssError, LssMaster, LssMasterEventKind as K, LssMode, LssPlan,
};
use duocan::{Instant, NodeId};

/// A slave's scan answer that no slave sent for this step.
fn stray() -> duocan::Frame {
    ans([0x4F, 0, 0, 0, 0, 0, 0, 0])
}

/// An unconfigured slave (serial 0x100) and a fastscan for the one node-ID 1, started at 0.
fn one_slave_scan() -> (Wire, LssAddress) {
    let a = addr(0x2A, 7, 1, 0x100);
    let mut w = Wire::new(LssMaster::new(cfg()), vec![slave(a, 0xFF)]);
    let plan = LssPlan::new().with_free([NodeId::must(1)]);
    w.master.fastscan(Instant::ZERO, plan).unwrap();
    (w, a)
}

/// Runs the scan to its end with a stray after each request `inject` picks.
fn run(w: &mut Wire, mut inject: impl FnMut(&[u8]) -> bool) {
    w.run_with(5000, |d| inject(d).then(stray));
}

/// The fastscan request testing bit `bit` of identity part `sub`.
fn bit_step(data: &[u8], sub: u8, bit: u8) -> bool {
    data[0] == 0x51 && data[5] == bit && data[6] == sub
}

#[test]
fn a_stray_answer_in_an_unanswered_bit_step_costs_one_restart_not_the_scan() {
    // Product 7: bits 2..0 are ones, so nobody answers their steps.
    let (a, b) = (addr(0x2A, 7, 1, 0x100), addr(0x2A, 7, 1, 0x101));
    let mut w = Wire::new(LssMaster::new(cfg()), vec![slave(b, 0xFF), slave(a, 0xFF)]);
    let plan = LssPlan::new()
        .with_identity(a, NodeId::must(10))
        .with_free([NodeId::must(11)]);
    w.master.fastscan(Instant::ZERO, plan).unwrap();
    let mut once = true;
    run(&mut w, |d| {
        let hit = once && bit_step(d, 1, 1);
        once &= !hit;
        hit
    });
    assert!(!once, "the stray was given");
    let n = NodeId::must;
    assert_eq!(
        w.take_events(),
        [
            K::ScanRestarted { sub: 1 },
            K::Found(a),
            K::Assigned {
                address: a,
                node: n(10)
            },
            K::Found(b),
            K::Assigned {
                address: b,
                node: n(11)
            },
            K::ScanFinished { assigned: 2 },
        ]
    );
    let ids: Vec<_> = w
        .slaves
        .iter()
        .map(|s| s.node_id().map(|n| n.raw()))
        .collect();
    assert_eq!(ids, [Some(11), Some(10)]);
    assert!(w.slaves.iter().all(|s| s.mode() == LssMode::Waiting));
    // The attempt given up: its reset, the vendor's 32 bits and confirmation, the product's
    // 32 bits and confirmation, and the switch back to waiting.
    let stats = w.master.stats();
    assert_eq!((stats.restarts, stats.abandoned), (1, 1 + 33 + 33 + 1));
    let (req, _, _) = counts(&w);
    let (predicted, _, _) = cost(&[a, b], cfg().timeout, cfg().settle, false);
    assert_eq!(req, predicted + stats.abandoned);
}

#[test]
fn a_false_confirmation_of_the_serial_number_is_caught_at_the_configure_step() {
    // Serial 0x100: bit 0 is 0 (answered), bit 1 is 0 ... the stray in the step of bit 8 (a
    // one, unanswered) makes it 0, the later bits all ones: serial 0x0FF, whose confirmation a
    // second stray answers. Nobody is in configuration mode to take the node-ID.
    // One node-ID only: the false find must not use it up.
    let (mut w, a) = one_slave_scan();
    let (mut bit, mut confirm) = (true, true);
    run(&mut w, |d| {
        if bit && bit_step(d, 3, 8) {
            bit = false;
            return true;
        }
        if !bit && confirm && bit_step(d, 3, 0) && d[1..5] == 0xFFu32.to_le_bytes() {
            confirm = false;
            return true;
        }
        false
    });
    assert!(!bit && !confirm, "both strays were given");
    let n = NodeId::must;
    assert_eq!(
        w.take_events(),
        [
            K::Found(addr(0x2A, 7, 1, 0xFF)),
            K::ScanRestarted { sub: 3 },
            K::Found(a),
            K::Assigned {
                address: a,
                node: n(1)
            },
            K::ScanFinished { assigned: 1 },
        ]
    );
    assert_eq!(w.slaves[0].node_id(), Some(n(1)));
    let (req, _, _) = counts(&w);
    let (predicted, _, _) = cost(&[a], cfg().timeout, cfg().settle, false);
    // The attempt given up: 133 scan steps, the configure node-ID nobody took, the switch.
    assert_eq!(w.master.stats().abandoned, 133 + 1 + 1);
    assert_eq!(req, predicted + w.master.stats().abandoned);
}

#[test]
fn strays_in_every_attempt_stop_the_scan_after_its_restarts() {
    let (mut w, _) = one_slave_scan();
    run(&mut w, |d| bit_step(d, 1, 1));
    let mut want = vec![K::ScanRestarted { sub: 1 }; usize::from(RESTARTS)];
    want.push(K::Failed(LssError::ScanLost { sub: 1 }));
    assert_eq!(w.take_events(), want);
    assert_eq!(w.master.stats().restarts, u32::from(RESTARTS));
    assert_eq!(w.slaves[0].node_id(), None);
    assert!(w.master.is_idle());
}

#[test]
fn a_late_scan_answer_while_the_configure_step_waits_is_dropped() {
    let (mut w, a) = one_slave_scan();
    // The stray reaches the master after its configure node-ID request, before the answer.
    run(&mut w, |d| d[0] == 0x11);
    assert_eq!(w.master.stats().late, 1);
    assert_eq!(w.master.stats().restarts, 0);
    assert_eq!(w.slaves[0].node_id(), Some(NodeId::must(1)));
    assert_eq!(counts(&w), cost(&[a], cfg().timeout, cfg().settle, false));
}
