//! Runtime overhead: the tokio runtime against a bare socket loop, side by side in one run.
//!
//! An echo device answers every frame 0x100 with 0x101 (same data). A driver sends pings and
//! counts echoes, twice per round: with one frame in flight (the round trip, what an SDO
//! transfer waits for) and with a window of 16 (throughput). The echo is first a bare blocking
//! loop on the socket (read, re-encode, write), then the same echo as a machine under the
//! runtime on a duocan port. The echo side's CPU time (its threads' own clocks) is divided by
//! the frames it echoed. Several rounds alternate bare and runtime; the table gives each
//! ratio's median and spread (min–max), which is what to read on a machine shared with other
//! work.
//!
//! ```text
//! rt_overhead vcan N [ROUNDS]  # needs vcan0 (inside .ci/vcanvm), feature `socketcan`
//! rt_overhead udp N [ROUNDS]   # needs loopback multicast (inside `unshare -n`), feature `udp`
//! ```

// Built without `udp` and `socketcan` (a plain `cargo test` enables only `tokio`), the example
// has no transport and only prints its usage: what the transports share goes unused.
#![cfg_attr(
    not(any(feature = "udp", all(feature = "socketcan", target_os = "linux"))),
    allow(unused)
)]

use duocan::machine::{Machine, Station};
use duocan::runtime::Runtime;
use duocan::{Frame, Id, Instant};
use std::collections::VecDeque;
use std::time::{Duration, Instant as StdInstant};

const WINDOW: u64 = 16;
const PING: u16 = 0x100;
const PONG: u16 = 0x101;

/// Answers 0x100 with 0x101.
#[derive(Default)]
struct Echo {
    out: VecDeque<Frame>,
}

