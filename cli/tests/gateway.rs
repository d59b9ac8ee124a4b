//! `duocan gateway`: CiA 309-3 requests on standard input and over TCP, against the simulated
//! nodes of `--bus sim-station`.

#[path = "common/base64.rs"]
mod base64;
mod common;
use base64::b64;
use common::duocan;
use duocan::net::{SIM_DEVICE_NAME, SIM_HEARTBEAT_MS, SIM_VENDOR};
use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::process::{Child, Command, Stdio};
use std::time::Duration;

/// Runs `duocan --bus sim-station gateway` with `script` on standard input; returns exit code,
/// standard output and standard error.
fn gateway(script: &str) -> (i32, String, String) {
    let r = common::duocan_with_input(&["--bus", "sim-station", "gateway"], script);
    (r.code, r.out, r.err)
}

#[test]
fn a_script_on_standard_input_gets_one_exact_answer_per_request() {
    let version = env!("CARGO_PKG_VERSION");
    let mm: Vec<&str> = version.split('.').take(2).collect();
    let mm = mm.join(".");
    let name_b64 = b64(SIM_DEVICE_NAME.as_bytes());
    let hb = SIM_HEARTBEAT_MS.to_le_bytes();
    let no_seq =
        "[0] ERROR:101 #syntax error: a request starts with its sequence number: [<sequence>]";
    let cases: Vec<(&str, String)> = vec![
        // A comment or a blank line is answered with an empty line, as CANopenNode's gateway
        // answers it (cocomm waits for an answer to every line it sends).
        ("# a CiA 309-3 session", String::new()),
        ("", String::new()),
        (
            "[1] r 0x1018 1 u32",
            "[1] ERROR:105 #no default node set".into(),
        ),
        ("[2] 5 read 0x1018 1 u32", format!("[2] {SIM_VENDOR}")),
        ("[3] 5 r 0x1018 1 x32", format!("[3] 0x{SIM_VENDOR:08X}")),
        ("[4] 1 7 r 0x1018 2 u32", "[4] 7".into()),
        ("[5] set node 5", "[5] OK".into()),
        ("[6] r 0x1018 2 u32", "[6] 5".into()),
        ("[7] r 0x1008 0 vs", format!("[7] \"{SIM_DEVICE_NAME}\"")),
        ("[8] r 0x1008 0 d", format!("[8] {name_b64}")),
        ("[9] r 0x1017 0 u16", format!("[9] {SIM_HEARTBEAT_MS}")),
        ("[10] w 0x1017 0 u16 250", "[10] OK".into()),
        ("[11] r 0x1017 0", "[11] FA 00".into()),
        (
            "[12] W 0x6200 2 I8 -5 # upper case, a comment",
            "[12] OK".into(),
        ),
        ("[13] r 0x6200 2 i8", "[13] -5".into()),
        ("[14] w 0x6200 1 x16 0xbeef", "[14] OK".into()),
        ("[15] r 0x6200 1 x16", "[15] 0xBEEF".into()),
        ("[16] set sdo_block 1", "[16] OK".into()),
        ("[17] r 0x1008 0 vs", format!("[17] \"{SIM_DEVICE_NAME}\"")),
        ("[18] set sdo_block 0", "[18] OK".into()),
        // No sequence number: refused, as CANopenNode refuses it.
        ("r 0x1018 1 u32", no_seq.into()),
        ("[19] info version", format!("[19] 0 0 {mm} 0 1 3.0 {mm}")),
        // The node's answers, each with its meaning behind `#`.
        (
            "[20] r 0x1234 0 u8",
            "[20] ERROR:0x06020000 #object does not exist in the object dictionary".into(),
        ),
        (
            "[21] w 0x1018 1 u32 1",
            "[21] ERROR:0x06010002 #attempt to write a read only object".into(),
        ),
        // A type wider than the object: the bytes the node sent.
        ("[22] r 0x1017 0 u32", "[22] FA 00".into()),
        ("[23] set sdo_timeout 200", "[23] OK".into()),
        (
            "[24] 99 r 0x1000 0 u32",
            "[24] ERROR:0x05040000 #SDO protocol timed out".into(),
        ),
        // The gateway's own.
        (
            "[25] 5 enable guarding 100 3",
            "[25] ERROR:100 #request not supported: node guarding: not carried out by this gateway"
                .into(),
        ),
        (
            "[26] frobnicate",
            "[26] ERROR:100 #request not supported: frobnicate: not a request (help lists them)"
                .into(),
        ),
        (
            "[27] r 0x1017 0 q7",
            "[27] ERROR:101 #syntax error: q7: not a data type (help datatype lists them)".into(),
        ),
        (
            "[28] w 0x1017 0 u8 256",
            "[28] ERROR:101 #syntax error: 256: not a u8 (0 to 255)".into(),
        ),
        (
            "[x] start",
            "[0] ERROR:101 #syntax error: [x]: a sequence number is 0 to 4294967295".into(),
        ),
        // Any net names the one network served.
        ("[29] 2 5 r 0x1018 2 u32", "[29] 5".into()),
        ("[30] set network 2", "[30] OK".into()),
        (
            "[31] 200 start",
            "[31] ERROR:107 #unsupported node: a node is 0 to 127".into(),
        ),
        (
            "[32] 0 r 0x1000 0 u32",
            "[32] ERROR:107 #unsupported node: node 0 (all nodes) has no SDO server".into(),
        ),
        // NMT, seen in what the node does next: stopped, it has no SDO server.
        ("[33] stop", "[33] OK".into()),
        (
            "[34] r 0x1018 1 u32",
            "[34] ERROR:0x05040000 #SDO protocol timed out".into(),
        ),
        ("[35] 5 preoperational", "[35] OK".into()),
        ("[36] r 0x1018 1 u32", format!("[36] {SIM_VENDOR}")),
        ("[37] start", "[37] OK".into()),
        ("[38] 0 preop", "[38] OK".into()),
        // A communication reset puts the communication parameters back, not the application's
        // values; a node reset puts both back.
        ("[39] reset comm", "[39] OK".into()),
        ("[40] r 0x1017 0 u16", format!("[40] {SIM_HEARTBEAT_MS}")),
        (
            "[41] r 0x1017 0 u32",
            format!("[41] {:02X} {:02X}", hb[0], hb[1]),
        ),
        ("[42] r 0x6200 2 i8", "[42] -5".into()),
        // A boolean in any number form, and its byte read back.
        ("[43] w 0x6200 2 b 0x1", "[43] OK".into()),
        ("[44] r 0x6200 2 b", "[44] 1".into()),
        // A REAL32 read as C's %g prints it.
        ("[45] r 0x1018 1 r32", "[45] 1.91742e-38".into()),
        ("[46] reset node", "[46] OK".into()),
        ("[47] r 0x6200 2 i8", "[47] 0".into()),
    ];
    let script: String = cases.iter().map(|(l, _)| format!("{l}\n")).collect();
    let (code, out, err) = gateway(&script);
    assert_eq!(code, 0, "{err}");
    let expected: Vec<&str> = cases.iter().map(|(_, a)| a.as_str()).collect();
    let got: Vec<&str> = out.lines().collect();
    for (i, (g, e)) in got.iter().zip(&expected).enumerate() {
        assert_eq!(g, e, "response {i}\nall of it:\n{out}");
    }
    assert_eq!(got.len(), expected.len(), "{out}");
}

