//! The stored parameter image, as read back from a medium (a file, a flash sector) at power-on
//! and at every reset: any bytes, verbatim and with a valid CRC appended (so that the entry
//! walk and the value checks are reached), through a node that boots, resets and stores again.
//! Never a panic; the dictionary keeps only values its definitions accept.
#![no_main]

use duocan::od::parameters::{crc32, MemoryStorage, ParameterStorage, StoredDictionary};
use duocan::od::{check_value, comm, ObjectDef, ObjectDictionary, StaticDictionary};
use duocan::{Frame, Id, Instant, Machine, Node, NodeConfig, NodeId};
use libfuzzer_sys::fuzz_target;

static COMM: [ObjectDef; comm::COMM_LEN] = comm::communication();
static HB: [ObjectDef; 9] = comm::heartbeat_consumers::<9>();
static HIST: [ObjectDef; 5] = comm::error_history::<5>();
static STORE: [ObjectDef; comm::STORAGE_LEN] = comm::parameter_storage();

const IMAGE: usize = 2048;

fn run(image: &[u8]) {
    let mut medium = MemoryStorage::<IMAGE>::new();
    if medium.store(image).is_err() {
        return;
    }
    let mut od = StaticDictionary::<64, 512>::new();
    if od.load(5, &[&COMM, &HB, &HIST, &STORE]).is_err() {
        return;
    }
    let od = StoredDictionary::<_, _, IMAGE>::new(od, medium);
    let mut node = Node::new(NodeConfig::slave(NodeId::must(5)), od);
    let t = Instant::ZERO;
    node.boot(t);
    // Reset-communication, reset-node, then "save" to all over SDO: each reads the image again.
    for f in [
        Frame::from_array(Id::Standard(0), [0x82, 5]),
        Frame::from_array(Id::Standard(0), [0x81, 5]),
        Frame::from_array(
            Id::Standard(0x605),
            [0x23, 0x10, 0x10, 1, b's', b'a', b'v', b'e'],
        ),
    ] {
        node.handle_frame(t, &f);
        while node.poll_transmit().is_some() {}
        while node.poll_event().is_some() {}
    }
    // Whatever the image said, every value fits its definition. Except 0x1003 sub 0: the node
    // counts the errors it records there, while a write may only clear it (0).
    node.od().for_each(&mut |e| {
        if e.def.access.writable() && e.def.index != comm::ERROR_HISTORY {
            assert!(
                check_value(e.def, e.data).is_ok(),
                "{:#06x} sub {} holds a value its definition refuses",
                e.def.index,
                e.def.sub
            );
        }
    });
}

/// `body` with its CRC appended.
fn sealed(body: Vec<u8>) -> Vec<u8> {
    let mut v = body;
    let crc = crc32(&v);
    v.extend_from_slice(&crc.to_le_bytes());
    v
}

fuzz_target!(|data: &[u8]| {
    let data = &data[..data.len().min(IMAGE - 12)];
    run(data);
    run(&sealed(data.to_vec()));
    // Past the magic, with the entry count from the first byte: the entry walk itself.
    if let Some((&count, entries)) = data.split_first() {
        let mut body = b"DCP1".to_vec();
        body.extend_from_slice(&u32::from(count).to_le_bytes());
        body.extend_from_slice(entries);
        run(&sealed(body));
    }
});
