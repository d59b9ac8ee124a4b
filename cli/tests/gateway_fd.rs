//! `duocan --fd NODE-ID gateway` on a CANopen FD network: the CiA 309-3 requests read and write
//! over USDO (CiA 1301) in CAN FD frames, with the same answers as over SDO, against a duocan
//! node serving USDO on python-can's UDP bus with FD (bus 88 of the test networks, loopback),
//! and on two such buses merged (89 and 90), the node on both.

mod common;
use common::fd::{count_requests, fd_node, fd_node_on};
use duocan::machine::{BusLink, Device, Station};
use duocan::port::udp::{UdpBusConfig, UdpPort};
use duocan::runtime::Runtime;
use duocan_redundancy::{DualBus, DualBusConfig};

/// Runs `duocan --bus BUS --fd 127 gateway` with `script` on standard input; its output.
fn gateway(bus: &str, script: &str) -> String {
    let args = ["--bus", bus, "--fd", "127", "--timeout", "300", "gateway"];
    let r = common::duocan_with_input(&args, script);
    assert_eq!(r.code, 0, "{}", r.err);
    r.out
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
    let (node, requests) = rt.block_on(async { (fd_node_on(BUS).await, count_requests(BUS)) });
    check(&gateway(&format!("udp:{BUS}"), &script()));
    // Six transfers, the string's segmented: over USDO, none over classic SDO.
    assert!(requests.usdo() >= 6);
    assert_eq!(requests.sdo(), 0);
    rt.block_on(node.shutdown());
}

#[test]
fn the_gateway_reads_and_writes_over_usdo_on_two_fd_buses() {
    const BUSES: [u8; 2] = [89, 90];
    let rt = tokio::runtime::Runtime::new().unwrap();
    let (node, requests) = rt.block_on(async {
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
        (h, BUSES.map(count_requests))
    });
    let bus = format!("udp:{},udp:{}", BUSES[0], BUSES[1]);
    check(&gateway(&bus, &script()));
    // Every request on both buses; the node served each once (no repeat, nothing aborted
    // but the missing object's).
    assert!(requests[0].usdo() >= 6);
    assert_eq!(requests[0].usdo(), requests[1].usdo());
    assert_eq!(requests[0].sdo() + requests[1].sdo(), 0);
    let stats = rt
        .block_on(node.call(|d, _| d.machine.usdo_server().unwrap().stats()))
        .unwrap();
    assert_eq!((stats.completed, stats.aborted, stats.repeats), (5, 1, 0));
    rt.block_on(node.shutdown());
}
