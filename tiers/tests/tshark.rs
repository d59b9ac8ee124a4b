//! Wireshark's CANopen dissector reads duocan's pcap captures (LINKTYPE_CAN_SOCKETCAN).
//!
//! A master and a slave run on the simulated bus with the master's logical bus tapped into a
//! pcap file; `tshark` (Debian package `tshark`, on PATH) decodes it as CANopen and the test
//! asserts on the dissector's fields. The demo's pcap of its turnout rack (the CANopen rack whose
//! active board is killed) is decoded the same way. `.ci/tier-tshark.sh` installs tshark and
//! runs this.

#[allow(dead_code)]
#[path = "../../examples/demo/scenario/mod.rs"]
mod scenario;

use duocan::capture::recorder::{Filter, Recorder, Tapped};
use duocan::emcy::{code, register};
use duocan::machine::{Composite, SinglePort, Station};
use duocan::od::{comm, DynamicDictionary};
use duocan::od::{Access, DataType, DefaultValue, ObjectDef};
use duocan::pdo::params;
use duocan::sdo::{SdoClient, SdoOptions};
use duocan::sim::{BusConfig, SimNetwork};
use duocan::{Duration, Instant, NmtCommand, NmtTarget, Node, NodeConfig, NodeId};
use std::process::Command;
use std::sync::Arc;

type Plain = Station<SinglePort, Node<DynamicDictionary>>;
type Recorded = Station<SinglePort, Tapped<Composite<Node<DynamicDictionary>, SdoClient>>>;

fn od(id: u8) -> DynamicDictionary {
    comm::standard_dictionary(id, comm::Identity::default())
}

/// Runs the scenario and returns the pcap path.
fn capture() -> std::path::PathBuf {
    let path = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("tshark-scenario.pcap");
    let file = std::io::BufWriter::new(std::fs::File::create(&path).expect("create pcap"));
    let rec = Arc::new(
        Recorder::with_epoch(1_700_000_000_000_000)
            .pcap(Filter::All, file)
            .expect("pcap header"),
    );
    let mut sim = SimNetwork::new(7);
    let bus = sim.add_bus(BusConfig::new("can0", 500_000));
    let master_node = Node::new(NodeConfig::master(NodeId::must(1)), od(1));
    let master = Composite::new(master_node, SdoClient::new(1024));
    let m = sim
        .add_device::<Recorded>(
            "master",
            Station::single(Tapped::new(master, rec.clone())),
            &[bus],
        )
        .unwrap();
    let mut slave_od = od(5);
    slave_od
        .insert(
            ObjectDef::bytes(0x2001, 0, DataType::VisibleString, 64)
                .access(Access::Rw)
                .default(DefaultValue::Bytes(b"segmented upload")),
        )
        .unwrap();
    // TPDO1 on 0x185: 0x2101 (u16 0xBEEF), sent every 50 ms while operational.
    slave_od.upsert(ObjectDef::u16(0x2101, 0, Access::Rw, 0xBEEF).mappable());
    for d in params::tpdo_comm(1, DefaultValue::NodeIdPlus(0x180), 255, 0, 50) {
        slave_od.upsert(d);
    }
    for d in params::tpdo_mapping::<9>(1, &[0x2101_0010]) {
        slave_od.upsert(d);
    }
    let s = sim
        .add_device::<Plain>(
            "slave",
            Station::single(Node::new(NodeConfig::slave(NodeId::must(5)), slave_od)),
            &[bus],
        )
        .unwrap();
    let t0 = Instant::ZERO;
    {
        let n = &mut sim.device_mut(s).machine;
        n.set(t0, comm::HEARTBEAT_PRODUCER, 0, 100u16).unwrap();
        n.boot(t0);
    }
    {
        let n = &mut sim.device_mut(m).machine.inner.a;
        n.set(t0, comm::SYNC_PERIOD, 0, 50_000u32).unwrap();
        n.set(t0, comm::SYNC_COB_ID, 0, 0x4000_0080u32).unwrap();
        n.boot(t0);
    }
    sim.run_until(Instant::from_millis(120));
    let now = sim.now();
    sim.device_mut(m)
        .machine
        .inner
        .a
        .nmt_command(now, NmtCommand::Start, NmtTarget::Node(NodeId::must(5)))
        .unwrap();
    sim.run_for(Duration::from_millis(130));
    let now = sim.now();
    sim.device_mut(s)
        .machine
        .emcy_raise(now, code::GENERIC, register::GENERIC, [1, 2, 3, 4, 5]);
    sim.run_for(Duration::from_millis(100));
    // SDO: an expedited and a segmented upload from the slave.
    let now = sim.now();
    let client = &mut sim.device_mut(m).machine.inner.b;
    client
        .upload(now, NodeId::must(5), 0x1018, 1, SdoOptions::default())
        .unwrap();
    sim.run_for(Duration::from_millis(20));
    let now = sim.now();
    let client = &mut sim.device_mut(m).machine.inner.b;
    client
        .upload(now, NodeId::must(5), 0x2001, 0, SdoOptions::default())
        .unwrap();
    sim.run_for(Duration::from_millis(50));
    rec.flush().expect("flush pcap");
    assert_eq!(rec.errors(), 0);
    path
}

