//! The dual-bus layer in each mode fed random arrivals on both ports, port reports, sends and
//! the shared clock of the fuzz targets (forward, jumping an hour ahead, stepping back, the end
//! of time): no panic, bounded output and events, deadlines that move on once handled.
#![no_main]

mod common;

use common::{advance, port_status};
use duocan::{BusLink, Duration, Frame, Id, Instant, NodeId};
use duocan_redundancy::{Cia3026Config, DualBus, DualBusConfig, EcssConfig, LinkMode, Member};
use libfuzzer_sys::fuzz_target;

fn drain(b: &mut DualBus) {
    let mut k = 0;
    while b.poll_transmit().is_some() || b.poll_port_request().is_some() {
        k += 1;
        assert!(k <= 256, "unbounded transmit queue");
    }
    let mut k = 0;
    while b.poll_event().is_some() {
        k += 1;
        assert!(k <= 256, "unbounded event queue");
    }
}

/// Handles every deadline due at `now`; one that stays due is a livelock.
fn expire(b: &mut DualBus, now: Instant) {
    for _ in 0..64 {
        match b.poll_timeout() {
            Some(t) if t <= now => b.handle_timeout(now),
            _ => return,
        }
        drain(b);
    }
    panic!("deadline {:?} still due at {now:?}", b.poll_timeout());
}

fuzz_target!(|data: &[u8]| {
    let Some((&mode, rest)) = data.split_first() else {
        return;
    };
    let mode = match mode % 3 {
        0 => LinkMode::ActiveActive,
        1 => LinkMode::Cia302_6(Cia3026Config::default()),
        _ => LinkMode::EcssToggle(EcssConfig::slave(
            NodeId::must(1),
            Duration::from_millis(50),
        )),
    };
    let mut b = DualBus::new(DualBusConfig::with_guard_period(
        mode,
        Duration::from_millis(20),
    ));
    // A pair and a watched heartbeat: the same-function values and plausibility hold times too.
    let _ = b.add_pair(NodeId::must(0x10), NodeId::must(0x11), Some(Member::A));
    b.watch(NodeId::must(0x10), Duration::from_millis(20));
    let mut now = Instant::ZERO;
    for c in rest.chunks_exact(6) {
        let [op, lo, hi, dlc, byte, step] = *c else {
            continue;
        };
        now = advance(now, step);
        expire(&mut b, now);
        let id = Id::Standard(u16::from_le_bytes([lo, hi]) & 0x7FF);
        let frame = Frame::new(id, &[byte; 8][..usize::from(dlc % 9)]);
        let port = usize::from(op & 1);
        match op >> 1 & 7 {
            0..=3 => {
                if let Ok(f) = frame {
                    let _ = b.handle_rx(now, port, &f);
                }
            }
            4 => {
                if let Ok(f) = frame {
                    b.send(now, &f);
                }
            }
            5 => b.handle_port_status(now, port, port_status(dlc, byte)),
            // An arrival on both ports, the twin `step` microseconds later.
            _ => {
                if let Ok(f) = frame {
                    let _ = b.handle_rx(now, port, &f);
                    let _ = b.handle_rx(now + Duration::from_micros(u64::from(step)), 1 - port, &f);
                }
            }
        }
        drain(&mut b);
    }
});
