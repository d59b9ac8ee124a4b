//! A CAN bus over UDP multicast in python-can's `udp_multicast` wire format.
//!
//! Every frame is one datagram holding a msgpack map with exactly python-can's keys
//! (`timestamp`, `arbitration_id`, `is_extended_id`, `is_remote_frame`, `is_error_frame`,
//! `channel`, `dlc`, `data`, `is_fd`, `bitrate_switch`, `error_state_indicator`), so python-can
//! buses and python `canopen` nodes share the bus with duocan. One multicast group (and port) is
//! one bus; a dual-bus device uses two.
//!
//! Loopback only unless told otherwise: [`UdpBusConfig`] sends with multicast interface
//! 127.0.0.1 and TTL 1 and refuses any other interface unless [`UdpBusConfig::on_interface`]
//! names it. python-can binds its socket to the wildcard address, so keep python buses on
//! distinct ports as well as groups. Only IPv4 groups are supported.
//!
//! CAN FD frames (`is_fd`, `bitrate_switch`, `error_state_indicator`, up to 64 bytes) travel on
//! a bus opened for them ([`UdpBusConfig::with_fd`], as python-can's `fd=True`):
//! [`Port::send_fd`] sends them and [`Port::recv_any`] hands them over. `recv`, and a port not
//! opened for CAN FD, refuse them as below, and the blocking reader ([`Port::reader`]) reads
//! classic frames only.
//!
//! Datagrams that are not classic CAN frames (garbage, truncated, nested deeper than a frame,
//! bytes after the frame, CAN FD, error frames) are counted in [`PortCounters::rx_invalid`](super::PortCounters) and logged; frames this port
//! sent itself come back through multicast loopback and are dropped silently.
//!
//! On Linux every frame comes with the kernel's receive timestamp of its datagram
//! (`SO_TIMESTAMPNS`, put on the monotonic clock at each read), not the `timestamp` field,
//! which is the sender's wall clock when it sent.

mod blocking;
mod codec;
mod rx;

pub use codec::{decode, decode_any, encode, encode_fd, DecodeError, UdpFrame};

use super::{AnyInput, Port, PortCounters, PortError, PortErrorKind, PortInput, PortReader};
use crate::frame::{FdFrame, Frame};
use socket2::{Domain, Protocol, Socket, Type};
use std::net::{Ipv4Addr, SocketAddr, SocketAddrV4};
use std::time::{SystemTime, UNIX_EPOCH};
use tokio::io::Interest;
use tokio::net::UdpSocket;

/// python-can's default IPv4 group.
pub const DEFAULT_GROUP: Ipv4Addr = Ipv4Addr::new(239, 74, 163, 2);
/// python-can's default port.
pub const DEFAULT_PORT: u16 = 43113;
/// Largest datagram read (python-can's receive buffer).
pub const MAX_DATAGRAM: usize = 4096;

/// Where a UDP bus lives and how far its packets may go.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct UdpBusConfig {
    /// Multicast group: one per bus.
    pub group: Ipv4Addr,
    /// UDP port.
    pub port: u16,
    /// Local interface address to send on and join the group on.
    pub interface: Ipv4Addr,
    /// Multicast TTL.
    pub ttl: u32,
    /// `channel` field of sent frames (python-can shows it as `msg.channel`).
    pub channel: Option<String>,
    /// The bus carries CAN FD frames ([`UdpBusConfig::with_fd`]).
    pub fd: bool,
    allow_non_loopback: bool,
}