#[test]
fn help_is_comment_lines_then_ok_and_cr_lf_input_is_taken() {
    let (code, out, err) = gateway("[1] help\r\n[2] 5 r 0x1018 2 u32\r\n[3] 5 r 0x1018 2 u32");
    assert_eq!(code, 0, "{err}");
    let lines: Vec<&str> = out.lines().collect();
    let (help, last3) = lines.split_at(lines.len() - 3);
    assert!(help.len() > 5, "{out}");
    assert!(help.iter().all(|l| l.starts_with("# ")), "{out}");
    assert!(out.contains("r[ead] <index> <sub>"), "{out}");
    // The last request has no line end: it is answered all the same.
    assert_eq!(last3, ["[1] OK", "[2] 5", "[3] 5"]);
    // The data types' page and the LSS page.
    let (code, out, err) = gateway("[1] help datatype\n[2] help lss\n");
    assert_eq!(code, 0, "{err}");
    let lines: Vec<&str> = out.lines().collect();
    let ends: Vec<usize> = (0..lines.len())
        .filter(|i| lines[*i].starts_with('['))
        .collect();
    assert_eq!(ends.len(), 2, "{out}");
    assert_eq!(lines[ends[0]], "[1] OK");
    assert_eq!(lines[ends[1]], "[2] OK");
    let (types, lss) = (
        lines[..ends[0]].join("\n"),
        lines[ends[0] + 1..ends[1]].join("\n"),
    );
    assert!(
        types.contains("r32 r64") && types.contains("hex"),
        "{types}"
    );
    assert!(
        lss.contains("lss_switch_glob") && lss.contains("lss_allnodes"),
        "{lss}"
    );
    assert!(lines
        .iter()
        .all(|l| l.starts_with("# ") || l.starts_with('[')));
}

