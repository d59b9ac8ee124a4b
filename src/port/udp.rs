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
//! Datagrams that are not classic CAN frames (garbage, truncated, CAN FD, error frames) are
//! counted in [`PortCounters::rx_invalid`](super::PortCounters) and logged; frames this port
//! sent itself come back through multicast loopback and are dropped silently.

use super::{Port, PortCounters, PortError, PortErrorKind, PortInput};
use crate::frame::{Frame, Id};
use rmpv::Value;
use socket2::{Domain, Protocol, Socket, Type};
use std::fmt;
use std::net::{Ipv4Addr, SocketAddr, SocketAddrV4};
use std::time::{SystemTime, UNIX_EPOCH};
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

/// Why a datagram is not a classic CAN frame.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum DecodeError {
    /// Not msgpack, or truncated.
    NotMsgpack,
    /// Msgpack, but not a map.
    NotAMap,
    /// A required key is missing or has the wrong type.
    Field(&'static str),
    /// An error frame (python-can `is_error_frame`).
    ErrorFrame,
    /// A CAN FD frame.
    Fd,
    /// Identifier, DLC or data out of range for classic CAN.
    Invalid(crate::frame::FrameError),
}

impl fmt::Display for DecodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DecodeError::NotMsgpack => f.write_str("not a msgpack value (garbage or truncated)"),
            DecodeError::NotAMap => f.write_str("msgpack value is not a map"),
            DecodeError::Field(k) => write!(f, "key {k:?} missing or of the wrong type"),
            DecodeError::ErrorFrame => f.write_str("error frame"),
            DecodeError::Fd => f.write_str("CAN FD frame on a classic CAN bus"),
            DecodeError::Invalid(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for DecodeError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            DecodeError::Invalid(e) => Some(e),
            _ => None,
        }
    }
}

/// Encodes a frame as python-can's `pack_message` does (same keys, same order, same types).
pub fn encode(frame: &Frame, timestamp: f64, channel: Option<&str>) -> Vec<u8> {
    let (raw, ext) = match frame.id() {
        Id::Standard(r) => (r as u32, false),
        Id::Extended(r) => (r, true),
    };
    let map = Value::Map(vec![
        (Value::from("timestamp"), Value::F64(timestamp)),
        (Value::from("arbitration_id"), Value::from(raw)),
        (Value::from("is_extended_id"), Value::Boolean(ext)),
        (
            Value::from("is_remote_frame"),
            Value::Boolean(frame.is_remote()),
        ),
        (Value::from("is_error_frame"), Value::Boolean(false)),
        (
            Value::from("channel"),
            channel.map(Value::from).unwrap_or(Value::Nil),
        ),
        (Value::from("dlc"), Value::from(frame.dlc())),
        (Value::from("data"), Value::Binary(frame.data().to_vec())),
        (Value::from("is_fd"), Value::Boolean(false)),
        (Value::from("bitrate_switch"), Value::Boolean(false)),
        (Value::from("error_state_indicator"), Value::Boolean(false)),
    ]);
    let mut buf = Vec::with_capacity(160);
    // Writing into a Vec cannot fail.
    let _ = rmpv::encode::write_value(&mut buf, &map);
    buf
}

