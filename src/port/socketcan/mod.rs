//! Linux SocketCAN ports (`can0`, `vcan0`, …) on the `socketcan` crate's raw socket.
//!
//! The socket is registered with tokio directly, with interest in socket errors as well as
//! readiness: when an interface goes down the kernel reports ENETDOWN as a socket error
//! (EPOLLERR), which a plain readable-interest wait (as in `socketcan::tokio`) never wakes for,
//! so a port on a downed interface that only listens would never notice.
//!
//! Every frame comes with the kernel's receive timestamp (`SO_TIMESTAMPNS`: when it entered the
//! network stack), put on the monotonic clock (see the [port module](super)).
//!
//! Error frames are enabled and decoded into [`PortStatus`] (bus-off, error passive, no-ack, …).
//! Opening checks the interface first, so a missing or down interface gives an error that says
//! so and how to fix it, instead of a bare errno. After a failure the runtime calls
//! [`Port::reopen`], which waits for nothing: it checks the interface and opens a new socket, or
//! fails again (the runtime retries with backoff).
//!
//! Under the runtime the port reads by blocking, on a thread of its own ([`Port::reader`]), as a
//! bare socket loop does: one `read` per frame, which wakes when the frame arrives, where a
//! readiness wait costs an `epoll_wait` and a `read` that finds the socket empty besides. The
//! runtime's task still sends on it, without waiting (`MSG_DONTWAIT`), what the device sends on
//! a timer or a command.
//!
//! # Confirmed transmissions
//!
//! [`Port::confirm_transmissions`] (the runtime asks for it for a dual-bus device) turns on
//! `CAN_RAW_RECV_OWN_MSGS`: the kernel hands the socket its own frames back, marked
//! `MSG_CONFIRM`, and the port hands each over as a `TxOk` status, never as a received frame.
//! Only where the interface's driver echoes (`IFF_ECHO`): a CAN controller's driver echoes a
//! frame once it was on the bus (acknowledged), which is what the dual-bus layer's stall rule
//! needs; without it the kernel echoes as it hands the frame to the driver, which confirms
//! nothing, and the port says it cannot. Each read then looks at the frame's flags first (a
//! peek: the `nix` crate's message flags leave `MSG_CONFIRM` out), so the reader thread takes
//! one frame per read instead of a batch: two system calls per frame, the cost of knowing.
//!
//! # CAN FD
//!
//! [`SocketCanPort::open_fd`] opens the interface for CAN FD frames (`CAN_RAW_FD_FRAMES`), after
//! checking that its MTU is the CAN FD MTU (72): an interface that carries no CAN FD frames
//! (a vcan or CAN controller left at MTU 16) is an error naming it and saying how to switch it.
//! [`Port::send_fd`] then sends CAN FD frames and [`Port::recv_any`] hands them over with the
//! classic ones; `recv` counts them as invalid. Such a port reads through tokio: the blocking
//! reader ([`Port::reader`]) reads classic frames only, so an FD port does not hand over to it.
//! A port opened with [`SocketCanPort::open`] is classic, as before.
//!
//! Frame conversions between [`Frame`] and the socketcan crate's frame types
//! ([`frame_from_socketcan`], [`socketcan_frame`]; `convert.rs`): lossless both ways for classic
//! data and remote frames; error and FD frames are refused with [`FrameError::NotClassic`].
//! What sysfs tells of an interface ([`link_state`], [`interface_mtu`]) is in `interface.rs`.

mod blocking;
mod convert;
mod interface;
#[cfg(test)]
mod tests;

use convert::{canfd_bytes, fd_from_kernel, CAN_EFF_FLAG, CAN_EFF_MASK, CAN_RTR_FLAG};
pub use convert::{decode_error_frame, frame_from_socketcan, socketcan_frame};
use interface::not_fd;
pub use interface::{inject_error_frame, interface_mtu, link_state, LinkState};

