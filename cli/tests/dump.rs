//! `duocan dump` of candump logs and pcaps written by duocan's writers, and `duocan record` on
//! the simulated bus read back.

mod common;
use common::{duocan, sim_ok};
use duocan::capture::candump::{read_log, CandumpWriter};
use duocan::capture::pcap::{PcapReader, PcapWriter};
use duocan::profile::railway::{self, DeviceAddress, RailFunction};
use duocan::{Frame, Id};
use std::path::PathBuf;

/// A file in the temporary directory, unique to this test process.
fn temp(name: &str) -> PathBuf {
    std::env::temp_dir().join(format!("duocan-cli-dump-{}-{name}", std::process::id()))
}

fn std_frame(id: u16, data: &[u8]) -> Frame {
    Frame::new(Id::Standard(id), data).unwrap()
}

/// The frames every dump test reads, and the line each gives.
fn known() -> Vec<(Frame, &'static str)> {
    let board = DeviceAddress::board_at(1, 2, 3, 4);
    vec![
        (std_frame(0x000, &[0x01, 0x05]), "NMT start node 5"),
        (std_frame(0x705, &[0x05]), "node 5 heartbeat operational"),
        (
            std_frame(0x605, &[0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0]),
            "node 5 SDO upload 0x1018:01 request",
        ),
        (
            std_frame(0x585, &[0x43, 0x18, 0x10, 0x01, 0x23, 0x01, 0, 0]),
            "node 5 SDO upload 0x1018:01 = 0x00000123",
        ),
        (
            std_frame(0x085, &[0x30, 0x81, 0x11, 0, 0, 0, 0, 0]),
            "node 5 EMCY 0x8130 life guard or heartbeat error, register 0x11, data 00 00 00 00 00",
        ),
        (
            std_frame(0x185, &[0x11, 0xFD, 0xFF]),
            "node 5 TPDO1 Input 1 = 17, Input 2 = -3",
        ),
        (
            Frame::new(railway::id(RailFunction::Heartbeat, board), &[0x7F]).unwrap(),
            "railway R1 C2 L3 B4 P0 heartbeat pre-operational",
        ),
        (
            std_frame(0x071, &[0x01, 0x02]),
            "flying master active-master response node 2 (priority 1)",
        ),
    ]
}

/// TPDO1 of node 5 maps "Input 1" (UNSIGNED8) and "Input 2" (INTEGER16): the decoder's own
/// test description.
const EDS: &str = include_str!("../../src/capture/decode/tests/io.eds");

const T0: u64 = 1_700_000_000_000_000;

fn eds_file() -> PathBuf {
    let p = temp("io.eds");
    std::fs::write(&p, EDS).unwrap();
    p
}

fn candump_file(name: &str) -> PathBuf {
    let mut w = CandumpWriter::new(Vec::new());
    for (i, (f, _)) in known().iter().enumerate() {
        w.write(T0 + i as u64 * 100, "can0", f).unwrap();
    }
    let p = temp(name);
    std::fs::write(&p, w.into_inner()).unwrap();
    p
}

fn pcap_file(name: &str) -> PathBuf {
    let mut w = PcapWriter::new(Vec::new()).unwrap();
    for (i, (f, _)) in known().iter().enumerate() {
        w.write(T0 + i as u64 * 100, f).unwrap();
    }
    let p = temp(name);
    std::fs::write(&p, w.into_inner()).unwrap();
    p
}

/// The lines `dump` prints for the known frames on `interface`.
fn expected(interface: &str) -> String {
    known()
        .iter()
        .enumerate()
        .map(|(i, (f, text))| {
            let id = match f.id() {
                Id::Standard(r) => format!("{r:03X}"),
                Id::Extended(r) => format!("{r:08X}"),
            };
            format!(
                "1700000000.{:06}  {interface:<5}  {id:<8}  {text}\n",
                i * 100
            )
        })
        .collect()
}

fn ok(args: &[&str]) -> String {
    let r = duocan(args);
    assert_eq!(r.code, 0, "duocan {args:?}: {}", r.err);
    r.out
}

#[test]
fn a_candump_log_and_a_pcap_decode_line_by_line() {
    let eds = eds_file();
    let eds_arg = format!("5={}", eds.display());
    let log = candump_file("known.log");
    let out = ok(&["--eds", &eds_arg, "dump", log.to_str().unwrap()]);
    assert_eq!(out, expected("can0"));
    // The same frames in a pcap named .log: the magic decides, not the extension.
    let pcap = pcap_file("known.log.pcap");
    let renamed = temp("pcap-named.log");
    std::fs::rename(&pcap, &renamed).unwrap();
    let out = ok(&["--eds", &eds_arg, "dump", renamed.to_str().unwrap()]);
    assert_eq!(out, expected("pcap"));
    // Without the description the PDO is raw bytes.
    let out = ok(&["dump", log.to_str().unwrap(), "--kind", "pdo"]);
    assert_eq!(
        out,
        "1700000000.000500  can0   185       node 5 TPDO1 11 FD FF\n"
    );
}

