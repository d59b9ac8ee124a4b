//! Random frames and time steps into a slave node and a master node (standard dictionaries,
//! heartbeat producer and consumers, SDO server, PDOs, SYNC, EMCY, guarding): no panic, a
//! bounded number of frames and events per input, and deadlines that move on once handled, also
//! when the clock steps back, jumps an hour ahead or reaches the end of time (the clock contract).
//! The slave is on a CANopen FD network (it serves USDO): a chunk whose first byte has bit 1 set
//! hands it a CAN FD frame (the chunk's bytes, padded with 0xCC) instead of a classic one.
#![no_main]

mod common;

use duocan::od::{comm, DynamicDictionary, ObjectDictionary};
use duocan::{Duration, FdFrame, Frame, Id, Instant, Machine, Node, NodeConfig, NodeId};
use libfuzzer_sys::fuzz_target;

/// Most frames or events one input may cause (a full SDO sub-block is 127 segments).
const MAX_PER_INPUT: usize = 1024;

fn node(id: u8, master: bool) -> Node<DynamicDictionary> {
    let mut od = comm::standard_dictionary(id, comm::Identity::default());
    let _ = od.write_local(comm::HEARTBEAT_PRODUCER, 0, &100u16.to_le_bytes());
    if master {
        for (sub, peer) in [(1u8, 5u32), (2, 6), (3, 7)] {
            let consume = (peer << 16) | 250;
            let _ = od.write_local(comm::HEARTBEAT_CONSUMER, sub, &consume.to_le_bytes());
        }
    }
    let nid = NodeId::must(id);
    let cfg = if master {
        NodeConfig::master(nid)
    } else {
        NodeConfig::slave(nid).with_fd(true)
    };
    let mut n = Node::new(cfg, od);
    n.boot(Instant::ZERO);
    n
}

fn drain(n: &mut Node<DynamicDictionary>) {
    let mut k = 0;
    while n.poll_transmit().is_some() {
        k += 1;
        assert!(k <= MAX_PER_INPUT, "unbounded transmit queue");
    }
    let mut k = 0;
    while n.poll_transmit_fd().is_some() {
        k += 1;
        assert!(k <= MAX_PER_INPUT, "unbounded FD transmit queue");
    }
    let mut k = 0;
    while n.poll_event().is_some() {
        k += 1;
        assert!(k <= MAX_PER_INPUT, "unbounded event queue");
    }
}

/// Handles every deadline due at `now`; a machine whose deadline stays due is livelocked.
fn expire(n: &mut Node<DynamicDictionary>, now: Instant) {
    for _ in 0..64 {
        match n.poll_timeout() {
            Some(t) if t <= now => n.handle_timeout(now),
            _ => return,
        }
        drain(n);
    }
    panic!(
        "deadline {:?} still due at {now:?} after 64 rounds",
        n.poll_timeout()
    );
}

fuzz_target!(|data: &[u8]| {
    let mut nodes = [node(5, false), node(1, true)];
    let mut now = Instant::ZERO;
    for c in data.chunks_exact(14) {
        let [who, lo, hi, flags, dlc, step, d @ ..] = c else {
            continue;
        };
        now = common::misbehave(now, *step).unwrap_or_else(|| {
            now + match step >> 6 {
                0 => Duration::ZERO,
                1 => Duration::from_micros(u64::from(*step & 0x3F) * 100),
                2 => Duration::from_millis(u64::from(*step & 0x3F) * 10),
                _ => Duration::from_millis(u64::from(*step & 0x3F) * 1000),
            }
        });
        let raw = u16::from_le_bytes([*lo, *hi]);
        let id = if flags & 1 == 1 {
            Id::Extended(u32::from(raw) | u32::from(*flags >> 1) << 16)
        } else {
            // Mostly the identifiers the nodes listen to.
            Id::Standard(raw & 0x7FF)
        };
        let dlc = *dlc % 9;
        let frame = if flags & 2 == 2 {
            Frame::remote(id, dlc)
        } else {
            Frame::new(id, &d[..usize::from(dlc)])
        };
        let n = &mut nodes[usize::from(*who & 1)];
        expire(n, now);
        if *who & 2 == 2 {
            let raw = Id::Standard(raw & 0x7FF);
            if let Ok(f) = FdFrame::padded(raw, &d[..usize::from(dlc)], 0xCC) {
                n.handle_frame_fd(now, &f);
            }
        } else if let Ok(f) = frame {
            n.handle_frame(now, &f);
        }
        drain(n);
        // What one node sends, the other hears.
        let mut out = Vec::new();
        while let Some(f) = n.poll_transmit() {
            out.push(f);
        }
        let other = &mut nodes[usize::from(*who & 1) ^ 1];
        for f in out.iter().take(MAX_PER_INPUT) {
            other.handle_frame(now, f);
            drain(other);
        }
    }
});