use super::error_frame::{self, ErrorStatuses};
use super::stamp::{self, KernelClock};
use super::{AnyInput, Port, PortCounters, PortError, PortErrorKind, PortInput, PortReader};
use crate::frame::{FdFrame, Frame, FrameError, Id};
use crate::machine::PortStatus;
use nix::errno::Errno;
use nix::sys::socket::{recvmsg, MsgFlags};
use socketcan::{CanFrame, Socket, SocketOptions};
use std::io::{self, IoSliceMut};
use std::os::fd::AsRawFd;
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
        // Readable only: with writable interest too, every frame sent (its buffer freed once
        // the interface took it) would wake the runtime's epoll for nothing. Sends try the
        // socket directly (`write_waiting`).
        #[allow(deprecated)]
        let fd = AsyncFd::with_interest(s, Interest::READABLE)?;
        Ok(TokioCanSocket(fd))
    }
    fn set_error_filter_accept_all(&self) -> io::Result<()> {
        self.0.get_ref().set_error_filter_accept_all()
    }
    /// The next frame as the kernel wrote it, with its length and its receive timestamp.
    async fn read_frame(&self, rx: &mut Received) -> io::Result<()> {
        self.0
            .async_io(Interest::READABLE | Interest::ERROR, |s| rx.recv(s))
            .await
    }
    /// A frame if one is queued, through tokio's readiness: `WouldBlock` without a system call
    /// when the last read found the socket empty and nothing arrived since, and a read that
    /// finds it empty clears the readiness (a direct read would leave it set, and the next
    /// wait would begin with one more read that finds nothing).
    fn try_read_frame(&self, rx: &mut Received) -> io::Result<()> {
        self.0.try_io(Interest::READABLE, |s| rx.recv(s))
    }
    async fn write_frame(&self, f: CanFrame) -> io::Result<()> {
        write_waiting(|| self.0.get_ref().write_frame(&f)).await
    }
}

/// The size of the kernel's `struct can_frame` (`CAN_MTU`).
const CAN_MTU: usize = 16;
/// The size of the kernel's `struct canfd_frame` (`CANFD_MTU`), and the MTU of an interface
/// that carries CAN FD frames.
const CANFD_MTU: usize = 72;
/// `SOL_CAN_RAW` and its option `CAN_RAW_FD_FRAMES` (linux/can/raw.h).
const SOL_CAN_RAW: std::ffi::c_int = 101;
const CAN_RAW_FD_FRAMES: std::ffi::c_int = 5;
/// What the port read last through tokio: the frame as the kernel wrote it, its length, its
/// receive timestamp on the monotonic clock, and what the stamps are converted with.
#[derive(Debug)]
struct Received {
    /// Room for a `canfd_frame`; a classic port reads into the first [`CAN_MTU`] bytes only.
    raw: [u8; CANFD_MTU],
    /// The socket has `CAN_RAW_FD_FRAMES`: frames are read into the whole of `raw`.
    fd: bool,
    len: usize,
    at: Option<std::time::Instant>,
    /// The socket's count of frames dropped on its full queue, as of the last frame read.
    dropped: Option<u32>,
    /// Transmissions are confirmed ([`Port::confirm_transmissions`]): each read looks first
    /// whether the frame is the echo of one the socket sent.
    confirm: bool,
    /// The last frame read is such an echo.
    own: bool,
    control: Vec<u8>,
    clock: KernelClock,
}

impl Received {
    fn new() -> Self {
        Received {
            raw: [0; CANFD_MTU],
            fd: false,
            len: 0,
            at: None,
            dropped: None,
            confirm: false,
            own: false,
            control: stamp::control_space(),
            clock: KernelClock::new(),
        }
    }
    /// Reads one frame from the non-blocking socket `s` (`WouldBlock` when none is queued).
    fn recv(&mut self, s: &socketcan::CanSocket) -> io::Result<()> {
        let room = if self.fd { CANFD_MTU } else { CAN_MTU };
        let mut iov = [IoSliceMut::new(&mut self.raw[..room])];
        let flags = MsgFlags::empty();
        let called = std::time::Instant::now();
        let own = if self.confirm {
            next_is_own(s, MsgFlags::empty())
        } else {
            Ok(false)
        };
        let read = own.map_err(|e| e.raw_os_error().map_or(Errno::EIO, Errno::from_raw));
        match read.and_then(|own| {
            self.own = own;
            recvmsg::<()>(s.as_raw_fd(), &mut iov, Some(&mut self.control), flags)
        }) {
            Ok(m) => {
                let reading = self.clock.read();
                self.len = m.bytes;
                self.at = stamp::of_message(&m).map(|t| reading.convert(t));
                self.dropped = stamp::dropped(&m);
                Ok(())
            }
            Err(Errno::EAGAIN) => {
                // Found empty: what comes next arrived after the call began.
                self.clock.drained(called);
                Err(io::ErrorKind::WouldBlock.into())
            }
            Err(e) => Err(e.into()),
        }
    }
    fn frame(&self) -> &[u8] {
        &self.raw[..self.len.min(CANFD_MTU)]
    }
}

