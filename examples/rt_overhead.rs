//! Runtime overhead: frames/s through the tokio runtime against a bare socket loop, same run.
//!
//! An echo device answers every frame 0x100 with 0x101 (same data). A driver keeps a window of
//! 16 frames in flight and counts echoes. First the echo is a bare blocking loop on the socket
//! (read, re-encode, write), then the same echo runs as a machine under the runtime on a duocan
//! port. The ratio runtime/bare is the runtime's cost.
//!
//! ```text
//! rt_overhead vcan N   # needs vcan0 (inside .ci/vcanvm), feature `socketcan`
//! rt_overhead udp N    # needs loopback multicast (inside `unshare -n`), feature `udp`
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

/// Sends `n` pings with a window and waits for every pong; returns frames/s through the echo.
fn drive(w: &mut dyn Wire, n: u64) -> Result<f64, String> {
    let start = StdInstant::now();
    let mut sent = 0;
    let mut got = 0;
    while sent < WINDOW.min(n) {
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

fn bare_echo(mut w: Box<dyn Wire>, n: u64) -> std::thread::JoinHandle<()> {
    std::thread::spawn(move || {
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
                Ok(None) | Err(_) => return,
            }
        }
    })
}

fn report(medium: &str, n: u64, bare: f64, rt: f64) {
    println!("{medium}: {n} frames echoed, window {WINDOW}");
    println!("  bare socket loop : {bare:>10.0} frames/s");
    println!("  tokio runtime    : {rt:>10.0} frames/s");
    println!("  ratio runtime/bare: {:.2}", rt / bare);
}

#[cfg(all(feature = "socketcan", target_os = "linux"))]
mod vcan {
    use super::*;
    use duocan::port::socketcan::SocketCanPort;
    use socketcan::{CanFrame, Socket};

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
                .write_frame_insist(&CanFrame::from(f))
                .map_err(|e| e.to_string())
        }
        fn recv(&mut self) -> Result<Option<Frame>, String> {
            match self.0.read_frame() {
                Ok(f) => Ok(Frame::try_from(&f).ok()),
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

    pub fn run(n: u64) -> Result<(), Box<dyn std::error::Error>> {
        let echo = bare_echo(Box::new(Can::open("vcan0")?), n);
        let bare = drive(&mut Can::open("vcan0")?, n)?;
        let _ = echo.join();
        let rt = tokio::runtime::Runtime::new()?;
        let handle = rt.block_on(async {
            let port = SocketCanPort::open("vcan0")?;
            let echo = Runtime::new(Station::single(Echo::default()))
                .name("echo")
                .port(port)
                .spawn()?;
            Ok::<_, Box<dyn std::error::Error>>(echo)
        })?;
        std::thread::sleep(Duration::from_millis(50));
        let through = drive(&mut Can::open("vcan0")?, n)?;
        rt.block_on(handle.shutdown());
        report("vcan0", n, bare, through);
        Ok(())
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

    pub fn run(n: u64) -> Result<(), Box<dyn std::error::Error>> {
        let cfg = UdpBusConfig::numbered(7);
        let echo = bare_echo(Box::new(Udp::open(&cfg)?), n);
        let bare = drive(&mut Udp::open(&cfg)?, n)?;
        let _ = echo.join();
        let rt = tokio::runtime::Runtime::new()?;
        let handle = rt.block_on(async {
            let port = UdpPort::open(cfg.clone())?;
            let echo = Runtime::new(Station::single(Echo::default()))
                .name("echo")
                .port(port)
                .spawn()?;
            Ok::<_, Box<dyn std::error::Error>>(echo)
        })?;
        std::thread::sleep(Duration::from_millis(50));
        let through = drive(&mut Udp::open(&cfg)?, n)?;
        rt.block_on(handle.shutdown());
        report(&format!("udp {}", cfg.name()), n, bare, through);
        Ok(())
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let n: u64 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(20_000);
    let r: Result<(), Box<dyn std::error::Error>> = match args.get(1).map(String::as_str) {
        #[cfg(all(feature = "socketcan", target_os = "linux"))]
        Some("vcan") => vcan::run(n),
        #[cfg(feature = "udp")]
        Some("udp") => udp::run(n),
        _ => Err(
            "usage: rt_overhead vcan|udp [FRAMES] (vcan needs feature socketcan, udp feature udp)"
                .into(),
        ),
    };
    if let Err(e) = r {
        eprintln!("rt_overhead: {e}");
        std::process::exit(1);
    }
}