/// Decodes a datagram into a classic frame and its timestamp (0.0 if absent or not a number).
pub fn decode(datagram: &[u8]) -> Result<(Frame, f64), DecodeError> {
    let mut rd = datagram;
    let v = rmpv::decode::read_value(&mut rd).map_err(|_| DecodeError::NotMsgpack)?;
    let Value::Map(entries) = v else {
        return Err(DecodeError::NotAMap);
    };
    let get = |k: &str| {
        entries
            .iter()
            .find(|(key, _)| key.as_str() == Some(k))
            .map(|(_, v)| v)
    };
    let flag = |k: &'static str, default: bool| match get(k) {
        None | Some(Value::Nil) => Ok(default),
        Some(Value::Boolean(b)) => Ok(*b),
        Some(_) => Err(DecodeError::Field(k)),
    };
    if flag("is_error_frame", false)? {
        return Err(DecodeError::ErrorFrame);
    }
    if flag("is_fd", false)? {
        return Err(DecodeError::Fd);
    }
    let raw = get("arbitration_id")
        .and_then(Value::as_u64)
        .ok_or(DecodeError::Field("arbitration_id"))?;
    let raw = u32::try_from(raw).map_err(|_| DecodeError::Field("arbitration_id"))?;
    let ext = flag("is_extended_id", raw > crate::frame::STANDARD_ID_MAX as u32)?;
    let id = if ext {
        Id::extended(raw)
    } else {
        u16::try_from(raw).ok().and_then(Id::standard)
    }
    .ok_or(DecodeError::Invalid(crate::frame::FrameError::BadId {
        raw,
    }))?;
    let dlc = get("dlc")
        .and_then(Value::as_u64)
        .ok_or(DecodeError::Field("dlc"))?;
    let timestamp = get("timestamp").and_then(Value::as_f64).unwrap_or(0.0);
    if flag("is_remote_frame", false)? {
        let dlc = u8::try_from(dlc)
            .map_err(|_| DecodeError::Invalid(crate::frame::FrameError::TooLong { len: 255 }))?;
        let f = Frame::remote(id, dlc).map_err(DecodeError::Invalid)?;
        return Ok((f, timestamp));
    }
    let mut bytes = [0u8; 8];
    let data: &[u8] = match get("data") {
        Some(Value::Binary(b)) => b,
        Some(Value::Array(items)) => {
            // A peer that packed a list of ints (msgpack without use_bin_type).
            if items.len() > 8 {
                return Err(DecodeError::Invalid(crate::frame::FrameError::TooLong {
                    len: items.len(),
                }));
            }
            for (slot, it) in bytes.iter_mut().zip(items) {
                *slot = it
                    .as_u64()
                    .and_then(|b| u8::try_from(b).ok())
                    .ok_or(DecodeError::Field("data"))?;
            }
            &bytes[..items.len()]
        }
        Some(Value::Nil) | None if dlc == 0 => &[],
        _ => return Err(DecodeError::Field("data")),
    };
    if dlc != data.len() as u64 {
        return Err(DecodeError::Field("dlc"));
    }
    let f = Frame::new(id, data).map_err(DecodeError::Invalid)?;
    Ok((f, timestamp))
}

/// One UDP multicast bus.
#[derive(Debug)]
pub struct UdpPort {
    cfg: UdpBusConfig,
    name: String,
    sockets: Option<Sockets>,
    counters: PortCounters,
    buf: Vec<u8>,
}