impl Machine for Echo {
    type Event = ();
    type LinkCommand = std::convert::Infallible;
    fn handle_frame(&mut self, _: Instant, f: &Frame) {
        if f.id() == Id::Standard(PING) {
            if let Ok(r) = Frame::new(Id::Standard(PONG), f.data()) {
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

/// A blocking socket for the driver and the bare echo.
trait Wire: Send {
    fn send(&mut self, f: &Frame) -> Result<(), String>;
    /// Next frame, `None` on timeout.
    fn recv(&mut self) -> Result<Option<Frame>, String>;
}

fn ping(i: u64) -> Frame {
    Frame::new(Id::Standard(PING), &i.to_le_bytes()).unwrap_or_else(|_| unreachable!())
}

/// Sends `n` pings keeping `window` in flight and waits for every pong; returns frames/s
/// through the echo.
fn drive(w: &mut dyn Wire, n: u64, window: u64) -> Result<f64, String> {
    let start = StdInstant::now();
    let mut sent = 0;
    let mut got = 0;
    while sent < window.min(n) {
        w.send(&ping(sent))?;
        sent += 1;
    }
    while got < n {
        match w.recv()? {
            Some(f) if f.id() == Id::Standard(PONG) => {
                got += 1;
                if sent < n {
                    w.send(&ping(sent))?;
                    sent += 1;
                }
            }
            Some(_) => {}
            None => return Err(format!("echo stalled after {got} of {n} frames")),
        }
    }
    Ok(n as f64 / start.elapsed().as_secs_f64())
}

/// CPU time of one thread of this process (ns) and the times it was put on a CPU, from the
/// kernel's scheduler statistics.
fn thread_cpu(task: &str) -> Cpu {
    let s =
        std::fs::read_to_string(format!("/proc/self/task/{task}/schedstat")).unwrap_or_default();
    let mut f = s.split_whitespace().map(|x| x.parse().unwrap_or(0));
    let ns = f.next().unwrap_or(0);
    let slices = f.nth(1).unwrap_or(0);
    Cpu { ns, slices }
}

/// CPU time (ns) and times put on a CPU (each a wake-up or a preemption: a context switch).
#[derive(Clone, Copy, Default)]
struct Cpu {
    ns: u64,
    slices: u64,
}

impl std::ops::Sub for Cpu {
    type Output = Cpu;
    fn sub(self, o: Cpu) -> Cpu {
        Cpu {
            ns: self.ns.saturating_sub(o.ns),
            slices: self.slices.saturating_sub(o.slices),
        }
    }
}

impl std::iter::Sum for Cpu {
    fn sum<I: Iterator<Item = Cpu>>(it: I) -> Cpu {
        it.fold(Cpu::default(), |a, b| Cpu {
            ns: a.ns + b.ns,
            slices: a.slices + b.slices,
        })
    }
}

/// This thread's id (the driver's, whose CPU is not the echo's).
fn own_tid() -> String {
    std::fs::read_link("/proc/thread-self")
        .ok()
        .and_then(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
        .unwrap_or_default()
}

/// CPU time of every thread of this process but `except`: the runtime's threads.
fn others_cpu(except: &str) -> Cpu {
    let Ok(dir) = std::fs::read_dir("/proc/self/task") else {
        return Cpu::default();
    };
    dir.filter_map(Result::ok)
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|t| t != except)
        .map(|t| thread_cpu(&t))
        .sum()
}

/// The bare echo of `n` frames on its own thread; it returns the CPU time it used (ns).
fn bare_echo(mut w: Box<dyn Wire>, n: u64) -> std::thread::JoinHandle<Cpu> {
    std::thread::spawn(move || {
        let me = own_tid();
        let start = thread_cpu(&me);
        let mut done = 0;
        while done < n {
            match w.recv() {
                Ok(Some(f)) if f.id() == Id::Standard(PING) => {
                    if let Ok(r) = Frame::new(Id::Standard(PONG), f.data()) {
                        let _ = w.send(&r);
                    }
                    done += 1;
                }
                Ok(Some(_)) => {}
                Ok(None) | Err(_) => break,
            }
        }
        thread_cpu(&me) - start
    })
}

/// One measurement: frames/s through the echo and its CPU time per frame (µs).
#[derive(Clone, Copy)]
struct Run {
    rate: f64,
    cpu_us: f64,
    /// Times the echo's threads were put on a CPU, per frame.
    switches: f64,
}

/// Everything a round measures, bare and through the runtime.
#[derive(Clone, Copy)]
struct Round {
    rtt: [Run; 2],
    flow: [Run; 2],
}

/// Opens the driver's (and the bare echo's) blocking socket.
type Open<'a> = dyn Fn() -> Result<Box<dyn Wire>, String> + 'a;

/// Starts the echo machine under the runtime on the medium.
type Start<'a> = dyn Fn() -> Result<duocan::runtime::Handle<Station<duocan::machine::SinglePort, Echo>>, String>
    + 'a;

/// Round trips (window 1) and throughput (window 16), bare then through the runtime.
fn round(
    rt: &tokio::runtime::Runtime,
    open: &Open<'_>,
    start: &Start<'_>,
    n: u64,
) -> Result<Round, String> {
    let me = own_tid();
    let mut out = Round {
        rtt: [Run {
            rate: 0.0,
            cpu_us: 0.0,
            switches: 0.0,
        }; 2],
        flow: [Run {
            rate: 0.0,
            cpu_us: 0.0,
            switches: 0.0,
        }; 2],
    };
    for (window, slot) in [(1, 0), (WINDOW, 1)] {
        let frames = if window == 1 { n / 4 } else { n };
        let echo = bare_echo(open()?, frames);
        let rate = drive(&mut *open()?, frames, window)?;
        let cpu = echo.join().map_err(|_| "bare echo panicked")?;
        let bare = Run {
            rate,
            cpu_us: cpu.ns as f64 / 1e3 / frames as f64,
            switches: cpu.slices as f64 / frames as f64,
        };
        let handle = {
            let _in_rt = rt.enter();
            start()?
        };
        std::thread::sleep(Duration::from_millis(50));
        let mut w = open()?;
        let before = others_cpu(&me);
        let rate = drive(&mut *w, frames, window)?;
        let cpu = others_cpu(&me) - before;
        rt.block_on(handle.shutdown());
        let through = Run {
            rate,
            cpu_us: cpu.ns as f64 / 1e3 / frames as f64,
            switches: cpu.slices as f64 / frames as f64,
        };
        let runs = if slot == 0 {
            &mut out.rtt
        } else {
            &mut out.flow
        };
        *runs = [bare, through];
    }
    Ok(out)
}

/// Median and spread of `xs`.
fn stats(mut xs: Vec<f64>) -> (f64, f64, f64) {
    xs.sort_by(f64::total_cmp);
    (xs[xs.len() / 2], xs[0], xs[xs.len() - 1])
}

fn compare(
    medium: &str,
    open: &Open<'_>,
    start: &Start<'_>,
    n: u64,
    rounds: usize,
) -> Result<(), String> {
    // As `#[tokio::main]` gives: one worker per CPU.
    let rt = tokio::runtime::Runtime::new().map_err(|e| e.to_string())?;
    let mut all = Vec::new();
    for _ in 0..rounds {
        all.push(round(&rt, open, start, n)?);
    }
    println!(
        "{medium}: echo, {rounds} rounds of {} round trips and {n} frames in a window of {WINDOW}",
        n / 4
    );
    println!(
        "  {:<34} {:>12} {:>12} {:>22}",
        "", "bare", "runtime", "ratio median (spread)"
    );
    let line = |what: &str,
                unit: &str,
                pick: &dyn Fn(&Round) -> (f64, f64),
                ratio: &dyn Fn(f64, f64) -> f64| {
        let b = stats(all.iter().map(|r| pick(r).0).collect()).0;
        let t = stats(all.iter().map(|r| pick(r).1).collect()).0;
        let (m, lo, hi) = stats(
            all.iter()
                .map(|r| {
                    let (b, t) = pick(r);
                    ratio(b, t)
                })
                .collect(),
        );
        println!(
            "  {:<34} {:>12} {:>12} {:>9.2} ({lo:.2}–{hi:.2})",
            format!("{what} ({unit})"),
            fmt(b),
            fmt(t),
            m
        );
    };
    let over = |b: f64, t: f64| t / b;
    line(
        "round trip",
        "µs",
        &|r| (1e6 / r.rtt[0].rate, 1e6 / r.rtt[1].rate),
        &over,
    );
    line(
        "throughput",
        "frames/s",
        &|r| (r.flow[0].rate, r.flow[1].rate),
        &over,
    );
    line(
        "echo CPU per frame, window 16",
        "µs",
        &|r| (r.flow[0].cpu_us, r.flow[1].cpu_us),
        &over,
    );
    line(
        "echo CPU per frame, window 1",
        "µs",
        &|r| (r.rtt[0].cpu_us, r.rtt[1].cpu_us),
        &over,
    );
    line(
        "echo switches per frame, window 16",
        "n",
        &|r| (r.flow[0].switches, r.flow[1].switches),
        &over,
    );
    let (m, ..) = stats(
        all.iter()
            .map(|r| r.flow[1].rate / r.flow[0].rate)
            .collect(),
    );
    // The one line earlier versions printed (CI logs compare it).
    println!("  ratio runtime/bare: {m:.2}");
    Ok(())
}

fn fmt(x: f64) -> String {
    if x >= 100.0 {
        format!("{x:.0}")
    } else {
        format!("{x:.2}")
    }
}

#[cfg(all(feature = "socketcan", target_os = "linux"))]
mod vcan {
    use super::*;
    use duocan::port::socketcan::{frame_from_socketcan, socketcan_frame, SocketCanPort};
    use socketcan::Socket;

    pub struct Can(socketcan::CanSocket);
    impl Can {
        pub fn open(ifname: &str) -> Result<Self, String> {
            let s =
                socketcan::CanSocket::open(ifname).map_err(|e| format!("open {ifname}: {e}"))?;
            s.set_read_timeout(Duration::from_secs(3))
                .map_err(|e| e.to_string())?;
            Ok(Can(s))
        }
    }
    impl Wire for Can {
        fn send(&mut self, f: &Frame) -> Result<(), String> {
            self.0
                .write_frame_insist(&socketcan_frame(f))
                .map_err(|e| e.to_string())
        }
        fn recv(&mut self) -> Result<Option<Frame>, String> {
            match self.0.read_frame() {
                Ok(f) => Ok(frame_from_socketcan(f).ok()),
                Err(e)
                    if e.kind() == std::io::ErrorKind::WouldBlock
                        || e.kind() == std::io::ErrorKind::TimedOut =>
                {
                    Ok(None)
                }
                Err(e) => Err(e.to_string()),
            }
        }
    }

    pub fn run(n: u64, rounds: usize) -> Result<(), String> {
        let open = || Ok(Box::new(Can::open("vcan0")?) as Box<dyn Wire>);
        let start = || {
            let port = SocketCanPort::open("vcan0").map_err(|e| e.to_string())?;
            Runtime::new(Station::single(Echo::default()))
                .name("echo")
                .port(port)
                .spawn()
                .map_err(|e| e.to_string())
        };
        compare("vcan0", &open, &start, n, rounds)
    }
}

#[cfg(feature = "udp")]
mod udp {
    use super::*;
    use duocan::port::udp::{decode, encode, UdpBusConfig, UdpPort};
    use socket2::{Domain, Protocol, Socket, Type};
    use std::net::{SocketAddr, SocketAddrV4, UdpSocket};

    pub struct Udp {
        rx: UdpSocket,
        tx: UdpSocket,
        own: SocketAddr,
        dest: SocketAddr,
        buf: Vec<u8>,
    }
    impl Udp {
        pub fn open(cfg: &UdpBusConfig) -> Result<Self, String> {
            let e = |x: std::io::Error| {
                format!("{}: {x} (run inside `unshare -n` with `ip link set lo up; ip route add 224.0.0.0/4 dev lo`)", cfg.name())
            };
            let rx = Socket::new(Domain::IPV4, Type::DGRAM, Some(Protocol::UDP)).map_err(e)?;
            rx.set_reuse_address(true).map_err(e)?;
            rx.set_reuse_port(true).map_err(e)?;
            rx.bind(&SocketAddrV4::new(cfg.group, cfg.port).into())
                .map_err(e)?;
            rx.join_multicast_v4(&cfg.group, &cfg.interface)
                .map_err(e)?;
            rx.set_read_timeout(Some(Duration::from_secs(3)))
                .map_err(e)?;
            let tx = Socket::new(Domain::IPV4, Type::DGRAM, Some(Protocol::UDP)).map_err(e)?;
            tx.set_multicast_if_v4(&cfg.interface).map_err(e)?;
            tx.set_multicast_ttl_v4(1).map_err(e)?;
            tx.bind(&SocketAddrV4::new(cfg.interface, 0).into())
                .map_err(e)?;
            let tx: UdpSocket = tx.into();
            let own = tx.local_addr().map_err(e)?;
            Ok(Udp {
                rx: rx.into(),
                tx,
                own,
                dest: SocketAddrV4::new(cfg.group, cfg.port).into(),
                buf: vec![0; 4096],
            })
        }
    }
    impl Wire for Udp {
        fn send(&mut self, f: &Frame) -> Result<(), String> {
            self.tx
                .send_to(&encode(f, 0.0, None), self.dest)
                .map(|_| ())
                .map_err(|e| e.to_string())
        }
        fn recv(&mut self) -> Result<Option<Frame>, String> {
            loop {
                match self.rx.recv_from(&mut self.buf) {
                    Ok((_, from)) if from == self.own => {}
                    Ok((k, _)) => return Ok(decode(&self.buf[..k]).ok().map(|(f, _)| f)),
                    Err(e)
                        if e.kind() == std::io::ErrorKind::WouldBlock
                            || e.kind() == std::io::ErrorKind::TimedOut =>
                    {
                        return Ok(None)
                    }
                    Err(e) => return Err(e.to_string()),
                }
            }
        }
    }

    pub fn run(n: u64, rounds: usize) -> Result<(), String> {
        let cfg = UdpBusConfig::numbered(7);
        let open = || Ok(Box::new(Udp::open(&cfg)?) as Box<dyn Wire>);
        let start = || {
            let port = UdpPort::open(cfg.clone()).map_err(|e| e.to_string())?;
            Runtime::new(Station::single(Echo::default()))
                .name("echo")
                .port(port)
                .spawn()
                .map_err(|e| e.to_string())
        };
        compare(&format!("udp {}", cfg.name()), &open, &start, n, rounds)
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let n: u64 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(20_000);
    let rounds: usize = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(5).max(1);
    let r: Result<(), String> = match args.get(1).map(String::as_str) {
        #[cfg(all(feature = "socketcan", target_os = "linux"))]
        Some("vcan") => vcan::run(n, rounds),
        #[cfg(feature = "udp")]
        Some("udp") => udp::run(n, rounds),
        _ => Err(
            "usage: rt_overhead vcan|udp [FRAMES] [ROUNDS] (vcan needs feature socketcan, udp feature udp)"
                .into(),
        ),
    };
    if let Err(e) = r {
        eprintln!("rt_overhead: {e}");
        std::process::exit(1);
    }
}
