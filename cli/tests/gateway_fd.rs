//! `duocan --fd NODE-ID gateway` on a CANopen FD network: the CiA 309-3 requests read and write
//! over USDO (CiA 1301) in CAN FD frames, with the same answers as over SDO, against a duocan
//! node serving USDO on python-can's UDP bus with FD (bus 88 of the test networks, loopback),
//! and on two such buses merged (89 and 90), the node on both.

mod common;
use duocan::machine::{BusLink, Device, SinglePort, Station};
use duocan::od::{comm, Access, DataType, DynamicDictionary, ObjectDef};
use duocan::port::udp::{UdpBusConfig, UdpPort};
use duocan::port::{AnyInput, Port};
use duocan::runtime::Runtime;
use duocan::{Id, Node, NodeConfig, NodeId};
use duocan_redundancy::{DualBus, DualBusConfig};
use std::io::Write;
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

/// Node 5 serving USDO, with a value and a string to write.
fn fd_node() -> Node<DynamicDictionary> {
    let mut od = comm::standard_dictionary(5, Default::default());
    od.insert_all(&[
        ObjectDef::u32(0x2000, 0, Access::Rw, 0xCAFE_F00D),
        ObjectDef::bytes(0x2001, 0, DataType::VisibleString, 200).access(Access::Rw),
    ])
    .unwrap();
    Node::new(NodeConfig::slave(NodeId::must(5)).with_fd(true), od)
}

/// Counts, on `bus`, the tool's USDO requests (CAN FD frames from node-ID 127) and classic
/// SDO requests to node 5.
fn count_requests(bus: u8, usdo: Arc<AtomicUsize>, sdo: Arc<AtomicUsize>) {
    let mut tester = UdpPort::open(UdpBusConfig::numbered(bus).with_fd()).unwrap();
    tokio::spawn(async move {
        while let Ok(input) = tester.recv_any().await {
            match input {
                AnyInput::Fd(f, _) if f.id() == Id::Standard(0x600 + 127) => {
                    usdo.fetch_add(1, Ordering::Relaxed);
                }
                AnyInput::Frame(f, _) if f.id() == Id::Standard(0x605) => {
                    sdo.fetch_add(1, Ordering::Relaxed);
                }
                _ => {}
            }
        }
    });
}

/// Runs `duocan --bus BUS --fd 127 gateway` with `script` on standard input; its output.
fn gateway(bus: &str, script: &str) -> String {
    let mut child = Command::new(env!("CARGO_BIN_EXE_duocan"))
        .args(["--bus", bus, "--fd", "127", "--timeout", "300", "gateway"])
        .env_remove("DUOCAN_BUS")
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run duocan");
    let mut stdin = child.stdin.take().expect("stdin piped");
    stdin.write_all(script.as_bytes()).unwrap();
    drop(stdin);
    let o = child.wait_with_output().expect("duocan ends");
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(0), "{err}");
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// The requests and their answers, the same as over SDO.
const TEXT: &str =
    "a visible string longer than the fifty-six bytes of one USDO frame, over CAN FD";

fn check(out: &str) {
    let want = [
        "[1] 3405705229".to_string(),
        "[2] OK".into(),
        "[3] 42".into(),
        "[4] OK".into(),
        format!("[5] \"{TEXT}\""),
        "[6] ERROR:0x06020000 #object does not exist in the object dictionary".into(),
    ];
    let got: Vec<&str> = out.lines().collect();
    assert_eq!(got, want, "{out}");
}

fn script() -> String {
    format!(
        "[1] 5 r 0x2000 0 u32\n[2] 5 w 0x2000 0 u32 42\n[3] 5 r 0x2000 0 u32\n\
         [4] 5 w 0x2001 0 vs \"{TEXT}\"\n[5] 5 r 0x2001 0 vs\n[6] 5 r 0x1234 0 u8\n"
    )
}

#[test]
fn the_gateway_reads_and_writes_over_usdo_with_fd() {
    const BUS: u8 = 88;
    let rt = tokio::runtime::Runtime::new().unwrap();
    let (usdo, sdo) = (Arc::default(), Arc::<AtomicUsize>::default());
    let node = rt.block_on(async {
        let h = Runtime::new(Station::new(SinglePort::fd(), fd_node()))
            .port(UdpPort::open(UdpBusConfig::numbered(BUS).with_fd()).unwrap())
            .spawn()
            .unwrap();
        h.boot().await.unwrap();
        count_requests(BUS, Arc::clone(&usdo), Arc::clone(&sdo));
        h
    });
    check(&gateway(&format!("udp:{BUS}"), &script()));
    // Six transfers, the string's segmented: over USDO, none over classic SDO.
    assert!(usdo.load(Ordering::Relaxed) >= 6);
    assert_eq!(sdo.load(Ordering::Relaxed), 0);
    rt.block_on(node.shutdown());
}

#[test]
fn the_gateway_reads_and_writes_over_usdo_on_two_fd_buses() {
    const BUSES: [u8; 2] = [89, 90];
    let rt = tokio::runtime::Runtime::new().unwrap();
    let counts: [(Arc<AtomicUsize>, Arc<AtomicUsize>); 2] = Default::default();
    let node = rt.block_on(async {
        let mut link = DualBus::new(DualBusConfig::default());
        link.set_port_fd(0, true);
        link.set_port_fd(1, true);
        assert!(BusLink::fd_capable(&link));
        let h = Runtime::new(Station::new(link, fd_node()))
            .port(UdpPort::open(UdpBusConfig::numbered(BUSES[0]).with_fd()).unwrap())
            .port(UdpPort::open(UdpBusConfig::numbered(BUSES[1]).with_fd()).unwrap())
            .spawn()
            .unwrap();
        h.boot().await.unwrap();
        assert!(h.call(|d, _| d.fd_capable()).await.unwrap());
        for (bus, (usdo, sdo)) in BUSES.iter().zip(&counts) {
            count_requests(*bus, Arc::clone(usdo), Arc::clone(sdo));
        }
        h
    });
    let bus = format!("udp:{},udp:{}", BUSES[0], BUSES[1]);
    check(&gateway(&bus, &script()));
    // Every request on both buses; the node served each once (no repeat, nothing aborted
    // but the missing object's).
    let on = |i: usize| counts[i].0.load(Ordering::Relaxed);
    assert!(on(0) >= 6);
    assert_eq!(on(0), on(1));
    assert_eq!(counts[0].1.load(Ordering::Relaxed), 0);
    let stats = rt
        .block_on(node.call(|d, _| d.machine.usdo_server().unwrap().stats()))
        .unwrap();
    assert_eq!((stats.completed, stats.aborted, stats.repeats), (5, 1, 0));
    rt.block_on(node.shutdown());
}