/// Whether the next frame queued on `s` is the echo of one this socket sent (`MSG_CONFIRM`,
/// which the kernel sets on a socket's own frames with `CAN_RAW_RECV_OWN_MSGS`), peeked: the
/// frame stays queued for the read that takes it with its stamp. Through socket2, as nix's
/// message flags leave `MSG_CONFIRM` out. `flags`: more for the peek (`MSG_DONTWAIT`). The
/// second system call per frame is what confirmed transmissions cost.
fn next_is_own(s: &impl std::os::fd::AsFd, flags: MsgFlags) -> io::Result<bool> {
    let mut msg = socket2::MsgHdrMut::new();
    socket2::SockRef::from(s).recvmsg(&mut msg, (MsgFlags::MSG_PEEK | flags).bits())?;
    Ok(msg.flags().is_confirm())
}

/// How long a send waits before it tries again when the socket's buffer is full.
const ROOM_RETRY: std::time::Duration = std::time::Duration::from_millis(1);

/// Runs `write` until it does not find the socket's buffer full, waiting [`ROOM_RETRY`] between
/// tries: a full buffer is rare (a bus that takes no frames) and not worth a readiness
/// registration that would wake the runtime once per frame sent.
async fn write_waiting(write: impl Fn() -> io::Result<()>) -> io::Result<()> {
    loop {
        match write() {
            Err(e) if e.kind() == io::ErrorKind::WouldBlock => tokio::time::sleep(ROOM_RETRY).await,
            r => return r,
        }
    }
}

/// The port's socket: read through tokio, or by a reader thread.
#[derive(Debug)]
enum Sock {
    Async(TokioCanSocket),
    /// Blocking, read by the [`PortReader`] that shares it; sends from the port do not wait.
    Blocking(std::sync::Arc<socketcan::CanSocket>),
}

/// A SocketCAN port on one interface.
#[derive(Debug)]
pub struct SocketCanPort {
    ifname: String,
    /// Opened for CAN FD ([`SocketCanPort::open_fd`]).
    fd: bool,
    socket: Option<Sock>,
    rx: RxState,
    read: Received,
}

impl SocketCanPort {
    /// Opens `ifname` with error frames enabled. Must be called inside a tokio runtime.
    ///
    /// Fails with [`PortErrorKind::NoSuchInterface`] or [`PortErrorKind::InterfaceDown`] (and a
    /// hint how to create or raise it) before touching any socket.
    pub fn open(ifname: &str) -> Result<Self, PortError> {
        // Made before the socket: nothing it reads arrived earlier.
        Self::open_with(ifname, false)
    }

    /// Opens `ifname` for CAN FD frames as well as classic ones (`CAN_RAW_FD_FRAMES`), with
    /// error frames enabled: [`Port::send_fd`] and [`Port::recv_any`] carry CAN FD frames. Must
    /// be called inside a tokio runtime.
    ///
    /// Fails as [`SocketCanPort::open`] does, and with [`PortErrorKind::Config`] when the
    /// interface's MTU is not the CAN FD MTU (72): an interface that carries no CAN FD frames.
    pub fn open_fd(ifname: &str) -> Result<Self, PortError> {
        Self::open_with(ifname, true)
    }

    fn open_with(ifname: &str, fd: bool) -> Result<Self, PortError> {
        // Made before the socket: nothing it reads arrived earlier.
        let mut read = Received::new();
        read.fd = fd;
        let socket = open_socket(ifname, fd)?;
        Ok(SocketCanPort {
            ifname: ifname.to_owned(),
            fd,
            socket: Some(Sock::Async(socket)),
            rx: RxState {
                counters: PortCounters::new(),
                pending: ErrorStatuses::new(),
            },
            read,
        })
    }

