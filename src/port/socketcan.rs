//! Linux SocketCAN ports (`can0`, `vcan0`, …) on the `socketcan` crate's raw socket.
//!
//! The socket is registered with tokio directly, with interest in socket errors as well as
//! readiness: when an interface goes down the kernel reports ENETDOWN as a socket error
//! (EPOLLERR), which a plain readable-interest wait (as in `socketcan::tokio`) never wakes for,
//! so a port on a downed interface that only listens would never notice.
//!
//! Error frames are enabled and decoded into [`PortStatus`](crate::PortStatus) (bus-off, error passive, no-ack, …).
//! Opening checks the interface first, so a missing or down interface gives an error that says
//! so and how to fix it, instead of a bare errno. After a failure the runtime calls
//! [`Port::reopen`], which waits for nothing: it checks the interface and opens a new socket, or
//! fails again (the runtime retries with backoff).
//!
//! Frame conversions between [`Frame`] and the socketcan crate's frame types live here too:
//! lossless both ways for classic data and remote frames; error and FD frames are refused with
//! [`FrameError::NotClassic`].

use super::error_frame::{self, ErrorStatuses};
use super::{Port, PortCounters, PortError, PortErrorKind, PortInput};
use crate::frame::{Frame, FrameError, Id};
use socketcan::{
    CanAnyFrame, CanDataFrame, CanErrorFrame, CanFrame, CanRemoteFrame, EmbeddedFrame, Socket,
    SocketOptions,
};
use std::io;
use tokio::io::unix::AsyncFd;
use tokio::io::Interest;

/// A non-blocking raw CAN socket registered with tokio, woken by errors too.
#[derive(Debug)]
struct TokioCanSocket(AsyncFd<socketcan::CanSocket>);

impl TokioCanSocket {
    fn open(ifname: &str) -> io::Result<Self> {
        let s = socketcan::CanSocket::open(ifname)?;
        s.set_nonblocking(true)?;
        // `AsyncFd::new` is deprecated for types that may not own their descriptor; `CanSocket`
        // owns it (closes it on drop) and the AsyncFd owns the socket, so this use is sound.
        #[allow(deprecated)]
        let fd = AsyncFd::new(s)?;
        Ok(TokioCanSocket(fd))
    }
    fn set_error_filter_accept_all(&self) -> io::Result<()> {
        self.0.get_ref().set_error_filter_accept_all()
    }
    async fn read_frame(&self) -> io::Result<CanFrame> {
        self.0
            .async_io(Interest::READABLE | Interest::ERROR, |s| s.read_frame())
            .await
    }
    /// A frame if one is queued, through tokio's readiness: `WouldBlock` without a system call
    /// when the last read found the socket empty and nothing arrived since, and a read that
    /// finds it empty clears the readiness (a direct read would leave it set, and the next
    /// wait would begin with one more read that finds nothing).
    fn try_read_frame(&self) -> io::Result<CanFrame> {
        self.0.try_io(Interest::READABLE, |s| s.read_frame())
    }
    async fn write_frame(&self, f: CanFrame) -> io::Result<()> {
        self.0
            .async_io(Interest::WRITABLE | Interest::ERROR, |s| s.write_frame(&f))
            .await
    }
}

fn id_of(id: socketcan::Id) -> Id {
    Id::from(id)
}

impl TryFrom<&CanDataFrame> for Frame {
    type Error = FrameError;
    fn try_from(f: &CanDataFrame) -> Result<Frame, FrameError> {
        Frame::new(id_of(EmbeddedFrame::id(f)), EmbeddedFrame::data(f))
    }
}

impl TryFrom<&CanRemoteFrame> for Frame {
    type Error = FrameError;
    fn try_from(f: &CanRemoteFrame) -> Result<Frame, FrameError> {
        let dlc = u8::try_from(EmbeddedFrame::dlc(f)).map_err(|_| FrameError::TooLong {
            len: EmbeddedFrame::dlc(f),
        })?;
        Frame::remote(id_of(EmbeddedFrame::id(f)), dlc)
    }
}

impl TryFrom<&CanFrame> for Frame {
    type Error = FrameError;
    fn try_from(f: &CanFrame) -> Result<Frame, FrameError> {
        match f {
            CanFrame::Data(d) => Frame::try_from(d),
            CanFrame::Remote(r) => Frame::try_from(r),
            CanFrame::Error(_) => Err(FrameError::NotClassic),
        }
    }
}

impl TryFrom<CanFrame> for Frame {
    type Error = FrameError;
    fn try_from(f: CanFrame) -> Result<Frame, FrameError> {
        Frame::try_from(&f)
    }
}

