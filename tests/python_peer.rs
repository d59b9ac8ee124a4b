//! python `canopen` / python-can as an independent peer on the udp_multicast bus.
//!
//! Needs a private network namespace with loopback multicast and `DUOCAN_PYTHON` pointing at a
//! python with `python-can`, `canopen` and `msgpack`: `.ci/tier-python.sh` sets up both.

mod rt;

use duocan::node::NodeEventKind as K;
use duocan::port::udp::{encode, UdpBusConfig, UdpPort};
use duocan::port::{Port, PortInput};
use duocan::runtime::Runtime;
use duocan::{Frame, Id, NmtCommand, NmtState, NmtTarget, NodeId};
use rt::{node, node_event, single, wait_for};
use std::process::Stdio;
use std::time::Duration;
use tokio::io::{AsyncBufReadExt, BufReader, Lines};
use tokio::process::{Child, ChildStdout, Command};

struct Peer {
    child: Child,
    out: Lines<BufReader<ChildStdout>>,
}

impl Peer {
    async fn spawn(args: &[&str]) -> Peer {
        let python = std::env::var("DUOCAN_PYTHON").unwrap_or_else(|_| {
            panic!("DUOCAN_PYTHON is not set: point it at a python with python-can, canopen and msgpack (.ci/tier-python.sh does)")
        });
        let script = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/python/peer.py");
        let mut child = Command::new(&python)
            .arg(script)
            .args(args)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .kill_on_drop(true)
            .spawn()
            .unwrap_or_else(|e| panic!("cannot run {python}: {e}"));
        let out = BufReader::new(child.stdout.take().expect("stdout piped")).lines();
        let mut p = Peer { child, out };
        p.expect("READY", 20).await;
        p
    }

    /// Waits for a line starting with `prefix`; returns the line.
    async fn expect(&mut self, prefix: &str, secs: u64) -> String {
        let r = tokio::time::timeout(Duration::from_secs(secs), async {
            while let Some(l) = self.out.next_line().await.expect("peer stdout") {
                if l.starts_with(prefix) {
                    return Some(l);
                }
            }
            None
        })
        .await;
        match r {
            Ok(Some(l)) => l,
            Ok(None) => panic!("python peer exited before printing {prefix:?}"),
            Err(_) => panic!("python peer did not print {prefix:?} within {secs} s"),
        }
    }

    async fn stop(mut self) {
        drop(self.child.stdin.take());
        let _ = tokio::time::timeout(Duration::from_secs(5), self.child.wait()).await;
    }
}

