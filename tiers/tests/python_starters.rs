//! The starter examples on a real transport against an independent CANopen implementation: a
//! python `canopen` LocalNode on python-can's udp_multicast bus. `read_sdo` reads its vendor-ID
//! as a user runs it (`DUOCAN_BUS=udp:N`), `heartbeat_monitor` prints its boot-up, its state
//! and the loss of its heartbeat when the python process ends, and the watched nodes that are
//! not there.
//!
//! Needs what `.ci/tier-python.sh` sets up (a private network namespace, `DUOCAN_PYTHON`).

#[path = "common/peer.rs"]
mod peer;

#[path = "../../examples/heartbeat_monitor.rs"]
#[allow(dead_code)]
mod heartbeat_monitor;
#[path = "../../examples/read_sdo.rs"]
mod read_sdo;

use duocan::net::Network;
use duocan::port::udp::UdpBusConfig;
use peer::{group, Peer};
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// The python node's vendor-ID (`tiers/python/peer.py`, 0x1018 sub 1) is what the example
/// prints; here it must come back as the example's `Ok`: an absent node, a wrong type or a
/// bus that cannot open is an `Err`.
#[test]
fn read_sdo_reads_the_python_nodes_vendor_id_over_udp() {
    let cfg = UdpBusConfig::numbered(7);
    let rt = tokio::runtime::Runtime::new().unwrap();
    let (g, p) = group(&cfg);
    let mut peer = rt.block_on(Peer::spawn(&["node", "5", "100", &g, &p]));
    rt.block_on(peer.expect("STATE PRE-OPERATIONAL", 10));
    // The example reads DUOCAN_BUS; no other test of this binary does.
    std::env::set_var("DUOCAN_BUS", "udp:7");
    // On a thread of its own: the example builds its own runtime, which may not nest in ours.
    let result = std::thread::spawn(read_sdo::main).join().unwrap();
    result.unwrap_or_else(|e| panic!("read_sdo against the python node: {e}"));
    rt.block_on(peer.stop());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn heartbeat_monitor_prints_the_python_nodes_boot_up_state_and_loss() {
    let cfg = UdpBusConfig::numbered(8);
    let net = Network::monitor_named("udp:8").expect("open the UDP bus (inside unshare -n?)");
    let lines = Arc::new(Mutex::new(Vec::<String>::new()));
    let out = lines.clone();
    let run = tokio::spawn(heartbeat_monitor::monitor(net.clone(), move |l| {
        out.lock().unwrap().push(l)
    }));
    tokio::time::sleep(Duration::from_millis(200)).await;
    let (g, p) = group(&cfg);
    let mut peer = Peer::spawn(&["node", "5", "100", &g, &p]).await;
    peer.expect("STATE PRE-OPERATIONAL", 10).await;
    let seen = |want: &str| lines.lock().unwrap().iter().any(|l| l == want);
    let until = |want: &'static str, secs: u64| {
        let seen = &seen;
        let lines = &lines;
        async move {
            for _ in 0..secs * 100 {
                if seen(want) {
                    return;
                }
                tokio::time::sleep(Duration::from_millis(10)).await;
            }
            panic!("no line {want:?}; printed: {:?}", lines.lock().unwrap());
        }
    };
    until("node 0x05: pre-operational", 5).await;
    peer.stop().await;
    // Silent for the monitor's 500 ms: lost.
    until("node 0x05: heartbeat lost", 5).await;
    net.close().await;
    run.await.unwrap().unwrap();
    let lines = lines.lock().unwrap().clone();
    let (mut node5, others): (Vec<_>, Vec<_>) =
        lines.iter().partition(|l| l.starts_with("node 0x05"));
    // The python process may take longer than the watch's 500 ms to start: then node 5 is
    // reported not heard first, once.
    if node5
        .first()
        .is_some_and(|l| *l == "node 0x05: not heard for 500 ms")
    {
        node5.remove(0);
    }
    assert_eq!(
        node5,
        [
            "node 0x05: boot-up",
            "node 0x05: pre-operational",
            "node 0x05: heartbeat lost"
        ]
    );
    // The nine watched nodes that are not there: each reported once.
    let mut others: Vec<String> = others.into_iter().cloned().collect();
    others.sort();
    let want: Vec<String> = [1, 2, 3, 4, 6, 7, 8, 9, 10]
        .iter()
        .map(|n| format!("node {n:#04x}: not heard for 500 ms"))
        .collect();
    assert_eq!(others, want);
}