impl TryFrom<CanAnyFrame> for Frame {
    type Error = FrameError;
    fn try_from(f: CanAnyFrame) -> Result<Frame, FrameError> {
        match f {
            CanAnyFrame::Normal(d) => Frame::try_from(&d),
            CanAnyFrame::Remote(r) => Frame::try_from(&r),
            CanAnyFrame::Error(_) | CanAnyFrame::Fd(_) => Err(FrameError::NotClassic),
        }
    }
}

impl From<&Frame> for CanFrame {
    fn from(f: &Frame) -> CanFrame {
        // `Frame` guarantees an in-range identifier and DLC ≤ 8, which is all the socketcan
        // constructors check; the fallbacks are unreachable but keep this total.
        let id: socketcan::Id = f.id().into();
        if f.is_remote() {
            CanRemoteFrame::new_remote(id, f.dlc() as usize)
                .map(CanFrame::Remote)
                .unwrap_or_default()
        } else {
            CanDataFrame::new(id, f.data())
                .map(CanFrame::Data)
                .unwrap_or_default()
        }
    }
}

impl From<Frame> for CanFrame {
    fn from(f: Frame) -> CanFrame {
        CanFrame::from(&f)
    }
}

impl From<Frame> for CanAnyFrame {
    fn from(f: Frame) -> CanAnyFrame {
        CanAnyFrame::from(CanFrame::from(&f))
    }
}

/// Decodes a SocketCAN error frame into the statuses it reports.
pub fn decode_error_frame(f: &CanErrorFrame) -> ErrorStatuses {
    error_frame::decode(f.error_bits(), EmbeddedFrame::data(f))
}

const IFF_UP: u32 = 0x1;

/// Link state of a network interface as sysfs shows it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LinkState {
    /// No such interface.
    Missing,
    /// Present, administratively down.
    Down,
    /// Present and up.
    Up,
}

/// Reads `/sys/class/net/IFNAME/flags`. Names that are not interface names are `Missing`.
pub fn link_state(ifname: &str) -> LinkState {
    let valid = !ifname.is_empty()
        && ifname.len() < 16
        && !ifname.contains('/')
        && ifname != "."
        && ifname != "..";
    if !valid {
        return LinkState::Missing;
    }
    match std::fs::read_to_string(format!("/sys/class/net/{ifname}/flags")) {
        Ok(s) => {
            let flags = u32::from_str_radix(s.trim().trim_start_matches("0x"), 16).unwrap_or(0);
            if flags & IFF_UP != 0 {
                LinkState::Up
            } else {
                LinkState::Down
            }
        }
        Err(_) => LinkState::Missing,
    }
}

/// A SocketCAN port on one interface.
#[derive(Debug)]
pub struct SocketCanPort {
    ifname: String,
    socket: Option<TokioCanSocket>,
    pending: ErrorStatuses,
    counters: PortCounters,
}

impl SocketCanPort {
    /// Opens `ifname` with error frames enabled. Must be called inside a tokio runtime.
    ///
    /// Fails with [`PortErrorKind::NoSuchInterface`] or [`PortErrorKind::InterfaceDown`] (and a
    /// hint how to create or raise it) before touching any socket.
    pub fn open(ifname: &str) -> Result<Self, PortError> {
        let socket = open_socket(ifname)?;
        Ok(SocketCanPort {
            ifname: ifname.to_owned(),
            socket: Some(socket),
            pending: ErrorStatuses::new(),
            counters: PortCounters::new(),
        })
    }

    /// The interface name.
    pub fn ifname(&self) -> &str {
        &self.ifname
    }

    fn closed(&self) -> PortError {
        PortError::new(
            &self.ifname,
            PortErrorKind::Closed,
            "socket closed after a failure; re-open the port",
        )
    }
}

fn open_socket(ifname: &str) -> Result<TokioCanSocket, PortError> {
    match link_state(ifname) {
        LinkState::Missing => {
            return Err(PortError::new(
                ifname,
                PortErrorKind::NoSuchInterface,
                format!(
                    "no network interface {ifname:?}; create it (for a virtual bus: `ip link add dev {ifname} type vcan && ip link set {ifname} up`)"
                ),
            ))
        }
        LinkState::Down => {
            return Err(PortError::new(
                ifname,
                PortErrorKind::InterfaceDown,
                format!("interface {ifname} is down; raise it with `ip link set {ifname} up`"),
            ))
        }
        LinkState::Up => {}
    }
    let socket = TokioCanSocket::open(ifname).map_err(|e| {
        let hint = if e.raw_os_error() == Some(97) {
            "cannot open a CAN socket: this kernel has no SocketCAN (AF_CAN) support"
        } else {
            "cannot open a CAN socket"
        };
        PortError::io(ifname, hint, e)
    })?;
    socket
        .set_error_filter_accept_all()
        .map_err(|e| PortError::io(ifname, "cannot enable error frames", e))?;
    Ok(socket)
}