#[test]
fn filters_by_node_and_kind_and_count() {
    let log = candump_file("filters.log");
    let path = log.to_str().unwrap();
    let texts = |out: String| -> Vec<String> {
        out.lines()
            .map(|l| l.splitn(4, "  ").nth(3).unwrap().trim_start().to_string())
            .collect()
    };
    assert_eq!(
        texts(ok(&["dump", path, "--kind", "sdo,nmt"])),
        [
            "NMT start node 5",
            "node 5 SDO upload 0x1018:01 request",
            "node 5 SDO upload 0x1018:01 = 0x00000123"
        ]
    );
    // Node 2: the flying master's rank names it.
    assert_eq!(
        texts(ok(&["dump", path, "--node", "2"])),
        ["flying master active-master response node 2 (priority 1)"]
    );
    // A railway heartbeat is a heartbeat and a railway frame.
    assert_eq!(texts(ok(&["dump", path, "--kind", "heartbeat"])).len(), 2);
    assert_eq!(texts(ok(&["dump", path, "--kind", "railway"])).len(), 1);
    assert_eq!(ok(&["dump", path, "--count", "2"]).lines().count(), 2);
    let r = duocan(&["dump", path, "--kind", "sdo,pdo2"]);
    assert_eq!(r.code, 2);
    assert!(
        r.err.contains("kind \"pdo2\": give one of nmt"),
        "{}",
        r.err
    );
    let r = duocan(&["dump", path, "--node", "0"]);
    assert_eq!(r.code, 2);
}

#[test]
fn json_lines_carry_the_fields_of_each_kind() {
    let eds = eds_file();
    let log = candump_file("json.log");
    let out = ok(&[
        "--json",
        "--eds",
        &format!("5={}", eds.display()),
        "dump",
        log.to_str().unwrap(),
    ]);
    let v: Vec<serde_json::Value> = out
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(v.len(), known().len());
    for (line, (_, text)) in v.iter().zip(known()) {
        assert_eq!(line["text"], text);
        assert_eq!(line["interface"], "can0");
    }
    assert_eq!(v[0]["kind"], "nmt");
    assert_eq!(v[0]["target"], 5);
    assert_eq!(v[1]["state"], "operational");
    assert_eq!(v[3]["kind"], "sdo");
    assert_eq!(v[3]["index"], 0x1018);
    assert_eq!(v[3]["sub"], 1);
    assert_eq!(v[3]["value"], 0x123);
    assert_eq!(v[3]["side"], "server");
    assert_eq!(v[3]["time"], "1700000000.000300");
    assert_eq!(v[3]["data"], "4318100123010000");
    assert_eq!(v[4]["code"], 0x8130);
    assert_eq!(v[4]["code_text"], "life guard or heartbeat error");
    assert_eq!(v[5]["pdo"], "TPDO1");
    assert_eq!(v[5]["values"][1]["name"], "Input 2");
    assert_eq!(v[5]["values"][1]["value"], -3);
    assert_eq!(v[6]["kind"], "railway");
    assert_eq!(v[6]["extended"], true);
    assert_eq!(v[6]["address"], "R1 C2 L3 B4 P0");
    assert_eq!(v[7]["master"], 2);
}

/// A CANopen FD network's capture: a 64-byte TPDO in a CAN FD frame is decoded as a PDO (its
/// 64 bytes raw, and filtered by kind and node as any PDO), a USDO frame is not (said so,
/// without a filter only); JSON marks the PDO `fd`.
#[test]
fn a_64_byte_pdo_in_a_can_fd_frame_is_decoded() {
    let mut w = CandumpWriter::new(Vec::new());
    let pdo = duocan::FdFrame::new(Id::Standard(0x185), &[0x5A; 64])
        .unwrap()
        .with_brs(true);
    let usdo = duocan::FdFrame::new(Id::Standard(0x67F), &[0x01; 12]).unwrap();
    w.write_fd(T0, "can0", &pdo).unwrap();
    w.write_fd(T0 + 100, "can0", &usdo).unwrap();
    let p = temp("fd.log");
    std::fs::write(&p, w.into_inner()).unwrap();
    let path = p.to_str().unwrap();
    let out = ok(&["dump", path]);
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(lines.len(), 2, "{out}");
    let want = format!("node 5 TPDO1 {}", ["5A"; 64].join(" "));
    assert!(lines[0].ends_with(&want), "{out}");
    assert!(
        lines[1].ends_with("CAN FD frame of 12 bytes (not decoded)"),
        "{out}"
    );
    let out = ok(&["dump", path, "--kind", "pdo", "--node", "5"]);
    assert_eq!(out.lines().count(), 1, "{out}");
    assert_eq!(ok(&["dump", path, "--node", "6"]), "");
    let out = ok(&["--json", "dump", path, "--kind", "pdo"]);
    let v: serde_json::Value = serde_json::from_str(out.trim()).unwrap();
    assert_eq!(v["kind"], "pdo");
    assert_eq!(v["pdo"], "TPDO1");
    assert_eq!(
        (v["fd"].clone(), v["brs"].clone()),
        (true.into(), true.into())
    );
    assert_eq!(v["data"].as_str().unwrap().len(), 128);
}

