//! LSS (CiA 305): any bytes as frames on the LSS identifiers and the NMT identifier, through the
//! frame decoders (what decodes encodes back to the same frame), an LSS slave and an LSS master
//! in the middle of a fastscan, with time running; and any bytes as a slave's stored
//! configuration. Never a panic; the slave's node-IDs stay valid, the master's answers are
//! frames of 8 bytes on 0x7E5.
#![no_main]

use duocan::cia305::{LssAddress, LssMaster, LssPlan, LssRequest, LssResponse, LssSlave};
use duocan::od::parameters::{MemoryStorage, ParameterStorage};
use duocan::{Duration, Frame, Id, Instant, Machine, NodeId};
use libfuzzer_sys::fuzz_target;

fn check_decoders(f: &Frame) {
    if let Ok(r) = LssRequest::decode(f) {
        assert_eq!(LssRequest::decode(&r.encode()), Ok(r));
    }
    if let Ok(r) = LssResponse::decode(f) {
        assert_eq!(LssResponse::decode(&r.encode()), Ok(r));
    }
}

fuzz_target!(|data: &[u8]| {
    let Some((&first, rest)) = data.split_first() else {
        return;
    };
    let board = LssAddress { vendor: 0x2A, product: 7, revision: 1, serial: 0x1234 };
    // The first byte picks a stored configuration from the input or none.
    let mut medium = MemoryStorage::<16>::new();
    if first & 1 == 1 {
        let _ = medium.store(&rest[..rest.len().min(12)]);
    }
    let mut slave = LssSlave::new(board, if first & 2 == 0 { 0xFF } else { 9 }).with_storage(medium);
    let _ = slave.load_stored();
    let mut master: LssMaster = LssMaster::default();
    let plan = LssPlan::new().with_identity(board, NodeId::must(3)).with_free((4..=6).map(NodeId::must));
    let _ = master.fastscan(Instant::ZERO, plan);
    let mut now = Instant::ZERO;
    // Records of 10 bytes: which identifier and length, a time step, eight data bytes.
    for rec in rest.chunks_exact(10) {
        let id = match rec[0] & 3 {
            0 => 0x7E5,
            1 => 0x7E4,
            2 => 0x000,
            _ => 0x7E0 | u16::from(rec[0] >> 5),
        };
        let len = usize::from((rec[0] >> 2) & 7) + usize::from(rec[0] & 0x80 != 0);
        now = now + Duration::from_micros(u64::from(rec[1]) * 500);
        let Ok(f) = Frame::new(Id::Standard(id), &rec[2..2 + len.min(8)]) else {
            continue;
        };
        check_decoders(&f);
        slave.handle_frame(now, &f);
        master.handle_frame(now, &f);
        // The machines talk to each other too.
        while let Some(a) = slave.poll_transmit() {
            assert_eq!((a.id(), a.dlc()), (Id::Standard(0x7E4), 8));
            master.handle_frame(now, &a);
        }
        while let Some(r) = master.poll_transmit() {
            assert_eq!((r.id(), r.dlc()), (Id::Standard(0x7E5), 8));
            slave.handle_frame(now, &r);
        }
        if let Some(t) = master.poll_timeout().filter(|t| *t <= now) {
            master.handle_timeout(t.max(now));
        }
        slave.handle_timeout(now);
        while master.poll_event().is_some() {}
        while slave.poll_event().is_some() {}
        let pending = slave.pending_node_id();
        assert!(pending == 0xFF || (1..=127).contains(&pending));
        if master.is_idle() {
            let _ = master.fastscan(now, LssPlan::new().with_free([NodeId::must(1)]));
        }
    }
});