fn tshark(path: &std::path::Path, filter: &str, fields: &[&str]) -> Vec<Vec<String>> {
    let mut cmd = Command::new("tshark");
    cmd.args(["-r"]).arg(path);
    cmd.args([
        "-d",
        "can.subdissector=canopen",
        "-Y",
        filter,
        "-T",
        "fields",
        "-E",
        "separator=;",
    ]);
    for f in fields {
        cmd.args(["-e", f]);
    }
    let out = cmd
        .output()
        .unwrap_or_else(|e| panic!("cannot run tshark (install Debian's `tshark`): {e}"));
    assert!(
        out.status.success(),
        "tshark failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| l.split(';').map(str::to_owned).collect())
        .collect()
}

#[test]
fn tshark_decodes_nmt_heartbeat_sync_emcy_sdo_and_pdo() {
    let path = capture();
    let all = tshark(
        &path,
        "canopen",
        &["frame.number", "can.id", "canopen.function_code"],
    );
    assert!(all.len() >= 8, "frames decoded as CANopen: {all:?}");

    let boot = tshark(
        &path,
        "can.id == 0x705 && canopen.nmt_guard.state == 0",
        &["canopen.node_id"],
    );
    assert_eq!(boot, [["0x00000005"]], "boot-up of node 5");

    let nmt = tshark(
        &path,
        "can.id == 0",
        &["canopen.nmt_ctrl.cd", "canopen.nmt_ctrl.node_id"],
    );
    assert_eq!(nmt, [["0x01", "0x05"]], "NMT start node 5: {nmt:?}");

    let hb = tshark(
        &path,
        "can.id == 0x705 && canopen.nmt_guard.state != 0",
        &["canopen.nmt_guard.state"],
    );
    assert!(hb.len() >= 2, "heartbeats: {hb:?}");
    assert_eq!(
        hb[0],
        ["0x7f"],
        "pre-operational before the start command arrives"
    );
    assert_eq!(hb.last().unwrap(), &["0x05"], "operational after it");

    let sync = tshark(&path, "can.id == 0x80 && frame.len == 8", &["frame.number"]);
    assert!(sync.len() >= 5, "SYNC every 50 ms: {sync:?}");

    let emcy = tshark(
        &path,
        "can.id == 0x85",
        &[
            "canopen.em.err_code",
            "canopen.em.err_reg",
            "canopen.em.err_field",
        ],
    );
    assert_eq!(emcy.len(), 1, "{emcy:?}");
    assert_eq!(emcy[0][0], "0x1000");
    assert_eq!(emcy[0][1], "0x01");
    assert_eq!(emcy[0][2].replace(':', ""), "0102030405");

    let req = tshark(
        &path,
        "can.id == 0x605",
        &[
            "canopen.sdo.ccs",
            "canopen.sdo.main_idx",
            "canopen.sdo.sub_idx",
        ],
    );
    let res = tshark(
        &path,
        "can.id == 0x585",
        &[
            "canopen.sdo.scs",
            "canopen.sdo.main_idx",
            "canopen.sdo.e",
            "canopen.sdo.data.bytes",
        ],
    );
    println!("SDO requests {req:?}\nSDO responses {res:?}");
    assert_eq!(
        req[0][1..],
        ["0x1018", "0x01"],
        "expedited upload request of 0x1018:01"
    );
    assert_eq!(res[0][1], "0x1018");
    assert_eq!(res[0][2], "1", "expedited response");
    assert_eq!(
        req[1][1..],
        ["0x2001", "0x00"],
        "segmented upload request of 0x2001"
    );
    assert_eq!(res[1][3], "10000000", "segmented: size 16 announced");
    assert!(
        req[2..].iter().all(|r| r[0] == "3"),
        "upload segment requests: {req:?}"
    );
    let data: String = res[2..].iter().map(|r| r[3].as_str()).collect();
    let want: String = b"segmented upload"
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    assert!(data.starts_with(&want), "segments carry the string: {data}");

    let pdo = tshark(
        &path,
        "can.id == 0x185",
        &["canopen.function_code", "canopen.pdo.data.bytes"],
    );
    assert!(
        pdo.len() >= 3,
        "TPDO1 every 50 ms once operational: {pdo:?}"
    );
    assert!(
        pdo.iter().all(|p| p[1] == "efbe"),
        "0xBEEF little-endian: {pdo:?}"
    );
    let pre = tshark(
        &path,
        "can.id == 0x185 && frame.time_relative < 0.12",
        &["frame.number"],
    );
    assert!(pre.is_empty(), "no PDO before the NMT start: {pre:?}");
}

/// Seconds of simulated time of a packet, from its epoch time as tshark prints it.
fn sim_seconds(epoch: &str) -> f64 {
    epoch.parse::<f64>().unwrap() - scenario::outputs::EPOCH_US as f64 / 1e6
}

#[test]
fn tshark_decodes_the_demo_turnout_rack_as_canopen() {
    // The station's devices need a big stack in debug builds (see tests/demo.rs).
    std::thread::Builder::new()
        .stack_size(256 << 20)
        .spawn(demo_pcap)
        .unwrap()
        .join()
        .unwrap();
}

fn demo_pcap() {
    use scenario::analysis::Analysis;
    let st = scenario::run().expect("the demo's device descriptions read");
    let a = Analysis::new(&st);
    let o = a.outcome();
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("demo-tshark");
    let paths = scenario::outputs::write_all(&st, &a.chart(), &dir).unwrap();
    let path = paths
        .pcaps
        .iter()
        .find(|p| p.ends_with("turnout1.pcap"))
        .expect("a pcap of the turnout rack's bus 1");

    // Every frame of the CANopen rack is CANopen to Wireshark.
    let all = tshark(path, "frame", &["frame.number"]);
    let canopen = tshark(path, "canopen", &["frame.number"]);
    assert!(all.len() > 10_000, "{} frames", all.len());
    assert_eq!(canopen.len(), all.len());

    // P2's standby B (0x22) is started once, at the instant the demo measured.
    let start = tshark(
        path,
        "can.id == 0 && canopen.nmt_ctrl.node_id == 0x22",
        &["frame.time_epoch", "canopen.nmt_ctrl.cd"],
    );
    assert_eq!(start.len(), 1, "{start:?}");
    assert_eq!(start[0][1], "0x01", "NMT start");
    let measured = o
        .failovers
        .iter()
        .find(|f| f.what.contains("P2: board B started"))
        .unwrap();
    let at = sim_seconds(&start[0][0]);
    assert!(
        (at - measured.at.as_micros() as f64 / 1e6).abs() < 2e-6,
        "{at} vs {}",
        measured.at
    );

    // The killed A (0x12) is silent from its power loss until its replacement, a spare without
    // node-ID, is given 0x12 by LSS and boots.
    let booted = o.replacements[0]
        .booted
        .expect("the spare boots")
        .as_micros() as f64
        / 1e6;
    let killed = st
        .happened
        .iter()
        .find(|h| matches!(h.act, scenario::Act::BoardKilled { .. }))
        .unwrap()
        .at
        .as_micros() as f64
        / 1e6;
    let a_hb: Vec<(f64, String)> = tshark(
        path,
        "can.id == 0x712",
        &["frame.time_epoch", "canopen.nmt_guard.state"],
    )
    .into_iter()
    .map(|r| (sim_seconds(&r[0]), r[1].clone()))
    .collect();
    let gap: Vec<_> = a_hb
        .iter()
        .filter(|(t, _)| *t > killed && *t < booted - 0.000_5)
        .collect();
    assert!(gap.is_empty(), "{gap:?}");
    let boots: Vec<f64> = a_hb
        .iter()
        .filter(|(_, s)| s == "0x00")
        .map(|x| x.0)
        .collect();
    assert_eq!(boots.len(), 2, "power-on and replacement: {boots:?}");
    assert!(
        (boots[1] - booted).abs() < 0.001,
        "{boots:?} against {booted}"
    );
    assert!(
        a_hb.iter().any(|(t, s)| *t < killed && s == "0x05"),
        "operational before"
    );

    // The command due at 7 s went to the dead A, then to B, which answered with the same bytes.
    let to_a = tshark(
        path,
        "can.id == 0x212",
        &["frame.time_epoch", "canopen.pdo.data.bytes"],
    );
    let to_b = tshark(
        path,
        "can.id == 0x222",
        &["frame.time_epoch", "canopen.pdo.data.bytes"],
    );
    let late_a: Vec<_> = to_a
        .iter()
        .filter(|r| sim_seconds(&r[0]) > killed)
        .collect();
    assert_eq!(late_a.len(), 1, "{to_a:?}");
    let first_b = to_b
        .iter()
        .find(|r| sim_seconds(&r[0]) > killed)
        .expect("a command to B");
    assert_eq!(first_b[1], late_a[0][1], "the same command, resent");
    let answer = tshark(
        path,
        "can.id == 0x2a2",
        &["frame.time_epoch", "canopen.pdo.data.bytes"],
    );
    assert!(answer
        .iter()
        .any(|r| r[1] == first_b[1] && sim_seconds(&r[0]) > sim_seconds(&first_b[0])));

    // The replacement A is configured over SDO: its heartbeat producer time written.
    let sdo = tshark(
        path,
        "can.id == 0x612 && canopen.sdo.main_idx == 0x1017",
        &["frame.time_epoch", "canopen.sdo.ccs"],
    );
    assert!(
        sdo.iter()
            .any(|r| r[1] == "1" && sim_seconds(&r[0]) > booted),
        "{sdo:?}"
    );

    // SYNC every 20 ms all day, from whichever master is active, on whichever bus works: the
    // maintainer cuts bus 1 as bus 2 comes back, so the two buses' captures together.
    let bus2 = paths
        .pcaps
        .iter()
        .find(|p| p.ends_with("turnout2.pcap"))
        .expect("a pcap of the turnout rack's bus 2");
    let mut sync: Vec<f64> = [path, bus2]
        .into_iter()
        .flat_map(|p| tshark(p, "can.id == 0x80", &["frame.time_epoch"]))
        .map(|r| sim_seconds(&r[0]))
        .collect();
    sync.sort_by(f64::total_cmp);
    // A SYNC on both buses is one SYNC (its copies are microseconds apart).
    sync.dedup_by(|b, a| *b - *a < 1e-3);
    assert!(sync.len() > 850, "{} SYNC", sync.len());
    // The longest gap is the master takeover's, as the demo measured it, within its bound.
    let gap = sync.windows(2).map(|w| w[1] - w[0]).fold(0.0, f64::max);
    let takeover = o
        .failovers
        .iter()
        .find(|f| f.rack == "turnout rack" && f.what == "SYNC gap over the takeover")
        .expect("the demo measures the SYNC gap over the turnout rack's master takeover");
    let measured = (takeover.at - takeover.from).as_micros() as f64 / 1e6;
    assert!(
        (gap - measured).abs() < 2e-6,
        "longest SYNC gap {:.4} ms on the wire, the demo measured {:.4} ms",
        gap * 1e3,
        measured * 1e3
    );
    assert!(takeover.at - takeover.from <= takeover.bound.unwrap());
}