impl UdpBusConfig {
    /// A bus on `group:port`, loopback only, TTL 1.
    #[must_use]
    pub fn new(group: Ipv4Addr, port: u16) -> Self {
        UdpBusConfig {
            group,
            port,
            interface: Ipv4Addr::LOCALHOST,
            ttl: 1,
            channel: None,
            fd: false,
            allow_non_loopback: false,
        }
    }
    /// python-can's default bus (239.74.163.2:43113), loopback only.
    #[must_use]
    pub fn python_can_default() -> Self {
        Self::new(DEFAULT_GROUP, DEFAULT_PORT)
    }
    /// Bus number `n` of a test network: group 239.74.163.(2+n), port 43113+n.
    #[must_use]
    pub fn numbered(n: u8) -> Self {
        Self::new(
            Ipv4Addr::new(239, 74, 163, 2u8.saturating_add(n)),
            DEFAULT_PORT.saturating_add(n as u16),
        )
    }
    /// Opt in to sending on a non-loopback interface (its local address). CAN traffic then
    /// leaves the machine: only for networks made for it.
    #[must_use]
    pub fn on_interface(mut self, addr: Ipv4Addr) -> Self {
        self.interface = addr;
        self.allow_non_loopback = true;
        self
    }
    /// Sets the `channel` field of sent frames.
    #[must_use]
    pub fn with_channel(mut self, channel: impl Into<String>) -> Self {
        self.channel = Some(channel.into());
        self
    }
    /// The bus carries CAN FD frames, as python-can's `fd=True`: [`Port::send_fd`] sends them
    /// and [`Port::recv_any`] hands them over (without it, `send_fd` is refused and FD
    /// datagrams are counted as invalid).
    #[must_use]
    pub fn with_fd(mut self) -> Self {
        self.fd = true;
        self
    }
    /// Checks the configuration; the error says what to change.
    pub fn validate(&self) -> Result<(), PortError> {
        let name = self.name();
        if !self.group.is_multicast() {
            return Err(PortError::new(
                &name,
                PortErrorKind::Config,
                format!("{} is not an IPv4 multicast group (224.0.0.0/4); python-can's default is {DEFAULT_GROUP}", self.group),
            ));
        }
        if !self.interface.is_loopback() && !self.allow_non_loopback {
            return Err(PortError::new(
                &name,
                PortErrorKind::Config,
                format!(
                    "refusing to put CAN traffic on non-loopback interface {}: call UdpBusConfig::on_interface({}) to opt in",
                    self.interface, self.interface
                ),
            ));
        }
        if self.interface.is_loopback() && self.ttl > 1 {
            return Err(PortError::new(
                &name,
                PortErrorKind::Config,
                format!("TTL {} on loopback: use 0 or 1", self.ttl),
            ));
        }
        Ok(())
    }
    /// `group:port`, the port's name.
    pub fn name(&self) -> String {
        format!("{}:{}", self.group, self.port)
    }
}

/// One UDP multicast bus.
#[derive(Debug)]
pub struct UdpPort {
    cfg: UdpBusConfig,
    name: String,
    sockets: Option<Sockets>,
    counters: PortCounters,
    buf: Vec<u8>,
    stamps: rx::Stamps,
}

#[derive(Debug)]
struct Sockets {
    /// `None` while a reader thread has it ([`Port::reader`]).
    rx: Option<UdpSocket>,
    tx: UdpSocket,
    /// Our send socket's address: datagrams from it are our own, looped back.
    own: SocketAddr,
    dest: SocketAddr,
}

impl UdpPort {
    /// Joins the bus. Must be called inside a tokio runtime.
    pub fn open(cfg: UdpBusConfig) -> Result<Self, PortError> {
        cfg.validate()?;
        let name = cfg.name();
        // Made before the sockets: nothing they read arrived earlier.
        let stamps = rx::Stamps::new();
        let sockets = open_sockets(&cfg, &name)?;
        Ok(UdpPort {
            cfg,
            name,
            sockets: Some(sockets),
            counters: PortCounters::new(),
            buf: vec![0; MAX_DATAGRAM],
            stamps,
        })
    }
    /// The configuration.
    pub fn config(&self) -> &UdpBusConfig {
        &self.cfg
    }
}

