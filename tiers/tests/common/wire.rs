//! A bare, blocking socket pair on a python-can udp_multicast bus: what a program without any
//! CANopen stack or runtime does, for the transport's own round trip.

use duocan::port::udp::{decode, encode, UdpBusConfig};
use duocan::{Frame, Id};
use socket2::{Domain, Protocol, Socket, Type};
use std::net::{SocketAddr, SocketAddrV4, UdpSocket};
use std::time::{Duration, Instant};

pub struct Wire {
    rx: UdpSocket,
    tx: UdpSocket,
    own: SocketAddr,
    dest: SocketAddr,
    buf: Vec<u8>,
}

impl Wire {
    /// Joins `cfg`'s bus (receives time out after 3 s).
    pub fn open(cfg: &UdpBusConfig) -> Wire {
        let name = cfg.name();
        let e = |x: std::io::Error| -> ! { panic!("{name}: {x} (inside `unshare -n`?)") };
        let rx =
            Socket::new(Domain::IPV4, Type::DGRAM, Some(Protocol::UDP)).unwrap_or_else(|x| e(x));
        rx.set_reuse_address(true).unwrap_or_else(|x| e(x));
        rx.set_reuse_port(true).unwrap_or_else(|x| e(x));
        rx.bind(&SocketAddrV4::new(cfg.group, cfg.port).into())
            .unwrap_or_else(|x| e(x));
        rx.join_multicast_v4(&cfg.group, &cfg.interface)
            .unwrap_or_else(|x| e(x));
        rx.set_read_timeout(Some(Duration::from_secs(3)))
            .unwrap_or_else(|x| e(x));
        let tx =
            Socket::new(Domain::IPV4, Type::DGRAM, Some(Protocol::UDP)).unwrap_or_else(|x| e(x));
        tx.set_multicast_if_v4(&cfg.interface)
            .unwrap_or_else(|x| e(x));
        tx.set_multicast_ttl_v4(1).unwrap_or_else(|x| e(x));
        tx.bind(&SocketAddrV4::new(cfg.interface, 0).into())
            .unwrap_or_else(|x| e(x));
        let tx: UdpSocket = tx.into();
        let own = tx.local_addr().unwrap_or_else(|x| e(x));
        Wire {
            rx: rx.into(),
            tx,
            own,
            dest: SocketAddrV4::new(cfg.group, cfg.port).into(),
            buf: vec![0; 4096],
        }
    }

    pub fn send(&mut self, f: &Frame) {
        self.tx
            .send_to(&encode(f, 0.0, None), self.dest)
            .expect("send");
    }

    /// The next frame another socket sent; `None` after 3 s without one.
    pub fn recv(&mut self) -> Option<Frame> {
        loop {
            match self.rx.recv_from(&mut self.buf) {
                Ok((_, from)) if from == self.own => {}
                Ok((n, _)) => return decode(&self.buf[..n]).ok().map(|(f, _)| f),
                Err(_) => return None,
            }
        }
    }
}

/// The bare round trip on `cfg`'s bus: one thread pings (0x100), another answers (0x101), one
/// frame in flight; microseconds per round trip over `n`.
pub fn round_trip(cfg: &UdpBusConfig, n: u32) -> f64 {
    let mut answer = Wire::open(cfg);
    let mut ask = Wire::open(cfg);
    let echo = std::thread::spawn(move || {
        for _ in 0..n {
            match answer.recv() {
                Some(f) if f.id() == Id::Standard(0x100) => {
                    answer.send(&Frame::new(Id::Standard(0x101), f.data()).unwrap());
                }
                _ => return,
            }
        }
    });
    let start = Instant::now();
    for i in 0..n {
        ask.send(&Frame::new(Id::Standard(0x100), &i.to_le_bytes()).unwrap());
        while ask.recv().expect("the bare echo answers").id() != Id::Standard(0x101) {}
    }
    let us = start.elapsed().as_secs_f64() * 1e6 / n as f64;
    echo.join().expect("the bare echo ran");
    us
}
