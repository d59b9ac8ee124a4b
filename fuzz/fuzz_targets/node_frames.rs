//! Random frames and time steps into a slave node and a master node (standard dictionaries,
//! heartbeat producer and consumers, SDO server, PDOs, SYNC, EMCY, guarding): no panic, a
//! bounded number of frames and events per input, and deadlines that move on once handled, also
//! when the clock steps back, jumps an hour ahead or reaches the end of time (the clock contract).
//! Both are on a CANopen FD network (they serve USDO, and send their PDOs and EMCY in CAN FD
//! frames): a chunk whose first byte has bit 1 set hands its node a CAN FD frame instead of a
//! classic one, as long as its DLC byte's low nibble says in CAN FD (up to 64 bytes: the
//! chunk's 8 data bytes over and over). Each node maps 512 bits at odd offsets (3-, 13- and
//! 64-bit entries) into TPDO1 and RPDO1, the master's RPDO synchronous (the wide payloads kept
//! until the SYNC), and the CAN FD frames one node sends the other hears.
#![no_main]

mod common;

use duocan::od::ObjectDictionary;
use duocan::od::{comm, Access, DataType, DefaultValue, DynamicDictionary, ObjectDef};
use duocan::pdo::params;
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
    // 512 bits at odd offsets, both ways: TPDO1 to the other node's RPDO1.
    let values: Vec<ObjectDef> = (0..15)
        .map(|i| {
            ObjectDef::new(0x6100 + i, 0, DataType::Unsigned64)
                .mappable()
                .access(Access::Rw)
        })
        .collect();
    let _ = od.insert_all(&values);
    let bits = [3u32, 13, 64, 64, 64, 64, 64, 64, 64, 13, 13, 13, 3, 3, 3];
    let entries: Vec<u32> = bits
        .iter()
        .enumerate()
        .map(|(i, b)| (0x6100 + i as u32) << 16 | b)
        .collect();
    let (tx_cob, rx_cob, rx_type) = if master {
        (0x205, 0x185, 1)
    } else {
        (0x185, 0x205, 255)
    };
    let cob = |c: u32| DefaultValue::Unsigned(u64::from(c));
    let _ = od.insert_all(&params::tpdo_comm(1, cob(tx_cob), 254, 0, 0));
    let _ = od.insert_all(&params::tpdo_mapping::<16>(1, &entries));
    let _ = od.insert_all(&params::rpdo_comm(1, cob(rx_cob), rx_type, 0));
    let _ = od.insert_all(&params::rpdo_mapping::<16>(1, &entries));
    let nid = NodeId::must(id);
    let cfg = if master {
        NodeConfig::master(nid).with_fd(true)
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
        let [who, lo, hi, flags, dlc_byte, step, d @ ..] = c else {
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
        let dlc = *dlc_byte % 9;
        let frame = if flags & 2 == 2 {
            Frame::remote(id, dlc)
        } else {
            Frame::new(id, &d[..usize::from(dlc)])
        };
        let n = &mut nodes[usize::from(*who & 1)];
        expire(n, now);
        if *who & 2 == 2 {
            let raw = Id::Standard(raw & 0x7FF);
            let len = duocan::frame::fd::len_for_dlc(*dlc_byte & 0x0F).unwrap_or(0);
            let bytes: Vec<u8> = d.iter().cycle().take(len).copied().collect();
            if let Ok(f) = FdFrame::new(raw, &bytes) {
                n.handle_frame_fd(now, &f);
            }
        } else if let Ok(f) = frame {
            n.handle_frame(now, &f);
        }
        // The CAN FD frames one node sends (its TPDOs, EMCY, USDO), the other hears.
        let mut fd_out = Vec::new();
        while let Some(f) = n.poll_transmit_fd() {
            assert!(fd_out.len() < MAX_PER_INPUT, "unbounded FD transmit queue");
            fd_out.push(f);
        }
        drain(n);
        let other = &mut nodes[usize::from(*who & 1) ^ 1];
        for f in &fd_out {
            other.handle_frame_fd(now, f);
            drain(other);
        }
        let n = &mut nodes[usize::from(*who & 1)];
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