fn open_sockets(cfg: &UdpBusConfig, name: &str) -> Result<Sockets, PortError> {
    let io = |what: &str| {
        let what = what.to_owned();
        move |e| PortError::io(name, what, e)
    };
    let rx = open_rx(cfg, name)?;
    rx.set_nonblocking(true).map_err(io("non-blocking"))?;
    let (tx, own) = open_tx(cfg, name)?;
    tx.set_nonblocking(true).map_err(io("non-blocking"))?;
    let rx = UdpSocket::from_std(rx).map_err(io("register with tokio"))?;
    let tx = UdpSocket::from_std(tx).map_err(io("register with tokio"))?;
    Ok(Sockets {
        rx: Some(rx),
        tx,
        own,
        dest: SocketAddrV4::new(cfg.group, cfg.port).into(),
    })
}

/// The bus's receive socket: bound to the group, joined on the configured interface.
fn open_rx(cfg: &UdpBusConfig, name: &str) -> Result<std::net::UdpSocket, PortError> {
    let io = |what: &str| {
        let what = what.to_owned();
        move |e| PortError::io(name, what, e)
    };
    let rx = Socket::new(Domain::IPV4, Type::DGRAM, Some(Protocol::UDP)).map_err(io("socket"))?;
    rx.set_reuse_address(true).map_err(io("SO_REUSEADDR"))?;
    rx.set_reuse_port(true).map_err(io("SO_REUSEPORT"))?;
    // Bound to the group, not the wildcard: only this bus's datagrams arrive here.
    rx.bind(&SocketAddrV4::new(cfg.group, cfg.port).into())
        .map_err(io("bind to the group address"))?;
    rx.join_multicast_v4(&cfg.group, &cfg.interface).map_err(|e| {
        PortError::io(
            name,
            format!(
                "join group on {} (inside a fresh network namespace run `ip link set lo up; ip route add 224.0.0.0/4 dev lo`)",
                cfg.interface
            ),
            e,
        )
    })?;
    if let Err(e) = rx::Stamps::enable(&rx) {
        // Frames then come without stamps: the device takes them as handed over.
        tracing::warn!(port = %name, error = %e, "no receive timestamps (SO_TIMESTAMPNS)");
    }
    Ok(rx.into())
}

/// A send socket for the bus, with its address (datagrams from it come back through multicast
/// loopback: the receiver drops them as its own).
fn open_tx(cfg: &UdpBusConfig, name: &str) -> Result<(std::net::UdpSocket, SocketAddr), PortError> {
    let io = |what: &str| {
        let what = what.to_owned();
        move |e| PortError::io(name, what, e)
    };
    let tx = Socket::new(Domain::IPV4, Type::DGRAM, Some(Protocol::UDP)).map_err(io("socket"))?;
    tx.set_multicast_if_v4(&cfg.interface)
        .map_err(io("IP_MULTICAST_IF"))?;
    tx.set_multicast_ttl_v4(cfg.ttl)
        .map_err(io("IP_MULTICAST_TTL"))?;
    tx.set_multicast_loop_v4(true)
        .map_err(io("IP_MULTICAST_LOOP"))?;
    tx.bind(&SocketAddrV4::new(cfg.interface, 0).into())
        .map_err(io("bind the send socket"))?;
    let own = tx
        .local_addr()
        .ok()
        .and_then(|a| a.as_socket())
        .ok_or_else(|| PortError::new(name, PortErrorKind::Io, "send socket has no address"))?;
    Ok((tx.into(), own))
}

/// python-can's timestamp: seconds since the Unix epoch.
fn timestamp() -> f64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map(|d| d.as_secs_f64())
        .unwrap_or(0.0)
}

