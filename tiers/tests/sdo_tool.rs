//! The `sdo_tool` example against a duocan node on python-can's UDP bus. Runs inside
//! `unshare -n` with the example built first (`.ci/tier-python.sh` does both):
//! `cargo build -p duocan --features udp --example sdo_tool`.

#[path = "../../tests/common/runtime.rs"]
mod rt;

use duocan::port::udp::{UdpBusConfig, UdpPort};
use duocan::runtime::{Handle, Runtime};
use rt::{sdo_node, single, TestNode};
use std::path::PathBuf;
use std::process::Output;

type Dev = duocan::Station<duocan::machine::SinglePort, TestNode>;

/// target/<profile>/examples/sdo_tool, next to this test's target/<profile>/deps/.
fn tool() -> PathBuf {
    let exe = std::env::current_exe().expect("test executable path");
    let profile_dir = exe
        .parent()
        .and_then(|deps| deps.parent())
        .expect("target/<profile>/deps/<test>");
    let bin = profile_dir.join("examples").join("sdo_tool");
    assert!(
        bin.exists(),
        "{} is missing: build it first with `cargo build -p duocan --features udp --example sdo_tool`",
        bin.display()
    );
    bin
}

async fn sdo_tool(args: &[&str]) -> (i32, String, String) {
    let out: Output = tokio::process::Command::new(tool())
        .args(args)
        .output()
        .await
        .expect("run sdo_tool");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// Node 5 with the SDO test entries on UDP bus `bus`.
async fn node_on(bus: u8) -> Handle<Dev> {
    let h = Runtime::new(single(sdo_node(5, false, 0, &[])))
        .name("node5")
        .port(
            UdpPort::open(UdpBusConfig::numbered(bus))
                .expect("open the UDP bus (inside unshare -n?)"),
        )
        .spawn()
        .unwrap();
    h.boot().await.unwrap();
    h
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn reads_writes_and_identity_of_a_duocan_node() {
    let node = node_on(20).await;
    let port = "udp:20";

    let (code, out, err) = sdo_tool(&["--port", port, "--node", "5", "read", "0x1018", "1"]).await;
    assert_eq!(code, 0, "{err}");
    assert_eq!(out.trim(), "0x1018:01 = [34 12 00 00] = 4660 (0x00001234)");

    let (code, out, err) = sdo_tool(&[
        "--port", port, "--node", "5", "write", "0x1017", "0", "u16", "100",
    ])
    .await;
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("0x1017:00 written (2 bytes)"), "{out}");
    assert_eq!(node.read(0x1017, 0).await.unwrap(), 100u16.to_le_bytes());
    let (_, out, _) = sdo_tool(&[
        "--port", port, "--node", "5", "read", "0x1017", "0", "--type", "u16",
    ])
    .await;
    assert_eq!(out.trim(), "0x1017:00 = 100");

    // A string longer than 4 bytes: segmented both ways.
    let text = "written by sdo_tool";
    let (code, _, err) = sdo_tool(&[
        "--port", port, "--node", "5", "write", "0x2001", "0", "str", text,
    ])
    .await;
    assert_eq!(code, 0, "{err}");
    assert_eq!(node.read(0x2001, 0).await.unwrap(), text.as_bytes());
    let (_, out, _) = sdo_tool(&["-p", port, "-n", "5", "read", "0x2001", "0", "-t", "str"]).await;
    assert_eq!(out.trim(), format!("0x2001:00 = {text}"));
    let (code, _, err) = sdo_tool(&[
        "-p",
        port,
        "-n",
        "5",
        "write",
        "0x2002",
        "0",
        "hex",
        "01 02 0a ff",
    ])
    .await;
    assert_eq!(code, 0, "{err}");
    assert_eq!(node.read(0x2002, 0).await.unwrap(), [1, 2, 0x0A, 0xFF]);

    let (code, out, err) = sdo_tool(&["--port", port, "--node", "5", "info"]).await;
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("vendor-ID         [34 12 00 00]"), "{out}");
    assert!(out.contains("product code      [05 00 00 00]"), "{out}");
    assert!(out.contains("heartbeat (ms)    100"), "{out}");
    assert!(out.contains("device name       duocan"), "{out}");
    assert!(
        out.contains("hardware version  - (the node has no 0x1009:00)"),
        "{out}"
    );
    node.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn failures_say_what_failed_and_exit_non_zero() {
    let node = node_on(21).await;
    let port = "udp:21";

    // The server aborts: node, object and the abort code's meaning.
    let (code, out, err) = sdo_tool(&["--port", port, "--node", "5", "read", "0x2fff", "0"]).await;
    assert_eq!(code, 1, "{out}");
    assert!(err.contains("node 5"), "{err}");
    assert!(err.contains("object 0x2fff sub 0"), "{err}");
    assert!(
        err.contains("object does not exist in the object dictionary"),
        "{err}"
    );
    let (code, _, err) = sdo_tool(&[
        "--port", port, "--node", "5", "write", "0x1018", "1", "u32", "7",
    ])
    .await;
    assert_eq!(code, 1);
    assert!(err.contains("download to node 5"), "{err}");
    assert!(err.contains("read only"), "{err}");

    // Nobody answers: a timeout, with what to check.
    let (code, _, err) = sdo_tool(&[
        "--port",
        port,
        "--node",
        "9",
        "--timeout-ms",
        "200",
        "read",
        "0x1000",
        "0",
    ])
    .await;
    assert_eq!(code, 1);
    assert!(err.contains("node 9"), "{err}");
    assert!(err.contains("no answer in time"), "{err}");

    // Bad arguments: exit 2 before any traffic.
    let (code, _, err) = sdo_tool(&["--port", port, "--node", "200", "read", "0x1000", "0"]).await;
    assert_eq!(code, 2);
    assert!(err.contains("a node-ID is 1-127"), "{err}");
    let (code, _, err) = sdo_tool(&[
        "--port", port, "--node", "5", "write", "0x1017", "0", "u8", "300",
    ])
    .await;
    assert_eq!(code, 2);
    assert!(err.contains("300 does not fit u8"), "{err}");
    // Inputs that made the tool panic or misread them: exit 2, the argument quoted, no panic.
    for (args, says) in [
        (
            &["--node=--170141183460469231731687303715884105728", "info"][..],
            "no sign allowed here",
        ),
        (&["--node=-0x-5", "info"][..], "no sign allowed here"),
        (&["--node=+5", "info"][..], "'+' is not a decimal digit"),
        (
            &["--node", "5", "write", "0x2002", "0", "hex", "0é"][..],
            "is not hex",
        ),
        (
            &["--node", "5", "read", "0x1é", "0"][..],
            "'é' is not a hex digit",
        ),
        (
            &["--node", "5", "--timeout-ms", "0", "info"][..],
            "give 1 to 3600000",
        ),
    ] {
        let mut all = vec!["--port", port];
        all.extend_from_slice(args);
        let (code, _, err) = sdo_tool(&all).await;
        assert_eq!(code, 2, "{args:?}: {err}");
        assert!(err.contains(says), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
    let (code, _, err) = sdo_tool(&["--port", "udp:+5", "--node", "5", "info"]).await;
    assert_eq!(code, 2);
    assert!(err.contains("udp:N takes a bus number"), "{err}");
    let (code, _, err) = sdo_tool(&["--port", "udp:x", "--node", "5", "info"]).await;
    assert_eq!(code, 2);
    assert!(err.contains("udp:N takes a bus number"), "{err}");
    assert_eq!(
        node.read(0x1017, 0).await.unwrap(),
        [0, 0],
        "nothing written"
    );
    node.shutdown().await;
}