#[derive(Debug)]
struct Sockets {
    rx: UdpSocket,
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
        let sockets = open_sockets(&cfg, &name)?;
        Ok(UdpPort {
            cfg,
            name,
            sockets: Some(sockets),
            counters: PortCounters::new(),
            buf: vec![0; MAX_DATAGRAM],
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
    rx.set_nonblocking(true).map_err(io("non-blocking"))?;

    let tx = Socket::new(Domain::IPV4, Type::DGRAM, Some(Protocol::UDP)).map_err(io("socket"))?;
    tx.set_multicast_if_v4(&cfg.interface)
        .map_err(io("IP_MULTICAST_IF"))?;
    tx.set_multicast_ttl_v4(cfg.ttl)
        .map_err(io("IP_MULTICAST_TTL"))?;
    tx.set_multicast_loop_v4(true)
        .map_err(io("IP_MULTICAST_LOOP"))?;
    tx.bind(&SocketAddrV4::new(cfg.interface, 0).into())
        .map_err(io("bind the send socket"))?;
    tx.set_nonblocking(true).map_err(io("non-blocking"))?;
    let own = tx
        .local_addr()
        .ok()
        .and_then(|a| a.as_socket())
        .ok_or_else(|| PortError::new(name, PortErrorKind::Io, "send socket has no address"))?;
    let rx = UdpSocket::from_std(rx.into()).map_err(io("register with tokio"))?;
    let tx = UdpSocket::from_std(tx.into()).map_err(io("register with tokio"))?;
    Ok(Sockets {
        rx,
        tx,
        own,
        dest: SocketAddrV4::new(cfg.group, cfg.port).into(),
    })
}

impl UdpPort {
    /// Decodes the datagram in the buffer: a frame, or `None` (our own, or refused and counted).
    fn accept(&mut self, n: usize, from: SocketAddr) -> Option<PortInput> {
        if self.sockets.as_ref().is_some_and(|s| s.own == from) {
            return None;
        }
        match decode(&self.buf[..n]) {
            Ok((f, _)) => {
                self.counters.rx_frames();
                Some(PortInput::Frame(f))
            }
            Err(e) => {
                self.counters.rx_invalid();
                tracing::warn!(port = %self.name, %from, len = n, error = %e, "datagram refused");
                None
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
        loop {
            let Some(s) = self.sockets.as_ref() else {
                return Err(PortError::new(&self.name, PortErrorKind::Closed, "closed"));
            };
            match s.rx.recv_from(&mut self.buf).await {
                Ok((n, from)) => {
                    if let Some(x) = self.accept(n, from) {
                        return Ok(x);
                    }
                }
                Err(e) => return Err(self.failed(e)),
            }
        }
    }

    fn try_recv(&mut self) -> Option<Result<PortInput, PortError>> {
        loop {
            match self.sockets.as_ref()?.rx.try_recv_from(&mut self.buf) {
                Ok((n, from)) => {
                    if let Some(x) = self.accept(n, from) {
                        return Some(Ok(x));
                    }
                }
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => return None,
                Err(e) => return Some(Err(self.failed(e))),
            }
        }
    }

    async fn send(&mut self, frame: &Frame) -> Result<(), PortError> {
        let Some(s) = self.sockets.as_ref() else {
            self.counters.tx_dropped();
            return Err(PortError::new(&self.name, PortErrorKind::Closed, "closed"));
        };
        let ts = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map(|d| d.as_secs_f64())
            .unwrap_or(0.0);
        let bytes = encode(frame, ts, self.cfg.channel.as_deref());
        match s.tx.send_to(&bytes, s.dest).await {
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

    async fn reopen(&mut self) -> Result<(), PortError> {
        self.sockets = None;
        self.sockets = Some(open_sockets(&self.cfg, &self.name)?);
        self.counters.reopened();
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Bytes python-can 4.6 (`msgpack.packb(..., use_bin_type=True)`) produced for
    /// `Message(timestamp=1.5, arbitration_id=0x601, data=[0x40, 0x18, 0x10, 1, 0, 0, 0, 0])`.
    const PYTHON_SDO_HEX: &str = concat!(
        "8ba974696d657374616d70cb3ff8000000000000ae6172626974726174696f6e5f6964cd0601ae69",
        "735f657874656e6465645f6964c2af69735f72656d6f74655f6672616d65c2ae69735f6572726f72",
        "5f6672616d65c2a76368616e6e656cc0a3646c6308a464617461c4084018100100000000a569735f",
        "6664c2ae626974726174655f737769746368c2b56572726f725f73746174655f696e64696361746f",
        "72c2",
    );

    fn python_sdo() -> Vec<u8> {
        (0..PYTHON_SDO_HEX.len())
            .step_by(2)
            .map(|i| u8::from_str_radix(&PYTHON_SDO_HEX[i..i + 2], 16).unwrap())
            .collect()
    }

    #[test]
    fn encodes_byte_for_byte_like_python_can() {
        let f = Frame::from_array(Id::Standard(0x601), [0x40, 0x18, 0x10, 1, 0, 0, 0, 0]);
        let py = python_sdo();
        assert_eq!(encode(&f, 1.5, None), py);
        assert_eq!(decode(&py).unwrap(), (f, 1.5));
    }

    #[test]
    fn garbage_and_truncation_are_errors() {
        assert_eq!(decode(&[]), Err(DecodeError::NotMsgpack));
        assert!(decode(&[0xc1]).is_err());
        assert_eq!(decode(&[0x93, 1, 2, 3]), Err(DecodeError::NotAMap));
        let py = python_sdo();
        for n in 0..py.len() {
            assert!(decode(&py[..n]).is_err(), "prefix {n} decoded");
        }
        let fd = encode(&Frame::from_array(Id::Standard(1), [1]), 0.0, None);
        let fd: Vec<u8> = replace(&fd, b"is_fd\xc2", b"is_fd\xc3");
        assert_eq!(decode(&fd), Err(DecodeError::Fd));
        let err = replace(
            &encode(&Frame::from_array(Id::Standard(1), [1]), 0.0, None),
            b"is_error_frame\xc2",
            b"is_error_frame\xc3",
        );
        assert_eq!(decode(&err), Err(DecodeError::ErrorFrame));
        let bad_dlc = replace(
            &encode(&Frame::from_array(Id::Standard(1), [1]), 0.0, None),
            b"dlc\x01",
            b"dlc\x05",
        );
        assert_eq!(decode(&bad_dlc), Err(DecodeError::Field("dlc")));
        let bad_id = replace(
            &encode(&Frame::from_array(Id::Standard(0x7FF), [1]), 0.0, None),
            b"\xcd\x07\xff",
            b"\xcd\x08\x00",
        );
        assert!(matches!(decode(&bad_id), Err(DecodeError::Invalid(_))));
    }

    fn replace(hay: &[u8], from: &[u8], to: &[u8]) -> Vec<u8> {
        let i = hay
            .windows(from.len())
            .position(|w| w == from)
            .expect("pattern present");
        let mut v = hay.to_vec();
        v.splice(i..i + from.len(), to.iter().copied());
        v
    }

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

    proptest! {
        #[test]
        fn round_trip(f in crate::frame::tests::any_frame(), ts in 0.0f64..2e9) {
            prop_assert_eq!(decode(&encode(&f, ts, Some("can0"))).unwrap(), (f, ts));
        }

        #[test]
        fn arbitrary_bytes_never_panic(b in proptest::collection::vec(any::<u8>(), 0..300)) {
            let _ = decode(&b);
        }
    }
}
