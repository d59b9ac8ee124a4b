//! The `duocan` tool against a duocan node on python-can's UDP bus. Runs inside `unshare -n`
//! with the tool built first (`.ci/tier-python.sh` does both): `cargo build -p duocan-cli`.

#[path = "common/peer.rs"]
mod peer;
#[path = "../../tests/common/runtime.rs"]
mod rt;

#[path = "common/tool.rs"]
mod tool;
use duocan::port::udp::{UdpBusConfig, UdpPort};
use duocan::runtime::{Handle, Runtime};
use peer::{group, Peer};
use rt::{sdo_node, single, TestNode};
use tool::duocan;

type Dev = duocan::Station<duocan::machine::SinglePort, TestNode>;

/// Node 5 with the SDO test entries on UDP bus `bus`.
async fn node_on(bus: u8) -> Handle<Dev> {
    beating_node_on(bus, 0).await
}

/// [`node_on`] with a heartbeat every `hb_ms` (0: none).
async fn beating_node_on(bus: u8, hb_ms: u16) -> Handle<Dev> {
    let h = Runtime::new(single(sdo_node(5, false, hb_ms, &[])))
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

/// `scan`, `nmt` and `pdo show` with a python `canopen` LocalNode (0x22) and a duocan node (5)
/// on one UDP bus: the tool finds exactly the two, drives the python node's NMT state and
/// reads its PDO configuration.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn scans_drives_and_reads_pdos_of_a_python_node() {
    let cfg = UdpBusConfig::numbered(22);
    let node = node_on(22).await;
    let (g, p) = group(&cfg);
    let mut py = Peer::spawn(&["node", "0x22", "100", &g, &p]).await;
    py.expect("STATE PRE-OPERATIONAL", 10).await;
    let bus = "udp:22";

    let (code, out, err) = duocan(bus, &["scan", "--listen", "500"]).await;
    assert_eq!(code, 0, "{err}");
    let rows: Vec<Vec<&str>> = out
        .lines()
        .skip(1)
        .map(|l| l.split_whitespace().collect())
        .collect();
    let ids: Vec<&str> = rows.iter().map(|r| r[0]).collect();
    assert_eq!(ids, ["0x05", "0x22"], "{out}");
    // node, state, device type, vendor, then product, revision, serial, name, description:
    // what the python dictionary does not have is empty, not an error.
    assert_eq!(
        rows[1],
        [
            "0x22",
            "pre-operational",
            "0x00020192",
            "0x0000d0ca",
            "-",
            "-",
            "-",
            "-",
            "-"
        ],
        "{out}"
    );
    // Node 5 sends no heartbeat (and booted before the tool listened): found by its SDO
    // answer alone.
    assert_eq!(rows[0][1..3], ["(not", "heard)"], "{out}");
    assert_eq!(rows[0][4], "0x00001234", "{out}");

    let (code, out, err) = duocan(bus, &["nmt", "start", "0x22", "--wait"]).await;
    assert_eq!(code, 0, "{err}");
    assert_eq!(out, "NMT start sent to node 0x22: operational\n");
    py.expect("STATE OPERATIONAL", 5).await;
    let (code, out, err) = duocan(bus, &["nmt", "preop", "all"]).await;
    assert_eq!(code, 0, "{err}");
    assert_eq!(out, "NMT preop sent to all nodes\n");
    py.expect("STATE PRE-OPERATIONAL", 5).await;

    // The python node has TPDO 1 (0x6000, 16 bits) and no RPDO; no description: no names.
    let (code, out, err) = duocan(bus, &["pdo", "show", "0x22"]).await;
    assert_eq!(code, 0, "{err}");
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(lines.len(), 2, "{out}");
    assert!(
        lines[1].starts_with("0x22  TPDO 1  0x1a2   yes      254 "),
        "{out}"
    );
    assert!(lines[1].ends_with("0x6000:00/16"), "{out}");
    py.stop().await;
    node.shutdown().await;
}

/// A bus nobody is on: exit 0 and the words, not an error.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn scan_of_an_empty_bus_says_so() {
    let (code, out, err) = duocan(
        "udp:23",
        &["scan", "--listen", "100", "--probe-timeout", "20"],
    )
    .await;
    assert_eq!(code, 0, "{err}");
    assert_eq!(out, "no nodes answered\n");
}

/// 1 MiB: the image, the domain, and the node's SDO transfer limit.
const MIB: usize = 1 << 20;