impl UdpPort {
    /// Decodes the datagram in the buffer, received from `from` at `at`: a frame, or `None`
    /// (our own, or refused and counted).
    fn accept(&mut self, (n, from, at, dropped): rx::Datagram) -> Option<PortInput> {
        if let Some(d) = dropped {
            self.counters.rx_overrun_total(d);
        }
        if self.sockets.as_ref().is_some_and(|s| Some(s.own) == from) {
            return None;
        }
        match decode(self.buf.get(..n)?) {
            Ok((f, _)) => {
                self.counters.rx_frames();
                Some(PortInput::Frame(f, at))
            }
            Err(e) => {
                self.refused(from, n, &e);
                None
            }
        }
    }

    /// [`accept`](Self::accept) for [`Port::recv_any`]: CAN FD frames too, on a bus opened
    /// for them.
    fn accept_any(&mut self, d: rx::Datagram) -> Option<AnyInput> {
        if !self.cfg.fd {
            return self.accept(d).map(AnyInput::from);
        }
        let (n, from, at, dropped) = d;
        if let Some(d) = dropped {
            self.counters.rx_overrun_total(d);
        }
        if self.sockets.as_ref().is_some_and(|s| Some(s.own) == from) {
            return None;
        }
        match decode_any(self.buf.get(..n)?) {
            Ok((got, _)) => {
                self.counters.rx_frames();
                Some(match got {
                    UdpFrame::Frame(f) => AnyInput::Frame(f, at),
                    UdpFrame::Fd(f) => AnyInput::Fd(f, at),
                })
            }
            Err(e) => {
                self.refused(from, n, &e);
                None
            }
        }
    }

    fn refused(&self, from: Option<SocketAddr>, n: usize, e: &DecodeError) {
        self.counters.rx_invalid();
        tracing::warn!(port = %self.name, ?from, len = n, error = %e, "datagram refused");
    }

    /// Reads until a datagram `accept` takes.
    async fn read<R>(
        &mut self,
        accept: fn(&mut Self, rx::Datagram) -> Option<R>,
    ) -> Result<R, PortError> {
        loop {
            let Some(s) = self.sockets.as_ref() else {
                return Err(PortError::new(&self.name, PortErrorKind::Closed, "closed"));
            };
            // A reader thread reads the port: nothing comes here until it is re-opened.
            let Some(rx) = s.rx.as_ref() else {
                return std::future::pending().await;
            };
            let (stamps, buf) = (&mut self.stamps, &mut self.buf);
            let got = rx
                .async_io(Interest::READABLE, || stamps.recv(rx, buf))
                .await;
            match got {
                Ok(d) => {
                    if let Some(x) = accept(self, d) {
                        return Ok(x);
                    }
                }
                Err(e) => return Err(self.failed(e)),
            }
        }
    }

    async fn send_bytes(&mut self, bytes: &[u8]) -> Result<(), PortError> {
        let Some(s) = self.sockets.as_ref() else {
            self.counters.tx_dropped();
            return Err(PortError::new(&self.name, PortErrorKind::Closed, "closed"));
        };
        match s.tx.send_to(bytes, s.dest).await {
            Ok(_) => {
                self.counters.tx_frames();
                Ok(())
            }
            Err(e) => {
                self.counters.tx_failed();
                Err(PortError::io(&self.name, "send failed", e))
            }
        }
    }

    fn failed(&mut self, e: std::io::Error) -> PortError {
        self.sockets = None;
        PortError::io(&self.name, "receive failed", e)
    }
}

impl Port for UdpPort {
    fn name(&self) -> &str {
        &self.name
    }

    fn counters(&self) -> PortCounters {
        self.counters.clone()
    }

    async fn recv(&mut self) -> Result<PortInput, PortError> {
        self.read(Self::accept).await
    }

    async fn recv_any(&mut self) -> Result<AnyInput, PortError> {
        self.read(Self::accept_any).await
    }