fn group(cfg: &UdpBusConfig) -> (String, String) {
    (cfg.group.to_string(), cfg.port.to_string())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn python_node_heartbeat_is_consumed_and_duocan_nmt_drives_it() {
    let cfg = UdpBusConfig::numbered(0);
    let master = Runtime::new(single(node(1, true, 0, &[(0x22, 500)])))
        .name("master")
        .port(UdpPort::open(cfg.clone()).expect("open the UDP bus (inside unshare -n?)"))
        .spawn()
        .unwrap();
    let mut ev = master.subscribe();
    master.boot().await.unwrap();
    let (g, p) = group(&cfg);
    let mut peer = Peer::spawn(&["node", "0x22", "100", &g, &p]).await;
    peer.expect("STATE PRE-OPERATIONAL", 10).await;
    wait_for(&mut ev, 10, "python boot-up", |e| match node_event(e) {
        Some(K::BootUp { node }) if node.raw() == 0x22 => Some(()),
        _ => None,
    })
    .await;
    wait_for(
        &mut ev,
        5,
        "python heartbeat pre-operational",
        |e| match node_event(e) {
            Some(K::RemoteState {
                node,
                to: NmtState::PreOperational,
                ..
            }) if node.raw() == 0x22 => Some(()),
            _ => None,
        },
    )
    .await;

    let target = NmtTarget::Node(NodeId::new(0x22).unwrap());
    for (cmd, py, st) in [
        (
            NmtCommand::Start,
            "STATE OPERATIONAL",
            NmtState::Operational,
        ),
        (NmtCommand::Stop, "STATE STOPPED", NmtState::Stopped),
        (
            NmtCommand::EnterPreOperational,
            "STATE PRE-OPERATIONAL",
            NmtState::PreOperational,
        ),
    ] {
        master.nmt(cmd, target).await.unwrap().unwrap();
        peer.expect(py, 5).await;
        wait_for(
            &mut ev,
            5,
            "python heartbeat with the new state",
            |e| match node_event(e) {
                Some(K::RemoteState { node, to, .. }) if node.raw() == 0x22 && to == st => Some(()),
                _ => None,
            },
        )
        .await;
    }
    // NMT to another node-ID leaves it alone; broadcast start reaches it.
    master
        .nmt(
            NmtCommand::Start,
            NmtTarget::Node(NodeId::new(0x23).unwrap()),
        )
        .await
        .unwrap()
        .unwrap();
    master
        .nmt(NmtCommand::Start, NmtTarget::All)
        .await
        .unwrap()
        .unwrap();
    let l = peer.expect("STATE", 5).await;
    assert_eq!(
        l, "STATE OPERATIONAL",
        "only the broadcast changed the state"
    );

    // The peer goes away: the consumer times out 500 ms after its last heartbeat.
    peer.stop().await;
    wait_for(
        &mut ev,
        5,
        "heartbeat timeout of 0x22",
        |e| match node_event(e) {
            Some(K::HeartbeatTimeout { node, .. }) if node.raw() == 0x22 => Some(()),
            _ => None,
        },
    )
    .await;
    assert_eq!(master.port_counters(0).unwrap().rx_invalid, 0);
    master.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn garbage_datagrams_are_counted_and_the_runtime_keeps_going() {
    let cfg = UdpBusConfig::numbered(1);
    let mut port = UdpPort::open(cfg.clone()).expect("open the UDP bus (inside unshare -n?)");
    let counters = port.counters();
    // Raw junk from a plain socket: not msgpack, truncated, a map with wrong types, bad DLC.
    let junk = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    let good = encode(&Frame::from_array(Id::Standard(0x181), [1, 2]), 0.0, None);
    let mut wrong_type = good.clone();
    let i = wrong_type.windows(3).position(|w| w == b"dlc").unwrap();
    wrong_type[i + 3] = 0xc3; // dlc: true
    let datagrams: Vec<Vec<u8>> = vec![
        b"definitely not msgpack".to_vec(),
        good[..good.len() / 2].to_vec(),
        vec![0x92, 0x01, 0x02],
        wrong_type,
        vec![],
    ];
    for d in &datagrams {
        junk.send_to(d, (cfg.group, cfg.port)).unwrap();
    }
    junk.send_to(&good, (cfg.group, cfg.port)).unwrap();
    let got = tokio::time::timeout(Duration::from_secs(5), port.recv())
        .await
        .expect("the good frame arrives")
        .unwrap();
    assert_eq!(
        got,
        PortInput::Frame(Frame::from_array(Id::Standard(0x181), [1, 2]))
    );
    assert_eq!(counters.snapshot().rx_invalid, datagrams.len() as u64);

    // python-can's own CAN FD and error frames, then a good frame, into a running runtime.
    let master = Runtime::new(single(node(1, true, 0, &[])))
        .port(port)
        .spawn()
        .unwrap();
    master.boot().await.unwrap();
    let (g, p) = group(&cfg);
    let mut peer = Peer::spawn(&["junk", &g, &p]).await;
    peer.expect("SENT 2", 10).await;
    tokio::time::timeout(Duration::from_secs(5), async {
        while master.port_counters(0).unwrap().rx_frames < 2 {
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
    })
    .await
    .expect("the good python frame arrived");
    assert_eq!(
        master.port_counters(0).unwrap().rx_invalid,
        datagrams.len() as u64 + 2
    );
    assert_eq!(
        master.nmt_state().await.unwrap(),
        NmtState::Operational,
        "runtime still answers"
    );
    peer.stop().await;
    master.shutdown().await;
}