/// A `duocan --bus sim-station gateway --listen 127.0.0.1:0` and the port it serves on.
struct Served {
    child: Child,
    port: u16,
}

impl Served {
    fn start() -> Served {
        let mut child = Command::new(env!("CARGO_BIN_EXE_duocan"))
            .args(["--bus", "sim-station", "gateway", "--listen", "127.0.0.1:0"])
            .env_remove("DUOCAN_BUS")
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("run duocan");
        let mut err = BufReader::new(child.stderr.take().expect("stderr piped"));
        let mut line = String::new();
        err.read_line(&mut line)
            .expect("the gateway says where it listens");
        let port = line
            .trim()
            .strip_prefix("duocan gateway: listening on 127.0.0.1:")
            .and_then(|p| p.parse().ok())
            .unwrap_or_else(|| panic!("not the bound address: {line:?}"));
        Served { child, port }
    }

    fn connect(&self) -> Client {
        let s = TcpStream::connect(("127.0.0.1", self.port)).expect("connect");
        s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
        Client {
            r: BufReader::new(s.try_clone().unwrap()),
            w: s,
        }
    }
}

impl Drop for Served {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

struct Client {
    r: BufReader<TcpStream>,
    w: TcpStream,
}

impl Client {
    /// Sends one request; returns the response line, checking it ends in CR LF.
    fn ask(&mut self, line: &str) -> String {
        self.w.write_all(format!("{line}\r\n").as_bytes()).unwrap();
        let mut resp = String::new();
        self.r.read_line(&mut resp).expect("a response");
        assert!(resp.ends_with("\r\n"), "{resp:?}");
        resp.trim_end().to_string()
    }
}

#[test]
fn tcp_clients_are_served_at_once_each_with_its_own_defaults() {
    let served = Served::start();
    let mut a = served.connect();
    let mut b = served.connect();
    assert_eq!(a.ask("[1] set node 6"), "[1] OK");
    assert_eq!(b.ask("[1] set node 7"), "[1] OK");
    assert_eq!(a.ask("[2] r 0x1018 2 u32"), "[2] 6");
    assert_eq!(b.ask("[2] r 0x1018 2 u32"), "[2] 7");
    assert_eq!(b.ask("[3] set sdo_timeout 3000"), "[3] OK");
    // Both at once, from two threads: a node that does not answer keeps B waiting, not A.
    let tb = std::thread::spawn(move || {
        let r = b.ask("[4] 99 r 0x1000 0 u32");
        (b, r)
    });
    std::thread::sleep(Duration::from_millis(100));
    for i in 10..20 {
        assert_eq!(
            a.ask(&format!("[{i}] r 0x1018 1 x32")),
            format!("[{i}] 0x{SIM_VENDOR:08X}")
        );
    }
    assert!(!tb.is_finished(), "A was answered while B still waits");
    let (mut b, r) = tb.join().unwrap();
    assert_eq!(r, "[4] ERROR:0x05040000 #SDO protocol timed out");
    // A new client starts with no default node, whatever the others set.
    let mut c = served.connect();
    assert_eq!(
        c.ask("[1] r 0x1018 2 u32"),
        "[1] ERROR:105 #no default node set"
    );
    assert_eq!(c.ask("[2] 6 w 0x1017 0 u16 321"), "[2] OK");
    assert_eq!(b.ask("[5] 6 r 0x1017 0 u16"), "[5] 321");
    // A client that leaves does not stop the others.
    drop(c);
    assert_eq!(a.ask("[30] 5 start"), "[30] OK");
    assert_eq!(
        a.ask("[31] info"),
        "[31] ERROR:101 #syntax error: info version"
    );
}

const TOO_MANY: &str =
    "[0] ERROR:102 #request not processed in the present state: too many clients\r\n";

#[test]
fn a_client_past_the_limit_is_told_and_closed() {
    let served = Served::start();
    let mut clients: Vec<Client> = (0..16).map(|_| served.connect()).collect();
    for (i, c) in clients.iter_mut().enumerate() {
        assert_eq!(c.ask(&format!("[{i}] set node 1")), format!("[{i}] OK"));
    }
    let mut extra = served.connect();
    let mut all = String::new();
    extra.r.read_to_string(&mut all).unwrap();
    assert_eq!(all, TOO_MANY);
    // One leaves: its place is free again (once the gateway has seen it go).
    drop(clients.pop());
    let deadline = std::time::Instant::now() + Duration::from_secs(5);
    loop {
        let mut c = served.connect();
        c.w.write_all(b"[1] 5 r 0x1018 2 u32\r\n").unwrap();
        let mut resp = String::new();
        c.r.read_line(&mut resp).unwrap();
        if resp == "[1] 5\r\n" {
            break;
        }
        assert_eq!(resp, TOO_MANY);
        assert!(
            std::time::Instant::now() < deadline,
            "the slot was not freed"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

#[test]
fn a_tcp_line_that_is_not_text_or_too_long_is_a_syntax_error() {
    let served = Served::start();
    let mut a = served.connect();
    a.w.write_all(b"[1] 5 r \xff\xfe 0 u8\r\n").unwrap();
    let mut resp = String::new();
    a.r.read_line(&mut resp).unwrap();
    assert_eq!(
        resp,
        "[0] ERROR:101 #syntax error: the line is not UTF-8 text\r\n"
    );
    let long = vec![b'1'; 200 * 1024];
    a.w.write_all(&long).unwrap();
    assert_eq!(
        a.ask(""),
        "[0] ERROR:101 #syntax error: a line longer than 131072 bytes"
    );
    assert_eq!(a.ask("[2] 5 r 0x1018 2 u8"), "[2] 05 00 00 00");
    // A comment gets its empty line.
    assert_eq!(a.ask("# nothing"), "");
    // The connection is still fine; closing it ends its session only.
    a.w.shutdown(std::net::Shutdown::Write).unwrap();
    let mut rest = String::new();
    a.r.read_to_string(&mut rest).unwrap();
    assert_eq!(rest, "");
}

#[test]
fn listen_refuses_other_than_loopback_unless_told() {
    let r = duocan(&["--bus", "sim-station", "gateway", "--listen", "0.0.0.0:0"]);
    assert_eq!(r.code, 2, "{}", r.out);
    assert!(r.err.contains("not a loopback address"), "{}", r.err);
    assert!(r.err.contains("--allow-remote"), "{}", r.err);
    let r = duocan(&["--bus", "sim-station", "gateway", "--allow-remote"]);
    assert_eq!(r.code, 2);
    assert!(r.err.contains("--listen"), "{}", r.err);
    let r = duocan(&["--bus", "sim-station", "gateway", "--listen", "localhost"]);
    assert_eq!(r.code, 2);
    assert!(!r.err.contains("panicked"), "{}", r.err);
    let r = duocan(&["--bus", "sim-station", "--json", "gateway"]);
    assert_eq!(r.code, 2);
    assert!(r.err.contains("--json does not apply"), "{}", r.err);
    // No bus: a usage error before anything is read.
    let r = duocan(&["gateway"]);
    assert_eq!(r.code, 2);
    assert!(r.err.contains("no bus"), "{}", r.err);
}

#[test]
fn a_local_socket_is_served_owner_only_and_a_stale_one_replaced() {
    use std::os::unix::fs::PermissionsExt;
    use std::os::unix::net::UnixStream;
    let dir = std::env::temp_dir().join(format!("duocan-gw-sock-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("gw.sock");
    // A file that is not a socket is left alone.
    std::fs::write(&path, "keep").unwrap();
    let r = duocan(&[
        "--bus",
        "sim-station",
        "gateway",
        "--socket",
        path.to_str().unwrap(),
    ]);
    assert_eq!(r.code, 2, "{}", r.err);
    assert!(r.err.contains("not a socket"), "{}", r.err);
    assert_eq!(std::fs::read_to_string(&path).unwrap(), "keep");
    std::fs::remove_file(&path).unwrap();
    for round in 0..2 {
        // The second round finds the socket file the killed first one left behind.
        let mut child = Command::new(env!("CARGO_BIN_EXE_duocan"))
            .args(["--bus", "sim-station", "gateway", "--socket"])
            .arg(&path)
            .env_remove("DUOCAN_BUS")
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("run duocan");
        let mut err = BufReader::new(child.stderr.take().unwrap());
        let mut line = String::new();
        err.read_line(&mut line).unwrap();
        assert!(line.contains("listening on"), "round {round}: {line}");
        let mode = std::fs::metadata(&path).unwrap().permissions().mode();
        assert_eq!(mode & 0o777, 0o600);
        let s = UnixStream::connect(&path).unwrap();
        s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
        let mut r = BufReader::new(s.try_clone().unwrap());
        (&s).write_all(b"[1] 5 r 0x1018 2 u32\n\n").unwrap();
        let mut resp = String::new();
        r.read_line(&mut resp).unwrap();
        assert_eq!(resp, "[1] 5\r\n");
        resp.clear();
        r.read_line(&mut resp).unwrap();
        assert_eq!(resp, "\r\n", "a blank line gets an empty line");
        let _ = child.kill();
        let _ = child.wait();
    }
    let _ = std::fs::remove_dir_all(&dir);
}
