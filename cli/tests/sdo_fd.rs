//! `duocan --fd NODE-ID sdo read|write` on a CANopen FD network: the same commands and output
//! as over SDO, carried by USDO (CiA 1301) in CAN FD frames, against a duocan node serving USDO
//! on python-can's UDP bus with FD (bus 77 of the test networks, loopback).

mod common;
use common::duocan;
use duocan::machine::{SinglePort, Station};
use duocan::od::{comm, Access, DataType, ObjectDef};
use duocan::port::udp::{UdpBusConfig, UdpPort};
use duocan::port::{AnyInput, Port};
use duocan::runtime::Runtime;
use duocan::{Id, Node, NodeConfig, NodeId};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

const BUS: u8 = 77;

#[test]
fn sdo_read_and_write_go_over_usdo_with_fd() {
    let rt = tokio::runtime::Runtime::new().unwrap();
    let usdo_requests = Arc::new(AtomicUsize::new(0));
    let sdo_requests = Arc::new(AtomicUsize::new(0));
    let node = rt.block_on(async {
        let cfg = || UdpBusConfig::numbered(BUS).with_fd();
        let mut od = comm::standard_dictionary(5, Default::default());
        od.insert_all(&[
            ObjectDef::u32(0x2000, 0, Access::Rw, 0xCAFE_F00D),
            ObjectDef::bytes(0x2001, 0, DataType::VisibleString, 200).access(Access::Rw),
        ])
        .unwrap();
        let node = Node::new(NodeConfig::slave(NodeId::must(5)).with_fd(true), od);
        let h = Runtime::new(Station::new(SinglePort::fd(), node))
            .port(UdpPort::open(cfg()).unwrap())
            .spawn()
            .unwrap();
        h.boot().await.unwrap();
        // A listener counting the tool's USDO requests (CAN FD frames from node-ID 127).
        let mut tester = UdpPort::open(cfg()).unwrap();
        let (usdo, sdo) = (usdo_requests.clone(), sdo_requests.clone());
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
        h
    });
    let bus = format!("udp:{BUS}");
    let fd = |args: &[&str]| {
        let mut all = vec!["--bus", &bus, "--fd", "127", "--timeout", "300"];
        all.extend_from_slice(args);
        duocan(&all)
    };
    let r = fd(&["sdo", "read", "5", "0x2000", "0", "u32"]);
    assert_eq!((r.code, r.out.as_str()), (0, "3405705229\n"), "{}", r.err);
    let r = fd(&["sdo", "write", "5", "0x2000", "0", "u32", "42", "--verify"]);
    assert_eq!(r.code, 0, "{}", r.err);
    assert_eq!(r.out, "node 0x05 0x2000:00: written, 4 bytes, verified\n");
    // Longer than one frame: a segmented USDO transfer each way.
    let text = "a visible string longer than the fifty-six bytes of one USDO frame, over CAN FD";
    let r = fd(&["sdo", "write", "5", "0x2001", "0", "str", text]);
    assert_eq!(r.code, 0, "{}", r.err);
    let r = fd(&["sdo", "read", "5", "0x2001", "0", "str"]);
    assert_eq!((r.code, r.out.trim_end()), (0, text), "{}", r.err);
    // The node's refusal is the same error and exit code as over SDO.
    let r = fd(&["sdo", "read", "5", "0x1234", "1"]);
    assert_eq!(r.code, 1);
    assert!(r.err.contains("0x06020000"), "{}", r.err);
    // Each command went over USDO (the write's --verify reads back: six transfers, the
    // segmented ones of several requests each), none over classic SDO.
    assert!(usdo_requests.load(Ordering::Relaxed) >= 6);
    assert_eq!(sdo_requests.load(Ordering::Relaxed), 0);
    // Two interfaces, or a simulated network, cannot be an FD network: a usage error.
    let r = duocan(&[
        "--bus",
        "sim-station",
        "--fd",
        "127",
        "sdo",
        "read",
        "5",
        "0x1000",
    ]);
    assert_eq!(r.code, 2, "{}", r.err);
    rt.block_on(node.shutdown());
}
