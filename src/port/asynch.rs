//! The async port interface the runtime drives.

use super::PortCounters;
use crate::frame::{FdFrame, Frame};
use crate::machine::{ErrorCause, PortStatus};
use std::fmt;
use std::future::Future;
use std::io;

/// What a port delivers.
///
/// A frame comes with its **receive timestamp** when the port takes one: when the frame arrived
/// where it was received (the kernel's socket, a simulated wire), not when a task got to it.
/// The runtime hands a stamped frame to the device with
/// [`Device::handle_rx_at`](crate::Device::handle_rx_at), so that a reader that ran late does
/// not make the frame late (a dual-bus layer tells a frame's two copies apart by these times),
/// and one without a stamp with [`Device::handle_rx`](crate::Device::handle_rx). `T` is the
/// stamp's clock: a port's is the standard library's monotonic clock ([`std::time::Instant`]);
/// a link that carries a simulated segment in the network's own task stamps with the network's
/// [`Instant`](crate::Instant) ([`NetLink::poll_input`](crate::net::NetLink::poll_input)).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PortInput<T = std::time::Instant> {
    /// A classic CAN frame from the bus, with its receive timestamp (`None`: the port takes
    /// none).
    Frame(Frame, Option<T>),
    /// Controller status: a decoded error frame, a state change.
    Status(PortStatus),
}

impl<T> PortInput<T> {
    /// The frame, if this is one (whatever its stamp).
    #[must_use]
    pub fn frame(&self) -> Option<&Frame> {
        match self {
            PortInput::Frame(f, _) => Some(f),
            PortInput::Status(_) => None,
        }
    }
}

/// What a port delivers through [`Port::recv_any`]: [`PortInput`] and CAN FD frames.
///
/// A type of its own rather than a third variant of [`PortInput`]: a CAN FD frame is 72 bytes
/// against a classic frame's 16, and every classic frame the runtime moves would grow to its
/// size.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AnyInput<T = std::time::Instant> {
    /// A classic CAN frame and its receive timestamp (`None`: the port takes none).
    Frame(Frame, Option<T>),
    /// A CAN FD frame and its receive timestamp.
    Fd(FdFrame, Option<T>),
    /// Controller status.
    Status(PortStatus),
}

impl<T> From<PortInput<T>> for AnyInput<T> {
    fn from(input: PortInput<T>) -> Self {
        match input {
            PortInput::Frame(f, at) => AnyInput::Frame(f, at),
            PortInput::Status(s) => AnyInput::Status(s),
        }
    }
}

impl<T> AnyInput<T> {
    /// The CAN FD frame, if this is one.
    #[must_use]
    pub fn fd_frame(&self) -> Option<&FdFrame> {
        match self {
            AnyInput::Fd(f, _) => Some(f),
            _ => None,
        }
    }
}

/// What kind of failure a [`PortError`] is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PortErrorKind {
    /// The interface does not exist.
    NoSuchInterface,
    /// The interface exists but is down.
    InterfaceDown,
    /// The port was configured in a way it refuses (e.g. a non-loopback UDP interface without
    /// opt-in, a non-multicast group).
    Config,
    /// The operating system refused an operation (socket, bind, read, write).
    Io,
    /// The port was closed.
    Closed,
}

/// A port failure: which port, what happened, and what to do about it.
#[derive(Debug)]
pub struct PortError {
    /// Port name (interface or multicast group).
    pub port: String,
    /// What kind of failure.
    pub kind: PortErrorKind,
    /// What was being done, and a hint how to fix it.
    pub context: String,
    /// The operating system error, if any.
    pub source: Option<io::Error>,
}

impl PortError {
    /// A failure of `port`.
    #[must_use]
    pub fn new(port: &str, kind: PortErrorKind, context: impl Into<String>) -> Self {
        PortError {
            port: port.to_owned(),
            kind,
            context: context.into(),
            source: None,
        }
    }
    /// An OS error while doing `context` on `port`; ENODEV and ENETDOWN get their own kinds.
    #[must_use]
    pub fn io(port: &str, context: impl Into<String>, e: io::Error) -> Self {
        let kind = match e.raw_os_error() {
            Some(code) if code == ENODEV || code == ENXIO => PortErrorKind::NoSuchInterface,
            Some(code) if code == ENETDOWN => PortErrorKind::InterfaceDown,
            _ => PortErrorKind::Io,
        };
        PortError {
            port: port.to_owned(),
            kind,
            context: context.into(),
            source: Some(e),
        }
    }
    /// The cause to report upward as port status.
    pub fn cause(&self) -> ErrorCause {
        match self.kind {
            PortErrorKind::NoSuchInterface
            | PortErrorKind::InterfaceDown
            | PortErrorKind::Closed => ErrorCause::InterfaceDown,
            PortErrorKind::Config | PortErrorKind::Io => ErrorCause::Other,
        }
    }
}

// errno values shared by every Linux architecture the project targets (asm-generic).
const ENXIO: i32 = 6;
const ENODEV: i32 = 19;
const ENETDOWN: i32 = 100;

impl fmt::Display for PortError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "port {}: {}", self.port, self.context)?;
        if let Some(e) = &self.source {
            write!(f, ": {e}")?;
        }
        Ok(())
    }
}

impl std::error::Error for PortError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        self.source
            .as_ref()
            .map(|e| e as &(dyn std::error::Error + 'static))
    }
}

