//! The station's CiA 309-3 gateway (`duocan station run` with `gateway` and `gateway_socket`):
//! on a loopback TCP port and on a local socket, both serving both networks of the station by
//! their net numbers; an unknown net is `ERROR:106`; an over-long line is answered and the
//! connection goes on; the client limit holds for both listeners together; the socket file is
//! its owner's, replaces a stale one and is gone after SIGTERM; `/metrics` counts the clients
//! refused and served. Every read has a deadline.

mod common;
#[path = "station_http/log.rs"]
mod log;
#[path = "station_mqtt/station.rs"]
#[allow(dead_code)]
mod station;
use common::duocan;
use log::{next_before, stderr_lines};
use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::os::unix::net::UnixStream;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Two simulated networks told apart by their boards: east (net 1, by its place in the file)
/// has node 0x10, west (net 7, by its `gateway_net`) node 0x11. The simulated boards answer
/// 0x1018:1 (vendor-ID) 0x00D0CA00 and 0x1018:2 (product code) with their node-ID.
const NETWORKS: &str = r#"
[[network]]
name = "east"
buses = "sim-pairs:quiet"
node_id = 1
heartbeat_ms = 50
master_timeout_ms = 200
pairs = [[0x10, 0x50]]
pair_heartbeat_ms = 50
pair_timeout_ms = 200

[[network]]
name = "west"
buses = "sim-pairs:quiet"
node_id = 3
heartbeat_ms = 50
master_timeout_ms = 200
pairs = [[0x11, 0x51]]
pair_heartbeat_ms = 50
pair_timeout_ms = 200
gateway_net = 7
"#;

/// The station under test, killed if the test fails before it stops it (no station left
/// running behind a failed test).
struct Killed(std::process::Child);

