//! The starter examples, run as users run them: on the simulated nodes (no `DUOCAN_BUS`), on
//! the simulated CANopen FD network (`DUOCAN_BUS=sim-nodes:fd`, the examples unchanged) and,
//! for the monitor, on an in-memory bus where a node goes silent; the redundant master on the
//! simulated redundant station.

use crate::rt::{node, single};
use duocan::net::Network;
use duocan::port::mem::MemBus;
use duocan::runtime::Runtime;
use std::sync::{Arc, Mutex};
use std::time::Duration;

#[path = "../../examples/heartbeat_monitor.rs"]
#[allow(dead_code)]
mod heartbeat_monitor;
#[path = "../../examples/read_sdo.rs"]
mod read_sdo;
#[path = "../../examples/redundant_master.rs"]
#[allow(dead_code)]
mod redundant_master;
#[path = "../../examples/redundant_pdo.rs"]
#[allow(dead_code)]
mod redundant_pdo;

#[test]
fn read_sdo_reads_node_5_of_the_simulated_bus() {
    // Fails (Err) if node 5 did not answer with a u32.
    read_sdo::main().unwrap();
}

/// The name of the simulated CANopen FD network, as a user gives it in `DUOCAN_BUS`.
const FD_BUS: &str = "sim-nodes:fd";

/// `read_sdo`'s `main`, unchanged, with `DUOCAN_BUS=sim-nodes:fd`: this test binary runs itself
/// for the one test above with the variable set (set here, it would reach every other test of
/// the binary), and the run passes and prints node 5's vendor-ID.
#[test]
fn read_sdo_reads_node_5_of_the_simulated_fd_network() {
    let name = "examples::read_sdo_reads_node_5_of_the_simulated_bus";
    let out = std::process::Command::new(std::env::current_exe().unwrap())
        .args([name, "--exact", "--nocapture", "--test-threads=1"])
        .env("DUOCAN_BUS", FD_BUS)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("1 passed"), "{stdout}");
    assert!(stdout.contains("node 5 vendor-ID: 0x00d0ca00"), "{stdout}");
}

/// What `read_sdo` does on `sim-nodes:fd` goes over USDO: the network is an FD one, the value
/// is the simulated vendor-ID, and no classic SDO request or answer is on the wire (the tap
/// sees every classic frame; over SDO it would see 0x605 and 0x585).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sim_nodes_fd_reads_and_writes_over_usdo_not_sdo() {
    use duocan::capture::recorder::{Tap, TapDirection, TapPoint};
    use duocan::net::NetOptions;
    #[derive(Default)]
    struct Seen(Mutex<Vec<u16>>);
    impl Tap for Seen {
        fn frame(&self, _: duocan::Instant, _: TapPoint, _: TapDirection, f: &duocan::Frame) {
            if let duocan::Id::Standard(id) = f.id() {
                self.0.lock().unwrap().push(id);
            }
        }
    }
    let seen = Arc::new(Seen::default());
    let opts = NetOptions::default().with_tap(seen.clone() as Arc<dyn Tap>);
    let net = Network::open_named_with(FD_BUS, opts).unwrap();
    assert_eq!(net.fd_client(), Some(duocan::net::FD_CLIENT));
    let node = net.node(5);
    let vendor: u32 = node.sdo().read(0x1018, 1).await.unwrap();
    assert_eq!(vendor, duocan::net::SIM_VENDOR);
    node.sdo().write(0x1017, 0, 250u16).await.unwrap();
    assert_eq!(node.sdo().read::<u16>(0x1017, 0).await.unwrap(), 250);
    assert_eq!(
        node.sdo().read_string(0x1008, 0).await.unwrap(),
        duocan::net::SIM_DEVICE_NAME
    );
    let seen = seen.0.lock().unwrap().clone();
    assert!(
        !seen.iter().any(|id| (0x580..0x680).contains(id)),
        "classic SDO frames on the FD network: {seen:x?}"
    );
    net.close().await;
}