    fn try_recv(&mut self) -> Option<Result<PortInput, PortError>> {
        loop {
            let rx = self.sockets.as_ref()?.rx.as_ref()?;
            let (stamps, buf) = (&mut self.stamps, &mut self.buf);
            match rx.try_io(Interest::READABLE, || stamps.recv(rx, buf)) {
                Ok(d) => {
                    if let Some(x) = self.accept(d) {
                        return Some(Ok(x));
                    }
                }
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => return None,
                Err(e) => return Some(Err(self.failed(e))),
            }
        }
    }

    async fn send(&mut self, frame: &Frame) -> Result<(), PortError> {
        let bytes = encode(frame, timestamp(), self.cfg.channel.as_deref());
        self.send_bytes(&bytes).await
    }

    async fn send_fd(&mut self, frame: &FdFrame) -> Result<(), PortError> {
        if !self.cfg.fd {
            return Err(super::asynch::classic_port(&self.name, frame));
        }
        let bytes = encode_fd(frame, timestamp(), self.cfg.channel.as_deref());
        self.send_bytes(&bytes).await
    }

    async fn reopen(&mut self) -> Result<(), PortError> {
        self.sockets = None;
        // A new socket: no read has found it empty yet.
        self.stamps = rx::Stamps::new();
        self.sockets = Some(open_sockets(&self.cfg, &self.name)?);
        self.counters.reopened();
        Ok(())
    }

