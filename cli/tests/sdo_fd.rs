//! `duocan --fd NODE-ID sdo read|write` on a CANopen FD network: the same commands and output
//! as over SDO, carried by USDO (CiA 1301) in CAN FD frames, against a duocan node serving USDO
//! on python-can's UDP bus with FD (bus 77 of the test networks, loopback).

mod common;
use common::duocan;
use common::fd::{count_requests, fd_node_on};

const BUS: u8 = 77;

#[test]
fn sdo_read_and_write_go_over_usdo_with_fd() {
    let rt = tokio::runtime::Runtime::new().unwrap();
    let (node, requests) = rt.block_on(async { (fd_node_on(BUS).await, count_requests(BUS)) });
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
    assert!(requests.usdo() >= 6);
    assert_eq!(requests.sdo(), 0);
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

/// The simulated nodes on a CANopen FD bus: `--bus sim-nodes:fd`, or `sim-nodes` with `--fd`,
/// read their identity over USDO, typed by the simulated description as on `sim-nodes`.
#[test]
fn the_simulated_fd_nodes_answer_over_usdo() {
    for args in [
        &["--bus", "sim-nodes:fd"][..],
        &["--bus", "sim-nodes", "--fd", "127"][..],
    ] {
        let mut all = args.to_vec();
        all.extend_from_slice(&["sdo", "read", "5", "0x1018", "1"]);
        let r = duocan(&all);
        assert_eq!(
            (r.code, r.out.as_str()),
            (0, "13683200\n"),
            "{args:?}: {}",
            r.err
        );
    }
}
