//! duocan and python `canopen` side by side on one python-can udp_multicast bus, in one run:
//! the same SDO transfers from each stack's client to a duocan server node (one each, alike, on
//! one runtime), and a PDO echo by
//! each stack, with wall time, throughput and the CPU seconds of each side, then the ratios,
//! over several rounds (median and spread); twenty duocan nodes read at once through one handle
//! against one; the bare transport's round trip, the floor any stack stands on; and
//! one-at-a-time reads through the front door (`duocan::net::Network`) on one bus and the
//! redundant door on two, as ratios of the bare ping-pong (`common/door_speed.rs`). The
//! comparison figures in BENCHMARKS.md come from this table.
//!
//! Run by `.ci/tier-python.sh` (not with `--no-bench`), inside `unshare -n`:
//! `cargo test --release -p duocan-tiers --features python --test python_bench -- --nocapture`.
//! `DUOCAN_BENCH_ROUNDS` sets the rounds (default 3).
//!
//! CPU time is read from the kernel's per-thread clocks: each duocan side runs on a tokio
//! runtime of its own whose threads carry its name, and python reports its process's own.

#[path = "common/door_speed.rs"]
mod door_speed;
use door_speed::runtime;
#[path = "common/peer.rs"]
mod peer;
#[path = "../../tests/common/runtime.rs"]
mod rt;
#[path = "common/wire.rs"]
mod wire;

use duocan::machine::{Composite, Machine, Station};
use duocan::od::{Access, DataType, ObjectDef};
use duocan::port::udp::{UdpBusConfig, UdpPort};
use duocan::runtime::Runtime;
use duocan::sdo::{SdoOptions, TransferMode};
use duocan::{Frame, Id, Instant, NodeId};
use peer::{group, Peer};
use std::collections::VecDeque;
use std::time::{Duration, Instant as StdInstant};
use wire::Wire;

/// The server duocan's client reads and writes, and its twin python's client does: one SDO
/// channel each (python `canopen` takes every answer on its channel for its own).
const SERVER: u8 = 0x40;
const PY_SERVER: u8 = 0x41;
/// The 64 KiB domain transferred.
const BLOB: u16 = 0x2003;
const SIZE: usize = 64 * 1024;
const READS: usize = 10_000;
const ECHOES: u64 = 5_000;
const ECHO_WINDOW: u64 = 16;
/// Nodes read at once through one handle, node-IDs from [`FIRST_OF_MANY`].
const CONCURRENT: u8 = 20;
const FIRST_OF_MANY: u8 = 0x50;

/// CPU seconds so far of this process's threads named `name`: the runtime's workers and its
/// ports' reader threads (named `name-rxN` after the worker that starts them).
fn cpu(name: &str) -> f64 {
    let Ok(dir) = std::fs::read_dir("/proc/self/task") else {
        return 0.0;
    };
    let ours = |c: &str| c == name || c.strip_prefix(name).is_some_and(|r| r.starts_with("-rx"));
    dir.filter_map(Result::ok)
        .filter(|t| std::fs::read_to_string(t.path().join("comm")).is_ok_and(|c| ours(c.trim())))
        .filter_map(|t| std::fs::read_to_string(t.path().join("schedstat")).ok())
        .filter_map(|s| s.split_whitespace().next()?.parse::<u64>().ok())
        .sum::<u64>() as f64
        / 1e9
}

/// One measurement: the rate (KiB/s or operations/s) and the CPU seconds of each side.
#[derive(Clone, Copy, Default)]
struct Run {
    rate: f64,
    /// The side that asks (SDO client, echo driver's peer: the echo itself).
    cpu_a: f64,
    /// The duocan SDO server (none for the echo).
    cpu_b: f64,
}

/// What one row measures.
#[derive(Clone, Copy)]
enum Op {
    SegUp,
    SegDown,
    BlockUp,
    BlockDown,
    Expedited,
}

