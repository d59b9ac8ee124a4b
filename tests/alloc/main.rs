//! No allocation per frame on the runtime's path: a duocan node under the tokio runtime answers
//! thousands of SDO expedited reads and echoes, and the heap is counted (every thread, by a
//! counting global allocator: this test binary has it to itself).
//!
//! The port is an in-memory wire that itself never allocates (fixed queues), so what is counted
//! is the runtime's own work: the port task reading, the device handling the frame and queuing
//! its answer, the port task writing it.

mod reader;
mod wire;

use duocan::od::comm;
use duocan::port::Port;
use duocan::runtime::Runtime;
use duocan::{Frame, Id, Node, NodeConfig, NodeId, Station};
use stats_alloc::{Region, StatsAlloc, INSTRUMENTED_SYSTEM};
use std::alloc::System;
use std::time::Duration;
use wire::{pair, LoopPort};

#[global_allocator]
static GLOBAL: &StatsAlloc<System> = &INSTRUMENTED_SYSTEM;

const NODE: u8 = 0x22;

/// The heap is counted for the whole process: one test at a time.
static SERIAL: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// An expedited upload request of 0x1018:1 (the vendor-ID).
fn read_vendor() -> Frame {
    Frame::from_array(
        Id::Standard(0x600 + NODE as u16),
        [0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0],
    )
}

/// `n` reads, one at a time, each answered with the vendor-ID.
async fn reads(tester: &mut LoopPort, n: usize) {
    for _ in 0..n {
        tester.send(&read_vendor()).await.unwrap();
        let answer = tokio::time::timeout(Duration::from_secs(5), tester.recv())
            .await
            .expect("the node answers")
            .unwrap();
        let duocan::port::PortInput::Frame(f, _) = answer else {
            panic!("a frame, not {answer:?}")
        };
        assert_eq!(f.id(), Id::Standard(0x580 + NODE as u16));
        assert_eq!(&f.data()[..8], [0x43, 0x18, 0x10, 0x01, 0x34, 0x12, 0, 0]);
    }
}

/// Two workers, as `#[tokio::main]` gives on a two-core machine: the port task and the tester
/// may run on different threads.
fn two_workers() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap()
}

/// The slave whose vendor ID (0x1018:1 = 0x1234) every read asks for.
fn slave() -> Node<duocan::od::DynamicDictionary> {
    let od = comm::standard_dictionary(
        NODE,
        comm::Identity {
            vendor: 0x1234,
            ..Default::default()
        },
    );
    Node::new(NodeConfig::slave(NodeId::must(NODE)), od)
}

#[test]
fn the_runtime_path_allocates_nothing_per_frame() {
    let _alone = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let rt = two_workers();
    rt.block_on(async {
        let (mut tester, port) = pair();
        let node = slave();
        let handle = Runtime::new(Station::single(node))
            .port(port)
            .spawn()
            .unwrap();
        // A subscriber that never reads: the runtime must not pay for it per frame either.
        let _idle = handle.subscribe();
        handle.boot().await.unwrap();
        let _boot_up = tester.recv().await.unwrap();
        // Warm-up: first uses of the runtime's and the allocator's structures.
        reads(&mut tester, 1_000).await;

        let region = Region::new(GLOBAL);
        reads(&mut tester, 10_000).await;
        let stats = region.change();
        assert_eq!(
            (stats.allocations, stats.reallocations),
            (0, 0),
            "10,000 SDO reads (20,000 frames) through the runtime allocated: {stats:?}"
        );
        assert_eq!(handle.port_counters(0).unwrap().tx_dropped, 0);
        handle.shutdown().await;
    });
}
