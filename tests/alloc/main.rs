//! No allocation per frame on the runtime's path: a duocan node under the tokio runtime answers
//! thousands of SDO expedited reads and echoes, and the heap is counted (every thread, by a
//! counting global allocator: this test binary has it to itself).
//!
//! The port is an in-memory wire that itself never allocates (fixed queues), so what is counted
//! is the runtime's own work: the port task reading, the device handling the frame and queuing
//! its answer, the port task writing it.
//!
//! No test harness (`harness = false`): the counter sees every thread of the process, and
//! libtest's own threads allocate when a test ends (its main thread copies the test's name for
//! the report). With two tests, under CPU load the harness thread now and then ran late and
//! copied the first test's name inside the second's count (53 bytes, the length of the
//! name). Here `main` runs the cases one after the other and nothing else runs beside them.

mod reader;
mod wire;

use duocan::od::comm;
use duocan::port::Port;
use duocan::runtime::Runtime;
use duocan::{Frame, Id, Node, NodeConfig, NodeId, Station};
use stats_alloc::{Region, StatsAlloc, INSTRUMENTED_SYSTEM};
use std::alloc::System;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::Duration;
use wire::{pair, LoopPort};

#[global_allocator]
static GLOBAL: &StatsAlloc<System> = &INSTRUMENTED_SYSTEM;

const NODE: u8 = 0x22;

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
/// may run on different threads. Returned once both threads run: `build` creates them, but a
/// thread starts when the system first schedules it, and its start allocates (its name, for the
/// stack-overflow handler). Under CPU load the warm-up sometimes ran on one worker while the
/// other had not started yet, and its start then fell inside the count (15 bytes,
/// "tokio-rt-worker").
fn two_workers() -> tokio::runtime::Runtime {
    let started = Arc::new(AtomicUsize::new(0));
    let count = started.clone();
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .on_thread_start(move || {
            count.fetch_add(1, Ordering::SeqCst);
        })
        .enable_all()
        .build()
        .unwrap();
    let give_up = std::time::Instant::now() + Duration::from_secs(30);
    while started.load(Ordering::SeqCst) < 2 {
        assert!(
            std::time::Instant::now() < give_up,
            "the runtime's two worker threads did not start within 30 s"
        );
        std::thread::sleep(Duration::from_millis(1));
    }
    rt
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

fn the_runtime_path_allocates_nothing_per_frame() {
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

/// The cases, one after the other, reported as libtest reports tests (`test NAME ... ok`); an
/// argument that is not an option selects the cases whose name contains it.
fn main() {
    let cases: [(&str, fn()); 2] = [
        (
            "the_runtime_path_allocates_nothing_per_frame",
            the_runtime_path_allocates_nothing_per_frame,
        ),
        (
            "reader::the_reader_thread_allocates_nothing_per_frame",
            reader::the_reader_thread_allocates_nothing_per_frame,
        ),
    ];
    let filter = std::env::args().skip(1).find(|a| !a.starts_with('-'));
    let chosen: Vec<_> = cases
        .iter()
        .filter(|(name, _)| filter.as_deref().is_none_or(|f| name.contains(f)))
        .collect();
    println!("\nrunning {} tests", chosen.len());
    let mut failed = Vec::new();
    for (name, case) in chosen {
        let outcome = std::panic::catch_unwind(case);
        println!(
            "test {name} ... {}",
            if outcome.is_ok() { "ok" } else { "FAILED" }
        );
        if outcome.is_err() {
            failed.push(*name);
        }
    }
    if !failed.is_empty() {
        println!("\nfailures: {}", failed.join(", "));
        std::process::exit(101);
    }
}
