//! `duocan gateway --socket` driven by CANopenNode's own 309-3 client, `cocomm`, as its users
//! script it: a script sent line by line over the local socket, every answer checked as cocomm
//! prints it (`-o flat`: all on standard output).
//!
//! cocomm is built from the CANopenNode sources kept beside the repository
//! (`../shared/peers/canopennode/build.sh`, a few seconds, once: into cargo's folder for test
//! files), or taken from `DUOCAN_COCOMM` (a path to a built `cocomm`). Without either this test fails and says why: it is never skipped.
//! canopend's own gateway needs a CAN interface, so the answers it gives are written here as
//! the expected ones (from CANopenNode's gateway source), with the deliberate differences named
//! (the gateway's module documentation lists them).

#[path = "common/cocomm.rs"]
mod cocomm;
mod common;
use cocomm::{check_answers, cocomm_socket, run_cocomm, script};
use duocan::net::{SIM_DEVICE_NAME, SIM_HEARTBEAT_MS, SIM_VENDOR};
use std::io::{BufRead, BufReader};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};

/// `duocan --bus sim-station gateway --socket PATH`, stopped (and its socket removed) on drop.
struct Gateway {
    child: Child,
    dir: PathBuf,
    socket: PathBuf,
}

impl Gateway {
    fn start(name: &str) -> Gateway {
        let dir = std::env::temp_dir().join(format!("duocan-gw-{}-{name}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let socket = dir.join("gw.sock");
        let mut child = Command::new(env!("CARGO_BIN_EXE_duocan"))
            .args([
                "--bus",
                "sim-station",
                "gateway",
                "--lss-settle-ms",
                "30",
                "--socket",
            ])
            .arg(&socket)
            .env_remove("DUOCAN_BUS")
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("run duocan");
        let mut err = BufReader::new(child.stderr.take().unwrap());
        let mut line = String::new();
        err.read_line(&mut line).unwrap();
        assert_eq!(
            line.trim(),
            format!("duocan gateway: listening on {}", socket.display())
        );
        Gateway { child, dir, socket }
    }

    /// Sends `script` through cocomm; returns its standard output and exit code.
    fn cocomm(&self, script: &str) -> (String, i32) {
        cocomm_socket(&self.socket, script)
    }
}

impl Drop for Gateway {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// Runs `cases` (request, the answer cocomm prints) as one cocomm script and checks the
/// answers ([`check_answers`]); cocomm's exit code.
fn check(gw: &Gateway, cases: &[(&str, String)]) -> i32 {
    let (out, code) = gw.cocomm(&script(cases));
    check_answers(&out, cases);
    code
}

#[test]
fn cocomm_scripts_run_against_the_gateway_as_against_canopennodes() {
    let _one = common::one_station();
    let gw = Gateway::start("script");
    let hb = SIM_HEARTBEAT_MS.to_le_bytes();
    let cases: Vec<(&str, String)> =
        vec![
        // A comment and a blank line: an empty line each (without it cocomm hangs).
        ("# a script with a comment", String::new()),
        ("", String::new()),
        ("[1] set node 5", "[1] OK".into()),
        ("[2] r 0x1018 1 u32", format!("[2] {SIM_VENDOR}")),
        ("[3] r 0x1008 0 vs", format!("[3] \"{SIM_DEVICE_NAME}\"")),
        // A request without its sequence number is refused (CANopenNode answers it with the
        // sequence number of the request before; duocan with 0).
        (
            "5 r 0x1018 1 u32",
            "[0] ERROR:101 #syntax error: a request starts with its sequence number: [<sequence>]"
                .into(),
        ),
        // A boolean written as a number, read back.
        ("[4] w 0x6200 2 b 1", "[4] OK".into()),
        ("[5] r 0x6200 2 b", "[5] 1".into()),
        // A type wider than the object: the bytes.
        ("[6] r 0x1017 0 u32", format!("[6] {:02X} {:02X}", hb[0], hb[1])),
        // A REAL32 as C's %g.
        ("[7] r 0x1018 1 r32", "[7] 1.91742e-38".into()),
        // Errors with their meaning behind `#` (the words are duocan's).
        (
            "[8] r 0x1234 0 u8",
            "[8] ERROR:0x06020000 #object does not exist in the object dictionary".into(),
        ),
        (
            "[9] r 0x1017 0 q7",
            "[9] ERROR:101 #syntax error: q7: not a data type (help datatype lists them)".into(),
        ),
        ("[10] set network 2", "[10] OK".into()),
        ("[11] 2 5 r 0x1018 2 u32", "[11] 5".into()),
    ];
    // cocomm exits 1 when any answer was an error, as here.
    assert_eq!(check(&gw, &cases), 1);
}

#[test]
fn help_pages_reach_cocomm_whole_and_in_step() {
    let _one = common::one_station();
    let gw = Gateway::start("help");
    for (page, has) in [
        ("", "r[ead] <index> <sub>"),
        (" datatype", "r32 r64"),
        (" lss", "lss_allnodes"),
    ] {
        let (out, code) = gw.cocomm(&format!("[1] help{page}\n[2] 5 r 0x1018 2 u32\n"));
        assert_eq!(code, 0, "{out}");
        // The page (comment lines parted by LF), its OK, then the next answer in step.
        let (help, rest) = out
            .split_once("[1] OK\r\n")
            .unwrap_or_else(|| panic!("{out}"));
        assert!(help.contains(has), "help{page}: {help}");
        assert!(help.lines().all(|l| l.starts_with("# ")), "{help}");
        assert_eq!(rest, "[2] 5\r\n");
    }
}

#[test]
fn lss_through_cocomm_finds_a_board_and_gives_it_a_node_id() {
    let _one = common::one_station();
    let gw = Gateway::start("lss");
    let board1 = format!("0x{SIM_VENDOR:08X} 0x00000305 0x00000001 0x00000001");
    let cases: Vec<(&str, String)> = vec![
        // The first board without a node-ID, left in configuration mode.
        ("[1] _lss_fastscan", format!("[1] {board1}")),
        ("[2] lss_inquire_addr", format!("[2] {board1}")),
        ("[3] lss_inquire_addr 3", "[3] 0x00000001".into()),
        ("[4] lss_get_node", "[4] 0xFF".into()),
        ("[5] lss_set_node 0x30", "[5] OK".into()),
        // The active node-ID: the new one is active once the board leaves configuration.
        ("[6] lss_get_node", "[6] 0xFF".into()),
        // The simulated boards have no storage.
        (
            "[7] lss_store",
            "[7] ERROR:504 #LSS: storing the configuration failed: LSS, store configuration: \
             the slave refused with code 1 (not supported, spec 0)"
                .into(),
        ),
        (
            "[8] lss_set_node 200",
            "[8] ERROR:101 #syntax error: 200: a node-ID is 1 to 127 (255: none)".into(),
        ),
        // Back to waiting: the board boots with its new node-ID and answers SDO.
        ("[9] lss_switch_glob 0", "[9] OK".into()),
        ("[10] set sdo_timeout 2000", "[10] OK".into()),
        ("[11] 0x30 r 0x1018 4 u32", "[11] 1".into()),
        // Not any more in configuration mode: nobody answers.
        (
            "[12] lss_get_node",
            "[12] ERROR:103 #time-out: LSS, inquire node-ID: no slave answered in time: a slave \
             serves it in configuration mode only (switch state global or selective first); \
             check that it is on this bus, or wait longer"
                .into(),
        ),
        // Every other board without a node-ID gets one: the second board, 0x40.
        (
            "[13] lss_allnodes 100 0x40 0",
            format!(
                "# node-ID 64 given to 0x{SIM_VENDOR:08X} 0x00000305 0x00000001 0x00000002\n\
                 # 1 given a node-ID; no slave is left without one\n[13] OK"
            ),
        ),
        ("[14] 0x40 r 0x1018 4 u32", "[14] 2".into()),
        (
            "[15] lss_allnodes",
            "# 0 given a node-ID; no slave is left without one\n[15] OK".into(),
        ),
        ("[16] lss_switch_glob 1", "[16] OK".into()),
        (
            "[17] lss_set_node 0",
            "[17] ERROR:102 #request not processed in the present state: LSS, node-ID 0 is \
             outside 1-127 (0xFF means none)"
                .into(),
        ),
        ("[18] lss_switch_glob 0", "[18] OK".into()),
    ];
    assert_eq!(check(&gw, &cases), 1);
}

#[test]
fn cocomm_over_tcp_with_requests_as_arguments() {
    let _one = common::one_station();
    let mut gw = Command::new(env!("CARGO_BIN_EXE_duocan"))
        .args(["--bus", "sim-station", "gateway", "--listen", "127.0.0.1:0"])
        .env_remove("DUOCAN_BUS")
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run duocan");
    let mut err = BufReader::new(gw.stderr.take().unwrap());
    let mut line = String::new();
    err.read_line(&mut line).unwrap();
    let port = line
        .trim()
        .strip_prefix("duocan gateway: listening on 127.0.0.1:")
        .unwrap_or_else(|| panic!("{line:?}"))
        .to_string();
    // cocomm numbers the requests given as arguments itself ([1], [2], …), but not a comment.
    let args: Vec<std::ffi::OsString> = [
        "-t",
        "127.0.0.1",
        "-p",
        &port,
        "-o",
        "flat",
        "5 r 0x1018 2 u32",
        "# a comment",
        "[7] 5 r 0x1017 0 x16",
        "help lss",
    ]
    .map(Into::into)
    .to_vec();
    let (out, err, code) = run_cocomm(&args, "");
    let _ = gw.kill();
    let _ = gw.wait();
    assert_eq!(code, 0, "{out}{err}");
    let (head, lss) = out
        .split_once("\r\n[7] ")
        .unwrap_or_else(|| panic!("{out}"));
    assert_eq!(head, "[1] 5\r\n", "the comment's empty line follows");
    let lss = lss
        .strip_prefix(&format!("0x{SIM_HEARTBEAT_MS:04X}\r\n"))
        .unwrap_or_else(|| panic!("{out}"));
    assert!(lss.starts_with("# LSS requests"), "{out}");
    assert!(lss.ends_with("\n[4] OK\r\n"), "{out}");
}
