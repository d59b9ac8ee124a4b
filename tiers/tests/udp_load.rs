//! Exactly once under CPU load on two python-can UDP buses (`common/load.rs`, the same runs as
//! `vcan_load` on SocketCAN): a sender puts each frame on bus 1 and then on bus 2; the receiver
//! is the dual-bus layer under duocan's runtime, niced under a busy loop on every CPU, its
//! ports' reader threads held up as the scheduler likes. Every occurrence must be delivered
//! exactly once: a UDP port stamps each datagram as the kernel received it (`SO_TIMESTAMPNS`),
//! so twins handed over far apart still pair. Runs on the host (not in a VM), inside
//! `unshare -n` (`.ci/tier-python.sh`), built with `--release`, one test at a time; a run in
//! which the host held the process up beyond the layer's bounds is not judged (see
//! `vcan_load`). A UDP bus cannot be taken down, so there is no flapping run here.

use duocan::port::udp::{UdpBusConfig, UdpPort};

#[path = "common/load.rs"]
mod load;
use load::{check, Wires};

/// Two UDP buses of their own (groups numbered 60 and 61).
#[derive(Clone)]
struct Udp;

impl Wires for Udp {
    type P = UdpPort;
    fn open(&self, bus: usize) -> UdpPort {
        UdpPort::open(UdpBusConfig::numbered(60 + bus as u8)).expect("open a UDP bus")
    }
    fn name(&self, bus: usize) -> String {
        format!("udp bus {}", bus + 1)
    }
}

#[test]
fn exactly_once_at_1000_frames_per_second_under_load() {
    check(&Udp, 20_000, 1_000, None);
}

#[test]
fn exactly_once_at_5000_frames_per_second_under_load() {
    check(&Udp, 20_000, 5_000, None);
}