    /// The group's datagrams read by a thread of its own, which answers on a send socket of
    /// its own (see `blocking.rs`); `send` goes on without waiting on the port's.
    fn reader(&mut self) -> Option<Box<dyn PortReader>> {
        let s = self.sockets.as_mut()?;
        let rx = match s.rx.take()?.into_std() {
            Ok(rx) => rx,
            Err(e) => {
                // The socket is gone with the error: closed, the port's next `recv` fails and
                // the runtime re-opens it.
                tracing::warn!(port = %self.name, error = %e, "cannot take the receive socket out of tokio");
                self.sockets = None;
                return None;
            }
        };
        let started = blocking::Reader::new(
            &self.cfg,
            &self.name,
            rx,
            s.own,
            s.dest,
            self.counters.clone(),
            self.stamps.clone(),
        );
        match started {
            Ok(r) => Some(Box::new(r)),
            Err((rx, e)) => {
                tracing::warn!(port = %self.name, error = %e, "cannot read by blocking, reading through readiness");
                s.rx = blocking::back_to_async(rx).ok();
                None
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn config_refuses_non_loopback_and_non_multicast() {
        let c = UdpBusConfig::new(Ipv4Addr::new(10, 0, 0, 1), 1);
        assert_eq!(c.validate().unwrap_err().kind, PortErrorKind::Config);
        let mut c = UdpBusConfig::python_can_default();
        c.interface = Ipv4Addr::new(192, 168, 1, 2);
        let e = c.validate().unwrap_err();
        assert!(e.to_string().contains("on_interface"), "{e}");
        let c = UdpBusConfig::python_can_default().on_interface(Ipv4Addr::new(192, 168, 1, 2));
        assert!(c.validate().is_ok());
        let mut c = UdpBusConfig::python_can_default();
        c.ttl = 4;
        assert!(c.validate().is_err());
        assert_eq!(UdpBusConfig::numbered(1).name(), "239.74.163.3:43114");
    }

    /// A port without sockets: `accept` decodes and counts as on a live bus.
    fn offline_port() -> UdpPort {
        let cfg = UdpBusConfig::numbered(0);
        UdpPort {
            name: cfg.name(),
            cfg,
            sockets: None,
            counters: PortCounters::new(),
            buf: vec![0; MAX_DATAGRAM],
            stamps: rx::Stamps::new(),
        }
    }

    fn feed(port: &mut UdpPort, datagram: &[u8]) -> Option<PortInput> {
        port.buf[..datagram.len()].copy_from_slice(datagram);
        port.accept((datagram.len(), "127.0.0.1:9".parse().ok(), None, None))
    }

    /// The datagram that overflowed the stack of a debug build (`cargo test` is one): a full
    /// receive buffer of nested one-element arrays. It is counted as invalid, nothing panics,
    /// and the next good datagram still arrives.
    #[test]
    fn deeply_nested_datagram_is_counted_as_invalid() {
        let mut port = offline_port();
        let mut nested = vec![0x91; MAX_DATAGRAM - 1];
        nested.push(0x00);
        assert_eq!(feed(&mut port, &nested), None);
        // The same inside a map value, where a frame's `data` array may stand.
        let mut in_map = vec![0x81, 0xa4, b'd', b'a', b't', b'a'];
        in_map.extend(std::iter::repeat_n(0x91, 500));
        in_map.push(0x00);
        assert_eq!(feed(&mut port, &in_map), None);
        let good = Frame::from_array(crate::frame::Id::Standard(0x181), [1, 2]);
        let mut trailing = encode(&good, 0.0, None);
        trailing.push(0xc0);
        assert_eq!(feed(&mut port, &trailing), None);
        assert_eq!(port.counters.snapshot().rx_invalid, 3);
        assert_eq!(
            feed(&mut port, &encode(&good, 0.0, None)),
            Some(PortInput::Frame(good, None))
        );
        assert_eq!(port.counters.snapshot().rx_frames, 1);
    }
}

#[cfg(test)]
mod fd_tests {
    use super::*;
    use crate::frame::Id;

    fn offline(cfg: UdpBusConfig) -> UdpPort {
        UdpPort {
            name: cfg.name(),
            cfg,
            sockets: None,
            counters: PortCounters::new(),
            buf: vec![0; MAX_DATAGRAM],
            stamps: rx::Stamps::new(),
        }
    }

    fn feed(port: &mut UdpPort, datagram: &[u8]) -> Option<AnyInput> {
        port.buf[..datagram.len()].copy_from_slice(datagram);
        port.accept_any((datagram.len(), "127.0.0.1:9".parse().ok(), None, None))
    }

    #[test]
    fn an_fd_port_hands_fd_frames_over_and_a_classic_one_counts_them() {
        let f = FdFrame::new(Id::Extended(0x001A_BCDE), &[0xA5; 64])
            .unwrap()
            .with_esi(true);
        let classic = Frame::from_array(Id::Standard(0x181), [1, 2]);
        let mut fd_port = offline(UdpBusConfig::numbered(0).with_fd());
        assert_eq!(
            feed(&mut fd_port, &encode_fd(&f, 0.0, None)),
            Some(AnyInput::Fd(f, None))
        );
        assert_eq!(
            feed(&mut fd_port, &encode(&classic, 0.0, None)),
            Some(AnyInput::Frame(classic, None))
        );
        // `recv`'s decoding stays classic.
        fd_port.buf[..0].copy_from_slice(&[]);
        let d = encode_fd(&f, 0.0, None);
        fd_port.buf[..d.len()].copy_from_slice(&d);
        assert_eq!(fd_port.accept((d.len(), None, None, None)), None);
        assert_eq!(fd_port.counters.snapshot().rx_frames, 2);
        assert_eq!(fd_port.counters.snapshot().rx_invalid, 1);

        let mut classic_port = offline(UdpBusConfig::numbered(0));
        assert_eq!(feed(&mut classic_port, &encode_fd(&f, 0.0, None)), None);
        assert_eq!(classic_port.counters.snapshot().rx_invalid, 1);
    }

    #[tokio::test]
    async fn a_classic_udp_port_refuses_to_send_fd() {
        let mut port = offline(UdpBusConfig::numbered(0));
        let f = FdFrame::new(Id::Standard(1), &[1; 12]).unwrap();
        let e = port.send_fd(&f).await.unwrap_err();
        assert_eq!(e.kind, PortErrorKind::Config);
        assert!(e.to_string().contains("classic CAN port"), "{e}");
    }
}