/// One CAN interface driven by the async runtime.
///
/// `recv` must be cancel-safe: the runtime races it against outgoing frames and drops the
/// future when a frame is to be sent. Readiness-based socket reads (SocketCAN, UDP) are.
pub trait Port: Send + 'static {
    /// The port's name, for logs and errors (`vcan0`, `239.74.163.2:43113`).
    fn name(&self) -> &str;
    /// The port's counters (shared: read them from anywhere).
    fn counters(&self) -> PortCounters;
    /// Next frame or status. Invalid input is counted and skipped, not returned. An `Err`
    /// means the port is unusable until [`Port::reopen`] succeeds.
    fn recv(&mut self) -> impl Future<Output = Result<PortInput, PortError>> + Send;
    /// The next input if one is ready without waiting, for draining bursts in one go; `None`
    /// when nothing is ready (or the port cannot tell). An `Err` means the same as from `recv`.
    fn try_recv(&mut self) -> Option<Result<PortInput, PortError>> {
        None
    }
    /// Sends one frame.
    fn send(&mut self, frame: &Frame) -> impl Future<Output = Result<(), PortError>> + Send;
    /// Sends one CAN FD frame, on a port opened for CAN FD. The default is a classic port's
    /// answer: a [`PortErrorKind::Config`] error saying so, nothing sent.
    fn send_fd(&mut self, frame: &FdFrame) -> impl Future<Output = Result<(), PortError>> + Send {
        let e = classic_port(self.name(), frame);
        async move { Err(e) }
    }
    /// Next frame, classic or CAN FD, or status: what [`Port::recv`] hands over plus the CAN FD
    /// frames of a port opened for them ([`Port::recv`] counts those as invalid and skips
    /// them, as a classic port does). The default is a classic port's: [`Port::recv`].
    fn recv_any(&mut self) -> impl Future<Output = Result<AnyInput, PortError>> + Send {
        async move { self.recv().await.map(AnyInput::from) }
    }
    /// Asks the port to confirm each frame it sends once the frame has left (SocketCAN: the
    /// kernel's echo of the socket's own frames, which a controller driver gives when the frame
    /// was on the bus; UDP: the port's own datagram coming back): from then on the port hands
    /// over a [`PortStatus::TxOk`](crate::PortStatus::TxOk) for each, in the order they were
    /// sent, and never its own frames as received ones. True if the port can (kept across
    /// [`Port::reopen`]); false (the default, nothing changes) if it cannot.
    ///
    /// Who asks: the dual-bus layer, whose transmit-stall rule judges a port by the
    /// confirmations of both (a frame that reaches the bus later than its twin's skew window
    /// is a duplicate). A single bus does not ask: a confirmation per frame would be work for
    /// nothing.
    fn confirm_transmissions(&mut self) -> bool {
        false
    }
    /// Re-opens the port after a failure (or on request: after bus-off, to reset the socket).
    fn reopen(&mut self) -> impl Future<Output = Result<(), PortError>> + Send;
    /// Hands the port's reading to a thread of its own, if the port can read by blocking: the
    /// runtime then reads through the returned [`PortReader`] (as a bare socket loop does: one
    /// system call per frame, no readiness wait) and no longer calls [`Port::recv`]; `send`
    /// stays usable and must not wait for room while holding up its caller. `None` (the
    /// default) keeps the port on `recv`. After [`Port::reopen`] the port reads through `recv`
    /// again until this is called again.
    fn reader(&mut self) -> Option<Box<dyn PortReader>> {
        None
    }
}

/// What a classic port answers to [`Port::send_fd`].
pub(crate) fn classic_port(port: &str, frame: &FdFrame) -> PortError {
    PortError::new(
        port,
        PortErrorKind::Config,
        format!(
            "a classic CAN port: cannot send the CAN FD frame {frame} (open the port for CAN FD)"
        ),
    )
}

/// How long a [`PortReader`] waits at most in one call: the reader thread looks this often
/// whether it is to stop.
pub const READER_WAIT: std::time::Duration = std::time::Duration::from_millis(50);

/// A [`PortReader`]'s socket wait ran out (`SO_RCVTIMEO`/`SO_SNDTIMEO`, set to
/// [`READER_WAIT`]) or a signal interrupted it: nothing came, try again.
#[cfg(any(feature = "udp", all(feature = "socketcan", target_os = "linux")))]
pub(crate) fn timed_out(e: &io::Error) -> bool {
    matches!(
        e.kind(),
        io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut | io::ErrorKind::Interrupted
    )
}

/// The blocking side of a port, used by a thread of its own (see [`Port::reader`]).
pub trait PortReader: Send {
    /// The next frame or status, waiting at most [`READER_WAIT`]: `Ok(None)` when nothing came
    /// in that time. An `Err` means the port is unusable until it is re-opened.
    fn read(&mut self) -> Result<Option<PortInput>, PortError>;
    /// Sends one frame, waiting at most [`READER_WAIT`] for room: `Ok(false)` when there was
    /// none in that time (the caller tries again or gives up). A reader may keep it to send
    /// with the next ones: [`PortReader::flush`] sends what it kept.
    fn write(&mut self, frame: &Frame) -> Result<bool, PortError>;
    /// The next input already read (with an earlier one, in one system call), without waiting
    /// or asking the system: the caller hands these on before it flushes. `None` (the default)
    /// when there is none.
    fn read_ready(&mut self) -> Option<PortInput> {
        None
    }
    /// Sends what [`PortReader::write`] kept, in order, waiting at most [`READER_WAIT`] for
    /// room: `Ok(false)` when some is left (the caller tries again or gives up). An `Err` is
    /// the failure of one frame, which is dropped; the rest stay for the next call. Nothing
    /// kept (the default): `Ok(true)`.
    fn flush(&mut self) -> Result<bool, PortError> {
        Ok(true)
    }
}