impl Drop for Killed {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// A fresh folder for one test's files.
fn temp_dir(what: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("duocan-gw-{what}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// One client's connection: a line out, a line back, each within a deadline.
struct Client<S: Read + Write> {
    r: BufReader<S>,
    w: S,
}

impl Client<TcpStream> {
    fn tcp(addr: &str) -> Self {
        let s = TcpStream::connect(addr).expect("connect");
        s.set_read_timeout(Some(Duration::from_secs(20))).unwrap();
        s.set_write_timeout(Some(Duration::from_secs(20))).unwrap();
        Client {
            r: BufReader::new(s.try_clone().unwrap()),
            w: s,
        }
    }
}

impl Client<UnixStream> {
    fn unix(path: &Path) -> Self {
        let s = UnixStream::connect(path).expect("connect");
        s.set_read_timeout(Some(Duration::from_secs(20))).unwrap();
        s.set_write_timeout(Some(Duration::from_secs(20))).unwrap();
        Client {
            r: BufReader::new(s.try_clone().unwrap()),
            w: s,
        }
    }
}

impl<S: Read + Write> Client<S> {
    /// Sends `line` and reads the answer (without its CR LF).
    fn ask(&mut self, line: &str) -> String {
        self.w.write_all(format!("{line}\r\n").as_bytes()).unwrap();
        self.answer()
    }

    fn answer(&mut self) -> String {
        let mut got = String::new();
        self.r.read_line(&mut got).expect("an answer in time");
        assert!(got.ends_with("\r\n"), "not a whole answer: {got:?}");
        got.trim_end().to_string()
    }

    /// Everything the gateway sends until it closes the connection.
    fn rest(&mut self) -> String {
        let mut all = String::new();
        self.r.read_to_string(&mut all).expect("closed in time");
        all
    }
}

/// The requests each listener must answer alike: both networks by net number, the default
/// net per connection, the errors, and a line too long.
fn exercise<S: Read + Write>(c: &mut Client<S>, via: &str) {
    // A client starts on the first network of the file (net 1: east).
    assert_eq!(c.ask("[1] 16 r 0x1018 1 u32"), "[1] 13683200", "{via}");
    assert_eq!(c.ask("[2] 1 16 r 0x1018 2 u32"), "[2] 16", "{via}");
    // West, by its gateway_net.
    assert_eq!(c.ask("[3] 7 17 r 0x1018 2 u32"), "[3] 17", "{via}");
    assert_eq!(
        c.ask("[4] 7 0x11 r 0x1000 0"),
        c.ask("[5] 1 0x10 r 0x1000 0").replace("[5]", "[4]"),
        "{via}"
    );
    // Node 0x11 is not on east: its SDO times out there (the request went to net 1).
    assert_eq!(c.ask("[6] set sdo_timeout 300"), "[6] OK", "{via}");
    let r = c.ask("[7] 1 17 r 0x1018 2 u32");
    assert!(r.starts_with("[7] ERROR:0x05040000"), "{via}: {r}");
    // Back to a time-out no busy machine runs out of.
    assert_eq!(c.ask("[7] set sdo_timeout 10000"), "[7] OK", "{via}");
    // Nets the station does not have.
    let r = c.ask("[8] 2 16 r 0x1018 2 u32");
    assert!(
        r.starts_with("[8] ERROR:106 #unsupported net"),
        "{via}: {r}"
    );
    assert!(r.contains("1 (east), 7 (west)"), "{via}: {r}");
    let r = c.ask("[9] set network 3");
    assert!(r.starts_with("[9] ERROR:106"), "{via}: {r}");
    let r = c.ask("[10] 5 0 start");
    assert!(r.starts_with("[10] ERROR:106"), "{via}: {r}");
    // The default net, for this connection.
    assert_eq!(c.ask("[11] set network 7"), "[11] OK", "{via}");
    assert_eq!(c.ask("[12] 17 r 0x1018 2 u32"), "[12] 17", "{via}");
    assert_eq!(c.ask("[13] set node 17"), "[13] OK", "{via}");
    assert_eq!(c.ask("[14] r 0x1018 2 u32"), "[14] 17", "{via}");
    // A line too long: an error, and the connection answers on.
    let mut long = vec![b'x'; 200 * 1024];
    long.extend_from_slice(b"\r\n");
    c.w.write_all(&long).unwrap();
    let r = c.answer();
    assert!(
        r.starts_with("[0] ERROR:101 #syntax error: a line longer than"),
        "{via}: {r}"
    );
    assert_eq!(c.ask("[15] 1 16 r 0x1018 2 u32"), "[15] 16", "{via}");
    // Not text, and not a request: answered, nothing more.
    c.w.write_all(b"\xff\xfe\r\n").unwrap();
    assert!(c.answer().starts_with("[0] ERROR:101"), "{via}");
    assert!(c.ask("[16] 7 w").starts_with("[16] ERROR:101"), "{via}");
}

/// Connects with `connect` until a client is served (the gateway frees a refused slot as
/// soon as it sees a client go), within 10 s.
fn served_again<S: Read + Write>(connect: impl Fn() -> Client<S>) -> Client<S> {
    let end = Instant::now() + Duration::from_secs(10);
    loop {
        let mut c = connect();
        c.w.write_all(b"[1] 1 16 r 0x1018 2 u32\r\n").unwrap();
        let mut got = String::new();
        let _ = c.r.read_line(&mut got);
        if got == "[1] 16\r\n" {
            return c;
        }
        assert!(got.contains("too many clients"), "{got:?}");
        assert!(Instant::now() < end, "no client served again in 10 s");
        std::thread::sleep(Duration::from_millis(100));
    }
}

#[test]
fn the_station_serves_309_3_on_tcp_and_a_local_socket_for_both_networks() {
    let _one = common::one_station();
    let dir = temp_dir("serve");
    let sock = dir.join("gw.sock");
    // A stale socket file, as a station killed with SIGKILL leaves: replaced.
    drop(std::os::unix::net::UnixListener::bind(&sock).unwrap());
    assert!(sock.exists());
    let station = dir.join("gw.toml");
    std::fs::write(
        &station,
        format!(
            "[station]\ngateway = \"127.0.0.1:0\"\ngateway_socket = \"gw.sock\"\n\
             gateway_max_clients = 3\nhttp = \"127.0.0.1:0\"\n{NETWORKS}"
        ),
    )
    .unwrap();
    let check = duocan(&["station", "check", station.to_str().unwrap()]);
    assert_eq!(check.code, 0, "{}", check.err);
    assert!(
        check
            .out
            .contains("309-3 gateway: tcp 127.0.0.1:0, socket ")
            && check
                .out
                .contains("(mode 0o600), at most 3 clients, nets: 1 east, 7 west"),
        "{}",
        check.out
    );

    // Each client's SDO time-out starts at --timeout: generous, for a busy machine.
    let mut child = Killed(
        common::station_run(&station)
            .args(["--timeout", "10000"])
            .spawn()
            .expect("run duocan"),
    );
    let rx = stderr_lines(&mut child.0);
    let end = Instant::now() + Duration::from_secs(120);
    let (mut addr, mut on_socket, mut active) = (None, false, 0);
    let mut http = None;
    let mut seen = vec![];
    while let Some(line) = next_before(&rx, end) {
        seen.push(line.clone());
        if let Some(a) = line.split("http listening on ").nth(1) {
            http = Some(a.trim().to_string());
        }
        if let Some(a) = line.split("309-3 gateway listening on 127.0.0.1:").nth(1) {
            addr = Some(format!("127.0.0.1:{}", a.trim()));
        }
        on_socket |= line.contains("309-3 gateway listening on ") && line.contains("gw.sock");
        if line.contains(": A active") {
            active += 1;
        }
        if addr.is_some() && http.is_some() && on_socket && active == 2 {
            break;
        }
    }
    let (Some(addr), Some(http)) = (addr.filter(|_| on_socket && active == 2), http) else {
        let _ = child.0.kill();
        panic!(
            "no gateway or no pair active in 120 s:\n{}",
            seen.join("\n")
        );
    };
    // The socket file: its owner's only.
    use std::os::unix::fs::PermissionsExt;
    let mode = std::fs::metadata(&sock).unwrap().permissions().mode();
    assert_eq!(mode & 0o777, 0o600, "{mode:o}");

    let mut tcp = Client::tcp(&addr);
    exercise(&mut tcp, "tcp");
    let mut local = Client::unix(&sock);
    exercise(&mut local, "unix");

    // The limit (3) is for both listeners together: a third client is served, a fourth on
    // either is told and closed; one leaves, and a client is served again.
    let mut third = Client::tcp(&addr);
    assert_eq!(third.ask("[1] 7 17 r 0x1018 2 u32"), "[1] 17");
    let too_many =
        "[0] ERROR:102 #request not processed in the present state: too many clients\r\n";
    assert_eq!(Client::tcp(&addr).rest(), too_many);
    assert_eq!(Client::unix(&sock).rest(), too_many);
    // Counted in the metrics, with the three served.
    let m = station::metrics(&http);
    let refused = m["duocan_gateway_refused_total{reason=\"too_many_clients\"}"];
    assert!(refused >= 2, "{m:?}");
    assert_eq!(m["duocan_gateway_clients"], 3, "{m:?}");
    assert_eq!(m["duocan_gateway_max_clients"], 3, "{m:?}");
    // The served ones go on.
    assert_eq!(tcp.ask("[20] 1 16 r 0x1018 2 u32"), "[20] 16");
    drop(third);
    let mut again = served_again(|| Client::unix(&sock));
    assert_eq!(again.ask("[2] 7 17 r 0x1018 2 u32"), "[2] 17");

    let pid = child.0.id().to_string();
    let killed = std::process::Command::new("kill")
        .args(["-TERM", &pid])
        .status()
        .expect("kill");
    assert!(killed.success());
    let end = Instant::now() + Duration::from_secs(30);
    let mut lines = seen;
    while let Some(line) = next_before(&rx, end) {
        lines.push(line);
    }
    let status = loop {
        if let Some(s) = child.0.try_wait().unwrap() {
            break s;
        }
        if Instant::now() > end {
            let _ = child.0.kill();
            panic!("not stopped 30 s after SIGTERM:\n{}", lines.join("\n"));
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    assert!(status.success(), "{status:?}:\n{}", lines.join("\n"));
    let all = lines.join("\n");
    assert!(all.contains("309-3 gateway closed"), "{all}");
    // Two refused, and any of the retries that came before the gateway saw a client go.
    let refused = all.matches("a client refused: too many clients").count();
    assert!(refused >= 2, "{all}");
    // The clients were disconnected, the socket file removed, the port closed.
    assert_eq!(tcp.rest(), "");
    assert_eq!(again.rest(), "");
    assert!(!sock.exists(), "the socket file is left behind");
    assert!(
        TcpStream::connect(&addr).is_err(),
        "the port still takes clients"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// `station check` refuses a gateway an operator did not mean: another machine's address
/// without the opt-in, an address that is not one; each error names file, line and key.
#[test]
fn a_gateway_open_to_other_machines_needs_its_key() {
    let dir = temp_dir("check");
    let station = dir.join("gw.toml");
    let name = station.to_str().unwrap();
    let check = |head: &str| {
        std::fs::write(&station, format!("[station]\n{head}\n{NETWORKS}")).unwrap();
        duocan(&["station", "check", name])
    };
    let r = check("gateway = \"0.0.0.0:5555\"");
    assert_eq!(r.code, 2, "{}", r.err);
    assert!(
        r.err.starts_with(&format!(
            "duocan: {name}:2:11: gateway: 0.0.0.0:5555 is reachable"
        )),
        "{}",
        r.err
    );
    assert!(r.err.contains("gateway_allow_remote = true"), "{}", r.err);
    assert!(r.err.contains("no authentication"), "{}", r.err);
    let r = check("gateway = \"0.0.0.0:5555\"\ngateway_allow_remote = true");
    assert_eq!(r.code, 0, "{}", r.err);
    assert!(
        r.out.contains("309-3 gateway: tcp 0.0.0.0:5555,"),
        "{}",
        r.out
    );
    let r = check("gateway = \"localhost\"");
    assert_eq!(r.code, 2, "{}", r.err);
    assert!(
        r.err.starts_with(&format!(
            "duocan: {name}:2:11: gateway: \"localhost\" is not an address and port"
        )),
        "{}",
        r.err
    );
    let r = check("gateway_socket = \"gw.sock\"\ngateway_socket_mode = 0o666");
    assert_eq!(r.code, 2, "{}", r.err);
    assert!(
        r.err.starts_with(&format!(
            "duocan: {name}:3:23: gateway_socket_mode: 0o666 is not allowed"
        )),
        "{}",
        r.err
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A path the gateway cannot take stops the start before any network opens, naming the key;
/// a file there that is not a socket is left as it was.
#[test]
fn a_station_whose_socket_path_is_taken_does_not_start() {
    let dir = temp_dir("taken");
    let sock = dir.join("gw.sock");
    std::fs::write(&sock, "not a socket").unwrap();
    let station = dir.join("gw.toml");
    std::fs::write(
        &station,
        format!("[station]\ngateway_socket = \"gw.sock\"\n{NETWORKS}"),
    )
    .unwrap();
    let mut run = common::station_run(&station);
    let out = run
        .args(["--duration-ms", "20000"])
        .output()
        .expect("run duocan");
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("gateway_socket: cannot listen on ") && err.contains("not a socket"),
        "{err}"
    );
    assert!(!err.contains("started network"), "{err}");
    assert_eq!(std::fs::read_to_string(&sock).unwrap(), "not a socket");
    let _ = std::fs::remove_dir_all(&dir);
}
