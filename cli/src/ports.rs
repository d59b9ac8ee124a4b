//! A port by its name on the command line: python-can's UDP bus (`udp`, `udp:N`,
//! `udp:GROUP:PORT`) or a SocketCAN interface (anything else), as one type, so that a command
//! can open a list of interfaces whatever their kinds (the failover kit's members, a device's
//! two buses).

use crate::args::{parse_udp, UdpSpec};
use crate::fail::Fail;
use duocan::port::socketcan::SocketCanPort;
use duocan::port::udp::{UdpBusConfig, UdpPort};
use duocan::port::{AnyInput, Port, PortCounters, PortError, PortInput};
use duocan::{FdFrame, Frame};

/// One interface, opened by name.
pub enum NamedPort {
    /// python-can's UDP bus.
    Udp(UdpPort),
    /// A SocketCAN interface.
    Can(SocketCanPort),
}

/// Opens the interface `name`; the UDP bus on loopback unless `udp_interface` says otherwise.
pub fn open(name: &str, udp_interface: Option<std::net::Ipv4Addr>) -> Result<NamedPort, Fail> {
    open_fd(name, udp_interface, false)
}

/// [`open`], for CAN FD frames too when `fd` (SocketCAN: `open_fd`, which checks the
/// interface's MTU; the UDP bus: python-can's `fd=True`).
pub fn open_fd(
    name: &str,
    udp_interface: Option<std::net::Ipv4Addr>,
    fd: bool,
) -> Result<NamedPort, Fail> {
    match parse_udp(name) {
        Some(spec) => {
            let mut cfg = match spec.map_err(Fail::usage)? {
                UdpSpec::Default => UdpBusConfig::python_can_default(),
                UdpSpec::Numbered(n) => UdpBusConfig::numbered(n),
                UdpSpec::Group(group, port) => UdpBusConfig::new(group, port),
            };
            if let Some(addr) = udp_interface {
                cfg = cfg.on_interface(addr);
            }
            if fd {
                cfg = cfg.with_fd();
            }
            UdpPort::open(cfg)
                .map(NamedPort::Udp)
                .map_err(|e| Fail::bus(e.to_string()))
        }
        None if fd => SocketCanPort::open_fd(name)
            .map(NamedPort::Can)
            .map_err(|e| Fail::bus(e.to_string())),
        None => SocketCanPort::open(name)
            .map(NamedPort::Can)
            .map_err(|e| Fail::bus(e.to_string())),
    }
}

impl Port for NamedPort {
    fn name(&self) -> &str {
        match self {
            NamedPort::Udp(p) => p.name(),
            NamedPort::Can(p) => p.name(),
        }
    }
    fn counters(&self) -> PortCounters {
        match self {
            NamedPort::Udp(p) => p.counters(),
            NamedPort::Can(p) => p.counters(),
        }
    }
    async fn recv(&mut self) -> Result<PortInput, PortError> {
        match self {
            NamedPort::Udp(p) => p.recv().await,
            NamedPort::Can(p) => p.recv().await,
        }
    }
    fn try_recv(&mut self) -> Option<Result<PortInput, PortError>> {
        match self {
            NamedPort::Udp(p) => p.try_recv(),
            NamedPort::Can(p) => p.try_recv(),
        }
    }
    async fn send(&mut self, frame: &Frame) -> Result<(), PortError> {
        match self {
            NamedPort::Udp(p) => p.send(frame).await,
            NamedPort::Can(p) => p.send(frame).await,
        }
    }
    async fn recv_any(&mut self) -> Result<AnyInput, PortError> {
        match self {
            NamedPort::Udp(p) => p.recv_any().await,
            NamedPort::Can(p) => p.recv_any().await,
        }
    }
    async fn send_fd(&mut self, frame: &FdFrame) -> Result<(), PortError> {
        match self {
            NamedPort::Udp(p) => p.send_fd(frame).await,
            NamedPort::Can(p) => p.send_fd(frame).await,
        }
    }
    async fn reopen(&mut self) -> Result<(), PortError> {
        match self {
            NamedPort::Udp(p) => p.reopen().await,
            NamedPort::Can(p) => p.reopen().await,
        }
    }
}
