//! CAN FD frames in the active-standby modes, on two simulated FD buses: CiA 302-6 sends them
//! on the active channel only and moves them with the channel (the 0x7F indication moves the
//! receiver too); ECSS bus toggling sends and receives them on the selected bus only, as it
//! does classic frames. (Active-active FD is `fd.rs`.)

use super::fd_end::FdEnd;
use duocan::frame::FdFrame;
use duocan::sim::{BusConfig, DevId, SimNetwork};
use duocan::{Duration, Id};
use duocan_redundancy::{Cia3026Config, DualBusConfig, EcssConfig, LinkMode};

const MS: fn(u64) -> Duration = Duration::from_millis;

/// Two FD buses (500 kbit/s nominal, 2 Mbit/s data), a sender and a receiver on both, each
/// layer in `mode`.
fn rig(mode: LinkMode) -> (SimNetwork, DevId<FdEnd>, DevId<FdEnd>) {
    let mut sim = SimNetwork::new(36);
    let buses = [
        sim.add_bus(BusConfig::new("canfd0", 500_000).fd(2_000_000)),
        sim.add_bus(BusConfig::new("canfd1", 500_000).fd(2_000_000)),
    ];
    let cfg = || DualBusConfig::default().with_mode(mode);
    let a = sim
        .add_device("a", FdEnd::with_config(cfg()), &buses)
        .unwrap();
    let b = sim
        .add_device("b", FdEnd::with_config(cfg()), &buses)
        .unwrap();
    (sim, a, b)
}

/// Sends `n` 64-byte FD frames from `a`, numbered from `first`, 5 ms apart: the frames sent.
fn send(sim: &mut SimNetwork, a: DevId<FdEnd>, first: u8, n: u8) -> Vec<FdFrame> {
    let mut sent = vec![];
    for k in first..first + n {
        let f = FdFrame::new(Id::Standard(0x185), &[k; 64])
            .unwrap()
            .with_brs(true);
        let now = sim.now();
        sim.device_mut(a).link.send_fd(now, &f).unwrap();
        sent.push(f);
        sim.run_for(MS(5));
    }
    sim.run_for(MS(20));
    sent
}

/// Frames each port of `d` received so far.
fn rx(sim: &SimNetwork, d: DevId<FdEnd>) -> [u64; 2] {
    let link = &sim.device(d).link;
    [link.port(0).counters().rx, link.port(1).counters().rx]
}

#[test]
fn in_cia302_6_fd_frames_go_on_the_active_channel_and_move_with_its_indication() {
    let (mut sim, a, b) = rig(LinkMode::Cia302_6(Cia3026Config::default()));
    sim.run_for(MS(50));
    assert_eq!(sim.device(a).link.active_channel(), Some(0));
    let mut sent = send(&mut sim, a, 0, 10);
    assert_eq!(sim.device(b).got, sent, "each once, in order");
    assert_eq!(rx(&sim, b), [10, 0], "on the active channel (bus 1) only");

    // The sender moves to bus 2: its indication there moves the receiver, and the FD frames
    // follow the channel.
    let now = sim.now();
    assert!(sim.device_mut(a).link.select_channel(now, 1));
    sim.run_for(MS(10));
    assert_eq!(sim.device(b).link.active_channel(), Some(1));
    let before = rx(&sim, b);
    sent.extend(send(&mut sim, a, 10, 10));
    assert_eq!(
        sim.device(b).got,
        sent,
        "each once, in order, across the switch"
    );
    let after = rx(&sim, b);
    assert_eq!(after[0], before[0], "nothing more on bus 1");
    assert_eq!(after[1] - before[1], 10, "the ten on bus 2");
}

#[test]
fn in_ecss_bus_toggling_fd_frames_go_and_are_taken_on_the_selected_bus_only() {
    let (mut sim, a, b) = rig(LinkMode::EcssToggle(EcssConfig::master()));
    sim.run_for(MS(50));
    let mut sent = send(&mut sim, a, 0, 5);
    assert_eq!(sim.device(b).got, sent);
    assert_eq!(rx(&sim, b), [5, 0], "on the selected bus (bus 1) only");

    // The sender alone on bus 2: the receiver, still on bus 1, takes nothing from bus 2 (the
    // toggle's rule, for FD frames as for classic ones).
    let now = sim.now();
    assert!(sim.device_mut(a).link.select_channel(now, 1));
    let lost = send(&mut sim, a, 5, 5);
    assert_eq!(
        sim.device(b).got,
        sent,
        "none of the frames on the other bus"
    );
    assert_eq!(
        rx(&sim, b),
        [5, 5],
        "counted by port health (the other bus works), not delivered"
    );
    assert_eq!(lost.len(), 5);

    // Both on bus 2: delivered again, once each.
    let now = sim.now();
    assert!(sim.device_mut(b).link.select_channel(now, 1));
    sent.extend(send(&mut sim, a, 10, 5));
    assert_eq!(sim.device(b).got, sent);
    assert_eq!(
        rx(&sim, b),
        [5, 10],
        "bus 2 carried both rounds, bus 1 nothing more"
    );
}