impl Op {
    const ALL: [Op; 5] = [
        Op::SegUp,
        Op::SegDown,
        Op::BlockUp,
        Op::BlockDown,
        Op::Expedited,
    ];
    fn name(self) -> &'static str {
        match self {
            Op::SegUp => "SDO segmented upload, 64 KiB",
            Op::SegDown => "SDO segmented download, 64 KiB",
            Op::BlockUp => "SDO block upload, 64 KiB",
            Op::BlockDown => "SDO block download, 64 KiB",
            Op::Expedited => "SDO expedited reads, 10,000",
        }
    }
    /// python's command for it.
    fn command(self) -> String {
        match self {
            Op::SegUp => format!("seg_up {BLOB:04X} 0"),
            Op::SegDown => format!("seg_down {BLOB:04X} 0 {SIZE}"),
            Op::BlockUp => format!("block_up {BLOB:04X} 0"),
            Op::BlockDown => format!("block_down {BLOB:04X} 0 {SIZE}"),
            Op::Expedited => format!("expedited 1018 1 {READS}"),
        }
    }
    /// Rate from seconds.
    fn rate(self, secs: f64) -> f64 {
        match self {
            Op::Expedited => READS as f64 / secs,
            _ => SIZE as f64 / 1024.0 / secs,
        }
    }
    fn unit(self) -> &'static str {
        match self {
            Op::Expedited => "reads/s",
            _ => "KiB/s",
        }
    }
}

/// A duocan server `id`: a slave with the 64 KiB domain (and the SDO test entries).
fn server(id: u8) -> Station<duocan::machine::SinglePort, rt::TestNode> {
    let mut n = rt::sdo_node(id, false, 0, &[]);
    n.od_mut()
        .insert(ObjectDef::bytes(BLOB, 0, DataType::Domain, SIZE as u32).access(Access::Rw))
        .expect("new entry");
    Station::single(n)
}

/// Answers 0x181 with 0x1A1 (same data): a PDO echo.
#[derive(Default)]
struct Echo {
    out: VecDeque<Frame>,
}

impl Machine for Echo {
    type Event = ();
    type LinkCommand = std::convert::Infallible;
    fn handle_frame(&mut self, _: Instant, f: &Frame) {
        if f.id() == Id::Standard(0x181) {
            if let Ok(r) = Frame::new(Id::Standard(0x1A1), f.data()) {
                self.out.push_back(r);
            }
        }
    }
    fn handle_timeout(&mut self, _: Instant) {}
    fn poll_transmit(&mut self) -> Option<Frame> {
        self.out.pop_front()
    }
    fn poll_timeout(&self) -> Option<Instant> {
        None
    }
    fn poll_event(&mut self) -> Option<()> {
        None
    }
}

/// Sends `ECHOES` PDOs keeping a window in flight and counts the answers: echoes/s.
fn drive_echo(cfg: &UdpBusConfig) -> f64 {
    let mut w = Wire::open(cfg);
    let start = StdInstant::now();
    let (mut sent, mut got) = (0u64, 0u64);
    let ping = |i: u64| Frame::new(Id::Standard(0x181), &i.to_le_bytes()).unwrap();
    while sent < ECHO_WINDOW {
        w.send(&ping(sent));
        sent += 1;
    }
    while got < ECHOES {
        match w.recv() {
            Some(f) if f.id() == Id::Standard(0x1A1) => {
                got += 1;
                if sent < ECHOES {
                    w.send(&ping(sent));
                    sent += 1;
                }
            }
            Some(_) => {}
            None => panic!("the echo stalled after {got} of {ECHOES}"),
        }
    }
    ECHOES as f64 / start.elapsed().as_secs_f64()
}

/// Median and spread (min, max).
fn stats(mut xs: Vec<f64>) -> (f64, f64, f64) {
    xs.sort_by(f64::total_cmp);
    (xs[xs.len() / 2], xs[0], xs[xs.len() - 1])
}

/// "median (min–max)".
fn cell(xs: &[f64]) -> String {
    let (m, lo, hi) = stats(xs.to_vec());
    let f = |x: f64| {
        if x >= 100.0 {
            format!("{x:.0}")
        } else {
            format!("{x:.2}")
        }
    };
    format!("{} ({}–{})", f(m), f(lo), f(hi))
}

