//! The `duocan` tool against a duocan node on python-can's UDP bus. Runs inside `unshare -n`
//! with the tool built first (`.ci/tier-python.sh` does both): `cargo build -p duocan-cli`.

#[path = "../../tests/common/runtime.rs"]
mod rt;

use duocan::port::udp::{UdpBusConfig, UdpPort};
use duocan::runtime::{Handle, Runtime};
use rt::{sdo_node, single, TestNode};
use std::path::PathBuf;
use std::process::Output;

type Dev = duocan::Station<duocan::machine::SinglePort, TestNode>;

/// target/<profile>/duocan, next to this test's target/<profile>/deps/.
fn tool() -> PathBuf {
    let exe = std::env::current_exe().expect("test executable path");
    let profile_dir = exe
        .parent()
        .and_then(|deps| deps.parent())
        .expect("target/<profile>/deps/<test>");
    let bin = profile_dir.join("duocan");
    assert!(
        bin.exists(),
        "{} is missing: build it first with `cargo build -p duocan-cli`",
        bin.display()
    );
    bin
}

/// Runs `duocan --bus <bus> <args>`: exit code, standard output, standard error.
async fn duocan(bus: &str, args: &[&str]) -> (i32, String, String) {
    let out: Output = tokio::process::Command::new(tool())
        .arg("--bus")
        .arg(bus)
        .args(args)
        .env_remove("DUOCAN_BUS")
        .output()
        .await
        .expect("run duocan");
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
async fn reads_and_writes_a_duocan_node() {
    let node = node_on(20).await;
    let bus = "udp:20";

    let (code, out, err) = duocan(bus, &["sdo", "read", "5", "0x1018", "1"]).await;
    assert_eq!(code, 0, "{err}");
    assert_eq!(out.trim(), "[34 12 00 00] = 4660 (0x00001234)");

    let (code, out, err) = duocan(bus, &["sdo", "write", "5", "0x1017", "0", "u16", "100"]).await;
    assert_eq!(code, 0, "{err}");
    assert_eq!(out.trim(), "node 0x05 0x1017:00: written, 2 bytes");
    assert_eq!(node.read(0x1017, 0).await.unwrap(), 100u16.to_le_bytes());
    let (_, out, _) = duocan(bus, &["sdo", "read", "5", "0x1017", "0", "u16"]).await;
    assert_eq!(out.trim(), "100");

    // A string longer than 4 bytes: segmented both ways, then block with a CRC.
    let text = "written by the duocan tool";
    let (code, _, err) = duocan(
        bus,
        &["sdo", "write", "5", "0x2001", "0", "str", text, "--verify"],
    )
    .await;
    assert_eq!(code, 0, "{err}");
    assert_eq!(node.read(0x2001, 0).await.unwrap(), text.as_bytes());
    let (_, out, _) = duocan(
        bus,
        &["sdo", "read", "5", "0x2001", "0", "str", "--block", "--crc"],
    )
    .await;
    assert_eq!(out.trim(), text);
    let (code, _, err) = duocan(
        bus,
        &["sdo", "write", "5", "0x2002", "0", "hex", "01 02 0a ff"],
    )
    .await;
    assert_eq!(code, 0, "{err}");
    assert_eq!(node.read(0x2002, 0).await.unwrap(), [1, 2, 0x0A, 0xFF]);
    node.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn failures_say_what_failed_and_exit_non_zero() {
    let node = node_on(21).await;
    let bus = "udp:21";

    // The server aborts: node, object and the abort code's meaning.
    let (code, out, err) = duocan(bus, &["sdo", "read", "5", "0x2fff", "0"]).await;
    assert_eq!(code, 1, "{out}");
    assert!(err.contains("node 5"), "{err}");
    assert!(err.contains("object 0x2fff sub 0"), "{err}");
    assert!(
        err.contains("object does not exist in the object dictionary"),
        "{err}"
    );
    let (code, _, err) = duocan(bus, &["sdo", "write", "5", "0x1018", "1", "u32", "7"]).await;
    assert_eq!(code, 1);
    assert!(err.contains("download to node 5"), "{err}");
    assert!(err.contains("read only"), "{err}");

    // Nobody answers: a timeout, with what to check.
    let (code, _, err) = duocan(
        bus,
        &["--timeout", "200", "sdo", "read", "9", "0x1000", "0"],
    )
    .await;
    assert_eq!(code, 1);
    assert!(err.contains("node 9"), "{err}");
    assert!(err.contains("no answer in time"), "{err}");

    // Bad arguments: exit 2 before any traffic.
    for (args, says) in [
        (
            &["sdo", "read", "200", "0x1000", "0"][..],
            "a node-ID is 1-127",
        ),
        (
            &["sdo", "write", "5", "0x1017", "0", "u8", "300"][..],
            "300 does not fit u8",
        ),
        (
            &["sdo", "write", "5", "0x2002", "0", "hex", "0é"][..],
            "is not hex",
        ),
        (
            &["sdo", "read", "5", "0x1é", "0"][..],
            "'é' is not a hex digit",
        ),
        (
            &["--timeout", "0", "sdo", "read", "5", "0x1000"][..],
            "give 1 to 3600000",
        ),
    ] {
        let (code, _, err) = duocan(bus, args).await;
        assert_eq!(code, 2, "{args:?}: {err}");
        assert!(err.contains(says), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
    for bad in ["udp:+5", "udp:x"] {
        let (code, _, err) = duocan(bad, &["sdo", "read", "5", "0x1000"]).await;
        assert_eq!(code, 2);
        assert!(err.contains("udp:N takes a bus number"), "{err}");
    }
    assert_eq!(
        node.read(0x1017, 0).await.unwrap(),
        [0, 0],
        "nothing written"
    );
    node.shutdown().await;
}