    /// What the last read through tokio took: a confirmation of its own frame, a frame, a
    /// status, or nothing (a frame refused, counted).
    fn taken(&mut self) -> Option<PortInput> {
        if let Some(d) = self.read.dropped {
            self.rx.counters.rx_overrun_total(d);
        }
        if self.read.own {
            return Some(PortInput::Status(PortStatus::TxOk));
        }
        let (raw, at) = (self.read.frame(), self.read.at);
        self.rx.accept_kernel(&self.ifname, raw, at)
    }

    /// The interface name.
    pub fn ifname(&self) -> &str {
        &self.ifname
    }

    /// Whether the port was opened for CAN FD ([`SocketCanPort::open_fd`]).
    pub fn is_fd(&self) -> bool {
        self.fd
    }
}

/// The error of a port whose socket was closed after a failure.
fn closed(ifname: &str) -> PortError {
    PortError::new(
        ifname,
        PortErrorKind::Closed,
        "socket closed after a failure; re-open the port",
    )
}

fn open_socket(ifname: &str, fd: bool) -> Result<TokioCanSocket, PortError> {
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
    if fd {
        let mtu = interface_mtu(ifname);
        if mtu != Some(CANFD_MTU) {
            return Err(not_fd(ifname, mtu));
        }
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
    if fd {
        socket
            .0
            .get_ref()
            .set_socket_option_int(SOL_CAN_RAW, CAN_RAW_FD_FRAMES, 1)
            .map_err(|e| {
                PortError::io(ifname, "cannot enable CAN FD frames (CAN_RAW_FD_FRAMES)", e)
            })?;
    }
    stamp::enlarge_queue(socket.0.get_ref());
    if let Err(e) = stamp::enable(socket.0.get_ref()) {
        // Frames then come without stamps: the device takes them as handed over.
        tracing::warn!(port = %ifname, error = %e, "no receive timestamps (SO_TIMESTAMPNS)");
    }
    Ok(socket)
}

/// What a port has read besides frames: its counters, and the statuses of the last error
/// frame not yet handed on.
#[derive(Debug)]
struct RxState {
    counters: PortCounters,
    pending: ErrorStatuses,
}

impl RxState {
    /// Counts a received frame (stamped `at`), or a refused one.
    fn frame(
        &mut self,
        ifname: &str,
        f: Result<Frame, FrameError>,
        at: Option<std::time::Instant>,
    ) -> Option<PortInput> {
        match f {
            Ok(f) => {
                self.counters.rx_frames();
                Some(PortInput::Frame(f, at))
            }
            Err(e) => {
                self.counters.rx_invalid();
                tracing::warn!(port = %ifname, error = %e, "frame refused");
                None
            }
        }
    }

    /// Classifies a frame as the kernel wrote it (`struct can_frame`: identifier with its
    /// flags, length, three reserved bytes, eight data bytes), received at `at`: a frame to
    /// hand on, or `None` (error frame queued as status; anything not of that size counted
    /// invalid).
    fn accept_kernel(
        &mut self,
        ifname: &str,
        raw: &[u8],
        at: Option<std::time::Instant>,
    ) -> Option<PortInput> {
        let Ok(raw) = <&[u8; 16]>::try_from(raw) else {
            self.counters.rx_invalid();
            if raw.len() == CANFD_MTU {
                tracing::warn!(port = %ifname, "CAN FD frame refused by `recv` (read it with `recv_any`)");
                return None;
            }
            tracing::warn!(port = %ifname, len = raw.len(), "frame of an unexpected size refused");
            return None;
        };
        let word = u32::from_ne_bytes([raw[0], raw[1], raw[2], raw[3]]);
        let mut data = [0u8; 8];
        data.copy_from_slice(&raw[8..]);
        if word & error_frame::CAN_ERR_FLAG != 0 {
            self.counters.rx_error_frames();
            self.pending = error_frame::decode(word & error_frame::CAN_ERR_MASK, &data);
            tracing::debug!(port = %ifname, bits = word & error_frame::CAN_ERR_MASK, "error frame");
            return None;
        }
        let id = if word & CAN_EFF_FLAG != 0 {
            Id::Extended(word & CAN_EFF_MASK)
        } else {
            Id::Standard((word & 0x7FF) as u16)
        };
        let len = raw[4].min(8);
        let f = if word & CAN_RTR_FLAG != 0 {
            Frame::remote(id, len)
        } else {
            Frame::new(id, &data[..usize::from(len)])
        };
        self.frame(ifname, f, at)
    }

    /// The oldest status of the last error frame not yet handed on.
    fn status(&mut self) -> Option<PortInput> {
        (!self.pending.is_empty()).then(|| PortInput::Status(self.pending.remove(0)))
    }

    /// Counts a send's outcome; a failure that means the interface is gone closes the socket.
    fn sent(&self, ifname: &str, r: io::Result<()>) -> Result<(), (PortError, bool)> {
        match r {
            Ok(()) => {
                self.counters.tx_frames();
                Ok(())
            }
            Err(e) => {
                self.counters.tx_failed();
                let err = PortError::io(ifname, "write failed", e);
                let gone = matches!(
                    err.kind,
                    PortErrorKind::InterfaceDown | PortErrorKind::NoSuchInterface
                );
                Err((err, gone))
            }
        }
    }
}

impl Port for SocketCanPort {
    fn name(&self) -> &str {
        &self.ifname
    }

    fn counters(&self) -> PortCounters {
        self.rx.counters.clone()
    }

    async fn recv(&mut self) -> Result<PortInput, PortError> {
        loop {
            if let Some(x) = self.rx.status() {
                return Ok(x);
            }
            let sock = match self.socket.as_ref() {
                Some(Sock::Async(s)) => s,
                // Its reader thread reads: nothing comes here until the port is re-opened.
                Some(Sock::Blocking(_)) => return std::future::pending().await,
                None => return Err(closed(&self.ifname)),
            };
            match sock.read_frame(&mut self.read).await {
                Ok(()) => {
                    if let Some(x) = self.taken() {
                        return Ok(x);
                    }
                }
                Err(e) => {
                    self.socket = None;
                    return Err(PortError::io(&self.ifname, "read failed", e));
                }
            }
        }
    }

    async fn recv_any(&mut self) -> Result<AnyInput, PortError> {
        if !self.fd {
            return self.recv().await.map(AnyInput::from);
        }
        loop {
            if let Some(x) = self.rx.status() {
                return Ok(x.into());
            }
            let sock = match self.socket.as_ref() {
                Some(Sock::Async(s)) => s,
                // An FD port never hands its reading to a thread; this one was opened before.
                Some(Sock::Blocking(_)) => return std::future::pending().await,
                None => return Err(closed(&self.ifname)),
            };
            match sock.read_frame(&mut self.read).await {
                Ok(()) => {
                    if let Some(d) = self.read.dropped {
                        self.rx.counters.rx_overrun_total(d);
                    }
                    if self.read.own {
                        return Ok(PortInput::Status(PortStatus::TxOk).into());
                    }
                    let (raw, at) = (self.read.frame(), self.read.at);
                    if let Ok(fd) = <&[u8; CANFD_MTU]>::try_from(raw) {
                        match fd_from_kernel(fd) {
                            Ok(f) => {
                                self.rx.counters.rx_frames();
                                return Ok(AnyInput::Fd(f, at));
                            }
                            Err(e) => {
                                self.rx.counters.rx_invalid();
                                tracing::warn!(port = %self.ifname, error = %e, "CAN FD frame refused");
                            }
                        }
                    } else if let Some(x) = self.rx.accept_kernel(&self.ifname, raw, at) {
                        return Ok(x.into());
                    }
                }
                Err(e) => {
                    self.socket = None;
                    return Err(PortError::io(&self.ifname, "read failed", e));
                }
            }
        }
    }

    async fn send_fd(&mut self, frame: &FdFrame) -> Result<(), PortError> {
        if !self.fd {
            return Err(super::asynch::classic_port(&self.ifname, frame));
        }
        let raw = canfd_bytes(frame);
        let r = match self.socket.as_ref() {
            Some(Sock::Async(s)) => {
                let fd = s.0.get_ref().as_raw_fd();
                write_waiting(|| {
                    nix::sys::socket::send(fd, &raw, MsgFlags::MSG_DONTWAIT)
                        .map(drop)
                        .map_err(io::Error::from)
                })
                .await
            }
            Some(Sock::Blocking(_)) | None => {
                self.rx.counters.tx_dropped();
                return Err(closed(&self.ifname));
            }
        };
        self.rx.sent(&self.ifname, r).map_err(|(err, gone)| {
            if gone {
                self.socket = None;
            }
            err
        })
    }

    fn try_recv(&mut self) -> Option<Result<PortInput, PortError>> {
        loop {
            if let Some(x) = self.rx.status() {
                return Some(Ok(x));
            }
            let Some(Sock::Async(sock)) = self.socket.as_ref() else {
                return None;
            };
            match sock.try_read_frame(&mut self.read) {
                Ok(()) => {
                    if let Some(x) = self.taken() {
                        return Some(Ok(x));
                    }
                }
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => return None,
                Err(e) => {
                    self.socket = None;
                    return Some(Err(PortError::io(&self.ifname, "read failed", e)));
                }
            }
        }
    }

    async fn send(&mut self, frame: &Frame) -> Result<(), PortError> {
        let r = match self.socket.as_ref() {
            Some(Sock::Async(s)) => s.write_frame(socketcan_frame(frame)).await,
            Some(Sock::Blocking(s)) => write_waiting(|| blocking::send_now(s, frame)).await,
            None => {
                self.rx.counters.tx_dropped();
                return Err(closed(&self.ifname));
            }
        };
        self.rx.sent(&self.ifname, r).map_err(|(err, gone)| {
            if gone {
                self.socket = None;
            }
            err
        })
    }

    fn confirm_transmissions(&mut self) -> bool {
        // An echo the kernel makes itself (a driver without `IFF_ECHO`) comes as the frame is
        // handed over: it would confirm frames that never reached the bus.
        if !interface::echoes(&self.ifname) {
            tracing::info!(port = %self.ifname, "the interface's driver does not echo frames (IFF_ECHO): transmissions stay unconfirmed");
            return false;
        }
        let set = match self.socket.as_ref() {
            Some(Sock::Async(s)) => s.0.get_ref().set_recv_own_msgs(true),
            Some(Sock::Blocking(s)) => s.set_recv_own_msgs(true),
            None => Ok(()),
        };
        if let Err(e) = set {
            tracing::warn!(port = %self.ifname, error = %e, "cannot receive own frames: transmissions stay unconfirmed");
            return false;
        }
        self.read.confirm = true;
        true
    }

    async fn reopen(&mut self) -> Result<(), PortError> {
        self.socket = None;
        self.rx.pending.clear();
        // A new socket: no read has found it empty yet.
        self.read.clock = KernelClock::new();
        let socket = open_socket(&self.ifname, self.fd)?;
        if self.read.confirm {
            socket
                .0
                .get_ref()
                .set_recv_own_msgs(true)
                .map_err(|e| PortError::io(&self.ifname, "cannot receive own frames", e))?;
        }
        self.socket = Some(Sock::Async(socket));
        self.rx.counters.reopened();
        Ok(())
    }

    fn reader(&mut self) -> Option<Box<dyn PortReader>> {
        // The blocking reader reads classic frames only: an FD port stays on `recv`.
        if self.fd {
            return None;
        }
        let Some(Sock::Async(s)) = self.socket.take() else {
            return None;
        };
        match blocking::Reader::new(
            &self.ifname,
            s,
            &mut self.rx,
            self.read.clock,
            self.read.confirm,
        ) {
            Ok((reader, shared)) => {
                self.socket = Some(Sock::Blocking(shared));
                Some(Box::new(reader))
            }
            Err((s, e)) => {
                tracing::warn!(port = %self.ifname, error = %e, "cannot read by blocking, reading through readiness");
                self.socket = Some(Sock::Async(s));
                None
            }
        }
    }
}