#[test]
fn duocan_and_python_canopen_side_by_side() {
    let rounds: usize = std::env::var("DUOCAN_BENCH_ROUNDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(3)
        .max(1);
    let cfg = UdpBusConfig::numbered(12);
    let echo_cfg = UdpBusConfig::numbered(13);
    let (ctl, srv, cli) = (
        runtime("bench-ctl"),
        runtime("duocan-srv"),
        runtime("duocan-cli"),
    );
    let port = |rt: &tokio::runtime::Runtime, cfg: &UdpBusConfig| {
        let _in = rt.enter();
        UdpPort::open(cfg.clone()).expect("open the UDP bus (inside unshare -n?)")
    };
    let [server, py_server] = [SERVER, PY_SERVER].map(|id| {
        let p = port(&srv, &cfg);
        let _in = srv.enter();
        Runtime::new(server(id)).port(p).spawn().unwrap()
    });
    let client = {
        let p = port(&cli, &cfg);
        let _in = cli.enter();
        let dev = Station::single(Composite::new(
            rt::node(1, true, 0, &[]),
            duocan::master::MasterSdoClient::with_sessions(SIZE + 1024, CONCURRENT as usize),
        ));
        Runtime::new(dev).name("client").port(p).spawn().unwrap()
    };
    srv.block_on(server.boot()).unwrap();
    srv.block_on(py_server.boot()).unwrap();
    let (g, p) = group(&cfg);
    let mut py = ctl.block_on(Peer::spawn_script(
        "bench.py",
        &["client", &PY_SERVER.to_string(), &g, &p],
    ));
    let node = NodeId::must(SERVER);
    let blob = rt::pattern(SIZE, 3);
    // Uploads read what is there: the 64 KiB first, on both servers. A failure says how long
    // the write ran and what every duocan port counted (drops on a full socket queue, refused
    // datagrams), so that a flake here shows its cause.
    for id in [SERVER, PY_SERVER] {
        let write = client.sdo_write(
            NodeId::must(id),
            BLOB,
            0,
            blob.clone(),
            SdoOptions::default(),
        );
        let t0 = StdInstant::now();
        if let Err(e) = cli.block_on(write) {
            panic!(
                "writing the 64 KiB to node {id:#x}: {e:?} after {:?}; ports: client {:?}, server {:?}, python's server {:?}",
                t0.elapsed(),
                client.port_counters(0),
                server.port_counters(0),
                py_server.port_counters(0),
            );
        }
    }

    let mut duocan = vec![Vec::new(); Op::ALL.len()];
    let mut python = vec![Vec::new(); Op::ALL.len()];
    let mut python_failed = [0usize; Op::ALL.len()];
    for _ in 0..rounds {
        for (i, op) in Op::ALL.into_iter().enumerate() {
            let (c0, s0, t0) = (cpu("duocan-cli"), cpu("duocan-srv"), StdInstant::now());
            let mode = SdoOptions::mode;
            let (client, blob) = (client.clone(), blob.clone());
            // On the runtime, as an application's task would be (not across threads from here).
            let task = cli.spawn(async move {
                match op {
                    Op::SegUp | Op::BlockUp => {
                        let m = if matches!(op, Op::SegUp) {
                            TransferMode::Segmented
                        } else {
                            TransferMode::Block
                        };
                        let v = client.sdo_read(node, BLOB, 0, mode(m)).await.unwrap();
                        assert_eq!(v.len(), SIZE);
                    }
                    Op::SegDown | Op::BlockDown => {
                        let m = if matches!(op, Op::SegDown) {
                            TransferMode::Segmented
                        } else {
                            TransferMode::Block
                        };
                        client
                            .sdo_write(node, BLOB, 0, blob, mode(m))
                            .await
                            .unwrap();
                    }
                    Op::Expedited => {
                        for _ in 0..READS {
                            client
                                .sdo_read(node, 0x1018, 1, SdoOptions::default())
                                .await
                                .unwrap();
                        }
                    }
                }
            });
            cli.block_on(task).unwrap();
            let secs = t0.elapsed().as_secs_f64();
            duocan[i].push(Run {
                rate: op.rate(secs),
                cpu_a: cpu("duocan-cli") - c0,
                cpu_b: cpu("duocan-srv") - s0,
            });

            // python's block transfers give up on a sub-block whose segments its socket did not
            // keep up with ("unexpected response"): tried once more, then counted as failed.
            for _attempt in 0..2 {
                let s0 = cpu("duocan-srv");
                let line = ctl.block_on(async {
                    py.send_line(&op.command()).await;
                    py.result("RESULT", 120).await
                });
                let line = match line {
                    Ok(l) => l,
                    Err(e) => {
                        eprintln!("python canopen: {}: {e}", op.name());
                        python_failed[i] += 1;
                        continue;
                    }
                };
                let w: Vec<&str> = line.split_whitespace().collect();
                let (wall, py_cpu): (f64, f64) = (w[2].parse().unwrap(), w[3].parse().unwrap());
                if matches!(op, Op::SegUp | Op::BlockUp) {
                    let size = ctl.block_on(py.expect("SIZE", 5));
                    assert_eq!(size, format!("SIZE {SIZE}"), "python read the 64 KiB");
                }
                python[i].push(Run {
                    rate: op.rate(wall),
                    cpu_a: py_cpu,
                    cpu_b: cpu("duocan-srv") - s0,
                });
                break;
            }
        }
    }
    ctl.block_on(py.stop());
    eprintln!(
        "overruns: server {:?}, python's server {:?}, client {:?}",
        server.port_counters(0).map(|c| c.rx_overrun),
        py_server.port_counters(0).map(|c| c.rx_overrun),
        client.port_counters(0).map(|c| c.rx_overrun),
    );

    // Twenty duocan nodes on the bus, read at once through the one client handle, against one.
    let nodes: Vec<_> = (0..CONCURRENT)
        .map(|k| {
            let p = port(&srv, &cfg);
            let _in = srv.enter();
            let n = rt::sdo_node(FIRST_OF_MANY + k, false, 0, &[]);
            Runtime::new(Station::single(n)).port(p).spawn().unwrap()
        })
        .collect();
    for n in &nodes {
        srv.block_on(n.boot()).unwrap();
    }
    let mut many = (Vec::new(), Vec::new());
    for _ in 0..rounds {
        let c = client.clone();
        let (one, twenty) = cli
            .block_on(cli.spawn(async move {
                let read = |c: duocan::runtime::Handle<_>, id: u8| async move {
                    let v = c
                        .sdo_read(NodeId::must(id), 0x2001, 0, SdoOptions::default())
                        .await
                        .unwrap();
                    assert_eq!(v, b"duocan node over a real bus");
                };
                let t = StdInstant::now();
                read(c.clone(), FIRST_OF_MANY).await;
                let one = t.elapsed();
                let t = StdInstant::now();
                let mut all = tokio::task::JoinSet::new();
                for k in 0..CONCURRENT {
                    all.spawn(read(c.clone(), FIRST_OF_MANY + k));
                }
                while all.join_next().await.is_some() {}
                (one, t.elapsed())
            }))
            .unwrap();
        many.0.push(one.as_secs_f64() * 1e3);
        many.1.push(twenty.as_secs_f64() * 1e3);
    }
    for n in &nodes {
        srv.block_on(n.shutdown());
    }
    cli.block_on(client.shutdown());

    // The PDO echo, each stack in turn on a bus of its own (both would answer a 0x181).
    let mut echo = [Vec::new(), Vec::new()];
    let (eg, ep) = group(&echo_cfg);
    let rt_echo = runtime("duocan-echo");
    for _ in 0..rounds {
        let h = {
            let p = port(&rt_echo, &echo_cfg);
            let _in = rt_echo.enter();
            Runtime::new(Station::single(Echo::default()))
                .port(p)
                .spawn()
                .unwrap()
        };
        std::thread::sleep(Duration::from_millis(50));
        let c0 = cpu("duocan-echo");
        let rate = drive_echo(&echo_cfg);
        echo[0].push(Run {
            rate,
            cpu_a: cpu("duocan-echo") - c0,
            cpu_b: 0.0,
        });
        rt_echo.block_on(h.shutdown());

        let mut pe = ctl.block_on(Peer::spawn_script("bench.py", &["echo", &eg, &ep]));
        let py_cpu = |pe: &mut Peer| {
            let l = ctl.block_on(async {
                pe.send_line("cpu").await;
                pe.expect("CPU", 10).await
            });
            l[4..].trim().parse::<f64>().unwrap()
        };
        let c0 = py_cpu(&mut pe);
        let rate = drive_echo(&echo_cfg);
        echo[1].push(Run {
            rate,
            cpu_a: py_cpu(&mut pe) - c0,
            cpu_b: 0.0,
        });
        ctl.block_on(pe.stop());
    }

    let rtt = wire::round_trip(&UdpBusConfig::numbered(14), 5_000);
    // One-at-a-time reads through the front door, on one bus and on two, against the bare
    // ping-pong: side by side, on buses of their own.
    let door = door_speed::measure(
        &[55, 56, 57, 58, 59].map(UdpBusConfig::numbered),
        5_000,
        rounds.max(3),
    );
    srv.block_on(server.shutdown());
    srv.block_on(py_server.shutdown());

    println!();
    println!(
        "duocan vs python canopen on one python-can udp_multicast bus, {rounds} rounds: median (min–max)"
    );
    println!(
        "{:<40} {:>24} {:>30} {:>7} {:>22} {:>22}",
        "", "duocan", "python canopen", "ratio", "CPU s duocan cli/srv", "CPU s python cli/srv"
    );
    let row = |name: &str, unit: &str, d: &[Run], p: &[Run], failed: usize| {
        let r = |v: &[Run]| v.iter().map(|x| x.rate).collect::<Vec<_>>();
        let c = |v: &[Run]| {
            if v.is_empty() {
                return "-".to_string();
            }
            let a = stats(v.iter().map(|x| x.cpu_a).collect()).0;
            let b = stats(v.iter().map(|x| x.cpu_b).collect()).0;
            if b > 0.0 {
                format!("{a:.3} / {b:.3}")
            } else {
                format!("{a:.3}")
            }
        };
        let (py, ratio) = if p.is_empty() {
            ("failed".to_string(), "-".to_string())
        } else {
            let ratio = stats(r(d)).0 / stats(r(p)).0;
            (cell(&r(p)), format!("{ratio:.1}×"))
        };
        let py = if failed > 0 {
            format!("{py} [{failed} failed]")
        } else {
            py
        };
        println!(
            "{:<40} {:>24} {:>30} {:>7} {:>22} {:>22}",
            format!("{name} ({unit})"),
            cell(&r(d)),
            py,
            ratio,
            c(d),
            c(p)
        );
    };
    for (i, op) in Op::ALL.into_iter().enumerate() {
        row(
            op.name(),
            op.unit(),
            &duocan[i],
            &python[i],
            python_failed[i],
        );
    }
    row(
        "PDO echo, window 16, 5,000",
        "echoes/s",
        &echo[0],
        &echo[1],
        0,
    );
    let (one, twenty) = (stats(many.0.clone()).0, stats(many.1.clone()).0);
    println!(
        "{CONCURRENT} duocan nodes read at once through one handle (segmented upload, 27 bytes): \
         {} ms, against one node alone {} ms: {:.1}× the time for {CONCURRENT}× the reads",
        cell(&many.1),
        cell(&many.0),
        twenty / one
    );
    println!(
        "bare transport: a socket ping-pong over the same bus format takes {rtt:.1} µs a round \
         trip ({:.0} round trips/s, the ceiling of one-at-a-time SDO reads)",
        1e6 / rtt
    );
    println!("{}", door.report());
    // The comparison must say something that noise cannot turn over: on a machine shared with
    // other work the wall times spread (read the medians), but on every row duocan's client
    // spends less CPU than python's for the same transfer.
    for (i, op) in Op::ALL.into_iter().enumerate() {
        if python[i].is_empty() {
            continue;
        }
        let (d, p) = (
            stats(duocan[i].iter().map(|x| x.cpu_a).collect()).0,
            stats(python[i].iter().map(|x| x.cpu_a).collect()).0,
        );
        // A transfer costs its client some CPU: none means the wrong threads were counted.
        assert!(
            d > 0.0 && d < p,
            "{}: duocan {d:.3} s of CPU vs python {p:.3} s",
            op.name()
        );
    }
}
