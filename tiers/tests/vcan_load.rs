//! Exactly once under CPU load, on two real SocketCAN buses: a sender puts each frame on vcan0
//! and then on vcan1 (as a dual-port node does); the receiver is the dual-bus layer
//! (`DualBus`, default settings) under duocan's runtime. Every (v)CPU runs a busy loop and the
//! receiver's threads run at nice 5, so its reader threads are held up as the scheduler
//! likes, each its own way, the two copies of a frame handed over far apart (in the emulated
//! VM up to ~60 ms after they arrived). Every occurrence must still be delivered exactly once:
//! none twice, none lost. Also with vcan0 going down and up every half second meanwhile.
//!
//! Held up, not starved: at nice 10 the receiver got about 5 % of the emulated CPU where its
//! 10,000 frames a second need about 11 %, its readers fell up to 0.4 s behind, and the
//! merger's memory (the horizon of each copy, 768 records) overflowed: an overloaded machine,
//! which no layer serves in time. At nice 5 it has twice what it needs, and the busy loops
//! still come between its threads.
//!
//! The traffic is what a network carries: a cyclic PDO whose data does not change (every
//! other frame), SYNC every 10 ms and a heartbeat every 100 ms (unchanged repeats too), and
//! frames with a counter in between. Repeats are counted by occurrence: a content sent k times
//! must be delivered k times, each counter frame once.
//!
//! The sender is another node, not the one under load: it runs at nice -10, so that the busy
//! loops do not come between its two copies of a frame (they would be a time slice apart on
//! the wires, beyond the skew of two real buses), and it sends no faster than a 1 Mbit/s bus
//! carries frames. The VM's kernel keeps its default socket receive buffers (208 KiB, which a
//! reader held up 35 ms at a full bus overflows): the ports ask for 4 MiB queues of their own,
//! and the kernel must drop nothing on them (the ports' `rx_overrun`).
//!
//! The load under test is the guest's: a host busy with other work holds the whole VM up (its
//! emulated CPU not scheduled), and a receiver frozen longer than the merger keeps its copies is
//! beyond what the layer is built for. A thread at nice -20 that sleeps a millisecond at a time
//! measures that. The merger's bound is its horizon: a reader running up to the horizon behind
//! the other port's finds every twin (see `duocan_redundancy::link::merge`); how far apart the
//! two readers handed copies over is measured on the counter frames (every other frame, each
//! sent once, see [`widest_apart`]). A run in which the host held the VM up (a hold-up longer
//! than half the merger's horizon, or more than a tenth of the time lost) or in which two
//! copies were handed over further apart than the horizon less a window is printed and not
//! judged, and run again, up to three times: the test fails saying so if none was clean, never
//! passes without a judged run.
//!
//! Each run prints what it saw: the verdict, the merger's counters, how late the frames were
//! handed over (the receiver's hold-ups), how the host held the VM up, the CPU the sender and
//! the receiver used. Runs inside duocan's qemu VM (`.ci/tier-vcan.sh`), one test at a time, built with
//! `--release` (the VM emulates its CPU: a debug receiver cannot keep up with
//! 10,000 frames a second there, and what it then loses in the kernel no layer can give back).

use duocan::port::socketcan::SocketCanPort;
use std::process::Command;

#[path = "common/load.rs"]
mod load;
use load::{check, Wires};

/// vcan0 taken down (`false`) or up by `ip link`.
fn set_vcan0(up: bool) {
    let state = if up { "up" } else { "down" };
    let st = Command::new("ip")
        .args(["link", "set", "vcan0", state])
        .status();
    assert!(st.is_ok_and(|s| s.success()), "ip link set vcan0 {state}");
}

/// vcan0 and vcan1.
#[derive(Clone)]
struct Vcan;

impl Wires for Vcan {
    type P = SocketCanPort;
    fn open(&self, bus: usize) -> SocketCanPort {
        SocketCanPort::open(&self.name(bus)).unwrap()
    }
    fn name(&self, bus: usize) -> String {
        format!("vcan{bus}")
    }
}

#[test]
fn exactly_once_at_1000_frames_per_second_under_load() {
    check(&Vcan, 20_000, 1_000, None);
}

#[test]
fn exactly_once_at_5000_frames_per_second_under_load() {
    check(&Vcan, 20_000, 5_000, None);
}

#[test]
fn exactly_once_with_one_bus_flapping_under_load() {
    check(&Vcan, 20_000, 5_000, Some(set_vcan0));
}