/// `flash` of a 1 MiB image to a duocan node with program download, and the same mebibyte to
/// a DOMAIN with `sdo write --file --verify`: both with their progress lines, which this test
/// writes to the log (uncaptured), so that the CI log shows how the transfers went.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn flashes_and_writes_a_mebibyte_with_progress_in_the_log() {
    use duocan::cia302::program::ProgramDictionary;
    use duocan::od::{comm, Access, DataType, ObjectDef};
    use duocan::sdo::SdoServerConfig;
    use duocan::{Node, NodeConfig, NodeId};
    use std::io::Write;

    let id = NodeId::new(9).unwrap();
    let mut od = comm::standard_dictionary(9, comm::Identity::default());
    od.upsert(
        ObjectDef::bytes(0x2002, 0, DataType::Domain, MIB as u32)
            .access(Access::Rw)
            .named("Domain"),
    );
    let mut n = Node::new(
        NodeConfig::slave(id),
        ProgramDictionary::new(od, duocan::cia302::program::RamStore::new(MIB as u32)),
    );
    n.sdo_server_mut()
        .set_config(SdoServerConfig::default().with_max_transfer(MIB));
    let node = Runtime::new(duocan::Station::single(n))
        .name("flash node")
        .port(UdpPort::open(UdpBusConfig::numbered(24)).expect("open the UDP bus"))
        .spawn()
        .unwrap();
    node.boot().await.unwrap();

    let dir = std::env::temp_dir().join(format!("duocan-cli-udp-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let img = dir.join("image.bin");
    let image: Vec<u8> = (0..MIB)
        .map(|i| (i as u32).wrapping_mul(2_654_435_761).to_le_bytes()[3])
        .collect();
    std::fs::write(&img, &image).unwrap();
    let img = img.to_str().unwrap();
    let want = format!("{:#x}", duocan::cia302::program::image_id(&image));

    let (code, out, err) = duocan(
        "udp:24",
        &["flash", "9", img, "--verify", "--expect-id", &want],
    )
    .await;
    // Uncaptured: the progress lines stand in the CI log.
    let _ = writeln!(
        std::io::stderr(),
        "duocan flash, its standard error:\n{err}"
    );
    assert_eq!(code, 0, "{err}");
    assert!(
        out.starts_with("flash node 0x09 program 1: 1048576 bytes in "),
        "{out}"
    );
    assert!(
        out.contains(
            "written, not read back (0x1F50 is write-only on this node), started; no error"
        ),
        "{out}"
    );
    for pct in ["(10%)", "(50%)", "(100%)"] {
        assert!(err.contains(pct), "no {pct} progress line: {err}");
    }
    let running = node.read(0x1F56, 1).await.unwrap();
    assert_eq!(
        running,
        duocan::cia302::program::image_id(&image).to_le_bytes(),
        "the new program runs"
    );

    let (code, out, err) = duocan(
        "udp:24",
        &[
            "sdo", "write", "9", "0x2002", "--file", img, "--verify", "--block",
        ],
    )
    .await;
    let _ = writeln!(
        std::io::stderr(),
        "duocan sdo write, its standard error:\n{err}"
    );
    assert_eq!(code, 0, "{err}");
    assert!(out.ends_with(", verified\n"), "{out}");
    assert!(
        err.contains("write node 0x09 0x2002:00: 1048576/1048576 bytes (100%)"),
        "{err}"
    );
    assert!(err.contains("verify node 0x09 0x2002:00:"), "{err}");
    assert_eq!(node.read(0x2002, 0).await.unwrap(), image);

    // Too large for the node: the node's abort and its meaning, exit 1, the old program kept.
    let big = dir.join("big.bin");
    std::fs::write(&big, vec![0u8; MIB + 1]).unwrap();
    let (code, _, err) = duocan("udp:24", &["-q", "flash", "9", big.to_str().unwrap()]).await;
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("download (0x1F50)") && err.contains("0x06070012"),
        "{err}"
    );
    assert_eq!(
        node.read(0x1F56, 1).await.unwrap(),
        duocan::cia302::program::image_id(&image).to_le_bytes()
    );
    let _ = std::fs::remove_dir_all(&dir);
    node.shutdown().await;
}

/// The commands that watch the wire, on the UDP bus: `record` writes what a duocan node and the
/// tool's own SDO read put on it, `dump` decodes the log, `monitor` (plain) reports the node.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn records_dumps_and_monitors_the_udp_bus() {
    let node = beating_node_on(23, 100).await;
    let bus = "udp:23";
    let dir = std::env::temp_dir().join(format!("duocan-watch-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let log = dir.join("bus.log");
    let pcap = dir.join("bus.pcap");
    let (l, p) = (log.to_str().unwrap(), pcap.to_str().unwrap());
    // Record for 1.5 s while an SDO read runs on the bus.
    let recording = tokio::spawn({
        let (l, p) = (l.to_string(), p.to_string());
        async move {
            duocan(
                bus,
                &["record", "--candump", &l, "--pcap", &p, "--duration", "1.5"],
            )
            .await
        }
    });
    tokio::time::sleep(std::time::Duration::from_millis(400)).await;
    let (code, _, err) = duocan(bus, &["sdo", "read", "5", "0x1018", "1", "u32"]).await;
    assert_eq!(code, 0, "{err}");
    let (code, out, err) = recording.await.unwrap();
    assert_eq!(code, 0, "{err}");
    println!("record:\n{out}");
    let (code, out, err) = duocan(bus, &["dump", l]).await;
    assert_eq!(code, 0, "{err}");
    println!("dump:\n{out}");
    assert!(
        out.contains("node 5 SDO upload 0x1018:01 = 0x00001234"),
        "the recorded SDO read, decoded: {out}"
    );
    assert!(out.contains("node 5 heartbeat"), "its heartbeats: {out}");
    let (code, out2, _) = duocan(bus, &["dump", p]).await;
    assert_eq!(code, 0);
    assert_eq!(
        out2.lines().count(),
        out.lines().count(),
        "the pcap holds what the log holds"
    );
    // The monitor, listen-only, plain: node 5's heartbeat state within its run.
    let (code, out, err) = duocan(
        bus,
        &["monitor", "--plain", "--duration", "1.5", "--every", "1"],
    )
    .await;
    assert_eq!(code, 0, "{err}");
    println!("monitor:\n{out}");
    assert!(out.contains("status: 1 nodes"), "{out}");
    assert!(out.contains("0x05"), "{out}");
    node.shutdown().await;
    let _ = std::fs::remove_dir_all(&dir);
}