#[test]
fn a_bad_file_exits_1_naming_file_and_place_after_the_lines_before() {
    let p = temp("bad.log");
    std::fs::write(&p, "(1.000000) can0 705#05\n(1.000001) can0 705#ZZ\n").unwrap();
    let r = duocan(&["dump", p.to_str().unwrap()]);
    assert_eq!(r.code, 1, "{}", r.err);
    assert_eq!(
        r.out,
        "1.000000  can0   705       node 5 heartbeat operational\n"
    );
    assert!(
        r.err.contains(&format!("{}, line 2: ", p.display())),
        "{}",
        r.err
    );
    // A pcap cut short: the byte offset of the record it cuts.
    let pcap = pcap_file("cut.pcap");
    let mut bytes = std::fs::read(&pcap).unwrap();
    bytes.truncate(bytes.len() - 3);
    std::fs::write(&pcap, &bytes).unwrap();
    let r = duocan(&["dump", pcap.to_str().unwrap()]);
    assert_eq!(r.code, 1);
    assert_eq!(r.out.lines().count(), known().len() - 1);
    assert!(
        r.err
            .contains(&format!("{}: pcap file truncated at byte", pcap.display())),
        "{}",
        r.err
    );
    let r = duocan(&["dump", temp("missing.log").to_str().unwrap()]);
    assert_eq!(
        r.code, 2,
        "a file that cannot be opened is the command line's"
    );
    let r = duocan(&["dump", pcap.to_str().unwrap(), "--duration", "1"]);
    assert_eq!(r.code, 2);
}

#[test]
fn record_on_the_simulated_bus_reads_back() {
    let log = temp("rec.log");
    let pcap = temp("rec.pcap");
    let out = sim_ok(&[
        "--json",
        "record",
        "--candump",
        log.to_str().unwrap(),
        "--pcap",
        pcap.to_str().unwrap(),
        "--count",
        "12",
    ]);
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["frames"], 12);
    assert_eq!(v["end"], "count reached");
    // The simulated station is two buses: each port's frames under its own name.
    assert_eq!(v["buses"][0]["interface"], "sim-bus1");
    assert_eq!(v["buses"][1]["interface"], "sim-bus2");
    let per_bus = |i: usize| v["buses"][i]["frames"].as_u64().unwrap();
    assert_eq!(per_bus(0) + per_bus(1), 12);
    let entries: Vec<_> = read_log(
        "rec.log",
        std::io::BufReader::new(std::fs::File::open(&log).unwrap()),
    )
    .map(Result::unwrap)
    .collect();
    assert_eq!(entries.len(), 12);
    for (bus, file) in [
        ("sim-bus1", pcap.clone()),
        ("sim-bus2", temp("rec-bus2.pcap")),
    ] {
        let logged: Vec<_> = entries.iter().filter(|e| e.interface == bus).collect();
        let packets: Vec<_> = PcapReader::new(std::fs::File::open(&file).unwrap())
            .unwrap()
            .map(Result::unwrap)
            .collect();
        assert_eq!(logged.len(), packets.len(), "{bus}");
        for (e, p) in logged.iter().zip(&packets) {
            assert_eq!((e.timestamp_us, &e.record), (p.timestamp_us, &p.record));
        }
    }
    assert!(per_bus(0) > 0 && per_bus(1) > 0, "{v}");
    // dump reads the log back: twelve lines, each bus's frames decoded on their own.
    let lines = ok(&["dump", log.to_str().unwrap()]);
    assert_eq!(lines.lines().count(), 12);
    assert!(lines.contains("boot-up"), "{lines}");
    assert!(!lines.contains("unknown"), "{lines}");
    // A duration instead of a count: a summary table for a person.
    let out = sim_ok(&[
        "record",
        "--candump",
        log.to_str().unwrap(),
        "--duration",
        "0.3",
    ]);
    assert!(
        out.starts_with("bus  interface  frames\n1    sim-bus1"),
        "{out}"
    );
    assert!(out.contains("(duration passed)"), "{out}");
    let r = duocan(&["--bus", "sim-station", "record", "--count", "3"]);
    assert_eq!(r.code, 2, "nowhere to write");
}

#[test]
fn live_dump_of_the_simulated_bus() {
    let out = sim_ok(&["dump", "--count", "4", "--kind", "heartbeat"]);
    assert_eq!(out.lines().count(), 4, "{out}");
    for l in out.lines() {
        let bus = l.split_whitespace().nth(1).unwrap();
        assert!(bus == "sim-bus1" || bus == "sim-bus2", "{l}");
        assert!(l.contains(" boot-up") || l.contains(" heartbeat "), "{l}");
    }
    let out = sim_ok(&["--json", "dump", "--duration", "0.5", "--node", "5"]);
    let v: Vec<serde_json::Value> = out
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert!(!v.is_empty());
    assert!(v.iter().all(|l| l["node"] == 5), "{out}");
}