/// `heartbeat_monitor`'s `monitor` on the network its `main` opens for
/// `DUOCAN_BUS=sim-nodes:fd` (`Network::monitor_named`): the states of the ten simulated FD
/// nodes, from their heartbeats.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn heartbeat_monitor_prints_the_states_of_the_simulated_fd_network() {
    let net = Network::monitor_named(FD_BUS).unwrap();
    assert_eq!(net.fd_client(), Some(duocan::net::FD_CLIENT));
    let lines = Arc::new(Mutex::new(Vec::<String>::new()));
    let out = lines.clone();
    let run = tokio::spawn(heartbeat_monitor::monitor(net.clone(), move |l| {
        out.lock().unwrap().push(l)
    }));
    let want: Vec<String> = (1..=10)
        .map(|n| format!("node {n:#04x}: pre-operational"))
        .collect();
    for _ in 0..300 {
        if want.iter().all(|w| lines.lock().unwrap().contains(w)) {
            break;
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    net.close().await;
    run.await.unwrap().unwrap();
    let lines = lines.lock().unwrap().clone();
    // Each node's state, heard from its heartbeats (a machine that stalls the test past the
    // watch's 500 ms may report a node lost and back in between: that is not asserted on).
    for w in &want {
        assert!(lines.contains(w), "{w}: {lines:?}");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn heartbeat_monitor_prints_states_and_the_loss() {
    let bus = MemBus::new("mem");
    let net = Network::monitor(bus.port()).unwrap();
    let lines = Arc::new(Mutex::new(Vec::<String>::new()));
    let out = lines.clone();
    let run = tokio::spawn(heartbeat_monitor::monitor(net.clone(), move |l| {
        out.lock().unwrap().push(l)
    }));
    tokio::time::sleep(Duration::from_millis(100)).await;
    let s = Runtime::new(single(node(3, false, 50, &[])))
        .port(bus.port())
        .spawn()
        .unwrap();
    s.boot().await.unwrap();
    let seen = |want: &str| lines.lock().unwrap().iter().any(|l| l == want);
    let until = |want: &'static str| {
        let seen = &seen;
        async move {
            for _ in 0..300 {
                if seen(want) {
                    return;
                }
                tokio::time::sleep(Duration::from_millis(10)).await;
            }
            panic!("no line {want:?}");
        }
    };
    until("node 0x03: boot-up").await;
    until("node 0x03: pre-operational").await;
    s.shutdown().await;
    until("node 0x03: heartbeat lost").await;
    net.close().await;
    run.await.unwrap().unwrap();
    let lines = lines.lock().unwrap().clone();
    let (mut node3, others): (Vec<_>, Vec<_>) =
        lines.iter().partition(|l| l.starts_with("node 0x03"));
    // Node 3 starts 100 ms after the watch: on a machine that stalls the test past the watch's
    // 500 ms, it is reported not heard first, once.
    if node3
        .first()
        .is_some_and(|l| *l == "node 0x03: not heard for 500 ms")
    {
        node3.remove(0);
    }
    assert_eq!(
        node3,
        [
            "node 0x03: boot-up",
            "node 0x03: pre-operational",
            "node 0x03: heartbeat lost"
        ]
    );
    // The nine watched nodes that are not there: each reported once, 500 ms after its watch.
    let mut others: Vec<String> = others.into_iter().cloned().collect();
    others.sort();
    let want: Vec<String> = [1, 2, 4, 5, 6, 7, 8, 9, 10]
        .iter()
        .map(|n| format!("node {n:#04x}: not heard for 500 ms"))
        .collect();
    assert_eq!(others, want);
}

/// On the simulated station (tokio's paused clock: the six simulated seconds take a fraction
/// of one), the example prints exactly one failover of each kind, in the script's order.
#[tokio::test(start_paused = true)]
async fn redundant_master_prints_a_bus_a_master_and_a_pair_failover() {
    let mut lines = Vec::new();
    redundant_master::run("sim-pairs", |l| lines.push(l))
        .await
        .unwrap();
    assert_eq!(
        lines,
        [
            "bus 1: failed (port down: interface down)",
            "this master: active",
            "pair 0x10/0x50: B active"
        ]
    );
}

/// On the simulated station, the redundant master reads the active board's inputs from its
/// TPDO and writes its outputs by RPDO; the board's dictionary shows the write.
#[tokio::test(start_paused = true)]
async fn redundant_pdo_reads_inputs_and_writes_outputs_of_a_pair_member() {
    assert_eq!(redundant_pdo::run("sim-pairs").await.unwrap(), 1234);
}

/// Lines of code as the starter examples are measured: every line that is not blank, a
/// comment (doc comments too), a `use` declaration or an attribute.
fn code_lines(text: &str) -> usize {
    text.lines()
        .map(str::trim)
        .filter(|l| !(l.is_empty() || l.starts_with("//") || l.starts_with("use ")))
        .filter(|l| !l.starts_with("#["))
        .count()
}

/// The starter examples are the measure of the front door: if one grows, the API is wrong.
/// Each does its task within its number of lines of code.
#[test]
fn the_starter_examples_stay_within_their_lines() {
    assert_eq!(
        code_lines("use a;\n//! doc\n\n  #[x]\nfn f() {\n    g();\n}\n"),
        3
    );
    for (file, text, most) in [
        ("read_sdo", include_str!("../../examples/read_sdo.rs"), 8),
        (
            "heartbeat_monitor",
            include_str!("../../examples/heartbeat_monitor.rs"),
            15,
        ),
        (
            "redundant_master",
            include_str!("../../examples/redundant_master.rs"),
            20,
        ),
        (
            "redundant_pdo",
            include_str!("../../examples/redundant_pdo.rs"),
            20,
        ),
    ] {
        let lines = code_lines(text);
        assert!(
            lines <= most,
            "examples/{file}.rs: {lines} lines of code, at most {most}"
        );
    }
}