impl SocketCanPort {
    /// Classifies a received frame: a frame to hand on, or `None` (error frame queued as status,
    /// invalid frame counted).
    fn accept(&mut self, raw: &CanFrame) -> Option<PortInput> {
        match raw {
            CanFrame::Error(ef) => {
                self.counters.rx_error_frames();
                self.pending = decode_error_frame(ef);
                tracing::debug!(port = %self.ifname, bits = ef.error_bits(), "error frame");
                None
            }
            other => match Frame::try_from(other) {
                Ok(f) => {
                    self.counters.rx_frames();
                    Some(PortInput::Frame(f))
                }
                Err(e) => {
                    self.counters.rx_invalid();
                    tracing::warn!(port = %self.ifname, error = %e, "frame refused");
                    None
                }
            },
        }
    }

    fn read_failed(&mut self, e: io::Error) -> PortError {
        self.socket = None;
        PortError::io(&self.ifname, "read failed", e)
    }
}

impl Port for SocketCanPort {
    fn name(&self) -> &str {
        &self.ifname
    }

    fn counters(&self) -> PortCounters {
        self.counters.clone()
    }

    async fn recv(&mut self) -> Result<PortInput, PortError> {
        loop {
            if !self.pending.is_empty() {
                return Ok(PortInput::Status(self.pending.remove(0)));
            }
            let Some(sock) = self.socket.as_ref() else {
                return Err(self.closed());
            };
            match sock.read_frame().await {
                Ok(raw) => {
                    if let Some(x) = self.accept(&raw) {
                        return Ok(x);
                    }
                }
                Err(e) => return Err(self.read_failed(e)),
            }
        }
    }

    fn try_recv(&mut self) -> Option<Result<PortInput, PortError>> {
        loop {
            if !self.pending.is_empty() {
                return Some(Ok(PortInput::Status(self.pending.remove(0))));
            }
            match self.socket.as_ref()?.try_read_frame() {
                Ok(raw) => {
                    if let Some(x) = self.accept(&raw) {
                        return Some(Ok(x));
                    }
                }
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => return None,
                Err(e) => return Some(Err(self.read_failed(e))),
            }
        }
    }

    async fn send(&mut self, frame: &Frame) -> Result<(), PortError> {
        let Some(sock) = self.socket.as_ref() else {
            self.counters.tx_dropped();
            return Err(self.closed());
        };
        match sock.write_frame(CanFrame::from(frame)).await {
            Ok(()) => {
                self.counters.tx_frames();
                Ok(())
            }
            Err(e) => {
                self.counters.tx_failed();
                let err = PortError::io(&self.ifname, "write failed", e);
                if matches!(
                    err.kind,
                    PortErrorKind::InterfaceDown | PortErrorKind::NoSuchInterface
                ) {
                    self.socket = None;
                }
                Err(err)
            }
        }
    }

    async fn reopen(&mut self) -> Result<(), PortError> {
        self.socket = None;
        self.pending.clear();
        self.socket = Some(open_socket(&self.ifname)?);
        self.counters.reopened();
        Ok(())
    }
}

/// Writes an error frame (`bits` | `CAN_ERR_FLAG`, `data`) on `ifname`: how tests inject
/// controller errors on a vcan interface, which has no controller of its own.
pub fn inject_error_frame(ifname: &str, bits: u32, data: &[u8]) -> io::Result<()> {
    let sock = socketcan::CanSocket::open(ifname)?;
    let ef = CanErrorFrame::new_error(bits, data)
        .map_err(|e| io::Error::new(io::ErrorKind::InvalidInput, e.to_string()))?;
    sock.write_frame(&CanFrame::Error(ef))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn socketcan_round_trip_is_lossless(f in crate::frame::tests::any_frame()) {
            let sc = CanFrame::from(&f);
            prop_assert_eq!(Frame::try_from(&sc).unwrap(), f);
            let any = CanAnyFrame::from(f);
            prop_assert_eq!(Frame::try_from(any).unwrap(), f);
        }
    }

    #[test]
    fn error_frames_are_not_frames() {
        let ef = CanErrorFrame::new_error(0x40, &[0; 8]).unwrap();
        assert_eq!(
            Frame::try_from(CanFrame::Error(ef)),
            Err(FrameError::NotClassic)
        );
        assert_eq!(
            decode_error_frame(&ef).as_slice(),
            &[crate::machine::PortStatus::Down(
                crate::machine::ErrorCause::BusOff
            )]
        );
    }

    #[test]
    fn missing_interface_is_a_clear_error() {
        assert_eq!(link_state("duocan-nope0"), LinkState::Missing);
        assert_eq!(link_state("../etc"), LinkState::Missing);
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .unwrap();
        let err = rt
            .block_on(async { SocketCanPort::open("duocan-nope0") })
            .unwrap_err();
        assert_eq!(err.kind, PortErrorKind::NoSuchInterface);
        assert!(err
            .to_string()
            .contains("ip link add dev duocan-nope0 type vcan"));
    }
}
