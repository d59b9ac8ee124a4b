//! Real CAN ports: what the runtime reads frames from and writes frames to.
//!
//! A `Port` (with the `tokio` feature) is one CAN interface as seen by an async driver: it yields received frames and
//! controller status (`PortInput`), sends frames, and can be re-opened after a failure. Input a
//! port cannot represent as a classic [`Frame`](crate::Frame) (CAN FD, a bad DLC, a garbage datagram) is counted
//! in its [`PortCounters`] and logged, never returned as an error: a bus full of junk must not
//! stop the runtime. An `Err` from a port means the port itself is unusable (interface down,
//! socket closed) and the runtime reports it as [`PortStatus::Down`](crate::PortStatus::Down) and starts re-opening it.
//!
//! A received frame comes with its receive timestamp where the port takes one
//! (`PortInput::Frame`): SocketCAN and UDP ports read the kernel's (`SO_TIMESTAMPNS`, taken as
//! the frame entered the network stack, on the wall clock, and put on the monotonic clock at
//! each read: a step of the wall clock between a frame's arrival and its read moves that frame,
//! never past its read time nor before the last read that found the socket empty); the
//! in-memory bus stamps a frame with the time it went onto the bus. The `embedded` adapter
//! hands frames over without stamps (`embedded_can` frames carry none).
//!
//! # CAN FD
//!
//! A port that can carry CAN FD frames says so through two methods of its own beside the
//! classic ones: `Port::send_fd` sends one, `Port::recv_any` hands over classic and FD frames
//! alike (`AnyInput`). Their defaults are a classic port's: `send_fd` refuses with a
//! configuration error, `recv_any` is `recv`. Separate methods rather than a frame enum in
//! `send` and `PortInput`: a classic frame is 16 bytes and a CAN FD frame 72, so an enum would
//! make every classic frame the runtime moves as large as an FD one, and every port and
//! caller would have to handle FD; this way the classic path is as it was and a port opts in
//! to FD when it is opened for it (SocketCAN: `SocketCanPort::open_fd`, which checks the
//! interface's MTU; UDP: `UdpBusConfig::with_fd`). `recv` of an FD port still hands over
//! classic frames only, counting FD ones as invalid. The `embedded` adapter stays classic:
//! `embedded_can::Frame` has no CAN FD frame. Every port of the in-memory bus (`mem`) carries
//! FD frames.
//!
//! The runtime reads the ports of a device that speaks CAN FD
//! ([`Device::fd_capable`](crate::Device::fd_capable)) through `recv_any` and sends the FD
//! frames it yields through `send_fd`, from a queue of their own beside the classic one (see
//! the runtime's CAN FD section); a classic device's ports it reads through `recv` (or a
//! reader thread) and writes through `send`, as before.
//!
//! Implementations: `socketcan` (Linux SocketCAN, feature `socketcan`), `udp` (python-can's
//! `udp_multicast` bus, feature `udp`), and for no_std targets the synchronous [`embedded`]
//! adapter, which drives a [`Device`](crate::Device) over `embedded_can::nb::Can` drivers.
//!
//! Two ports on one in-memory bus (`mem`, feature `tokio`): what one sends the other receives,
//! and neither hears itself. The runtime does this for a device; an application rarely calls a
//! port itself.
//!
//! ```
//! # #[cfg(feature = "tokio")]
//! # #[tokio::main(flavor = "current_thread")]
//! # async fn main() -> Result<(), duocan::port::PortError> {
//! use duocan::port::mem::MemBus;
//! use duocan::port::{Port, PortInput};
//! use duocan::{Frame, Id};
//!
//! let bus = MemBus::new("mem0");
//! let (mut a, mut b) = (bus.port(), bus.port());
//! let heartbeat = Frame::from_array(Id::Standard(0x705), [0x05]);
//! a.send(&heartbeat).await?;
//! let PortInput::Frame(got, _stamp) = b.recv().await? else { panic!("a frame was sent") };
//! assert_eq!(got, heartbeat);
//! // `a`'s next input is `b`'s answer: its own heartbeat does not come back to it.
//! let answer = Frame::from_array(Id::Standard(0x706), [0x7F]);
//! b.send(&answer).await?;
//! assert_eq!(a.recv().await?.frame(), Some(&answer));
//! assert_eq!((a.counters().snapshot().tx_frames, b.counters().snapshot().rx_frames), (1, 1));
//! # Ok(())
//! # }
//! # #[cfg(not(feature = "tokio"))]
//! # fn main() {}
//! ```
//!
//! A SocketCAN interface is opened by name (feature `socketcan`, Linux); a missing or down
//! interface is an error that says how to create or raise it:
//!
//! ```no_run
//! # #[cfg(all(feature = "socketcan", target_os = "linux"))]
//! # #[tokio::main]
//! # async fn main() -> Result<(), duocan::port::PortError> {
//! use duocan::nmt::{command_frame, NmtCommand, NmtTarget};
//! use duocan::port::{socketcan::SocketCanPort, Port};
//! use duocan::Id;
//!
//! let mut can0 = SocketCanPort::open("can0")?;
//! can0.send(&command_frame(Id::Standard(0), NmtCommand::Start, NmtTarget::All)).await?;
//! # Ok(())
//! # }
//! # #[cfg(not(all(feature = "socketcan", target_os = "linux")))]
//! # fn main() {}
//! ```

pub mod embedded;
pub mod error_frame;
#[cfg(all(feature = "socketcan", target_os = "linux"))]
pub mod socketcan;
#[cfg(feature = "udp")]
pub mod udp;

#[cfg(feature = "std")]
mod counters;
#[cfg(feature = "std")]
pub use counters::{PortCounters, PortCountersSnapshot};

#[cfg(feature = "tokio")]
mod asynch;
#[cfg(feature = "tokio")]
pub mod mem;
#[cfg(any(
    all(feature = "udp", target_os = "linux"),
    all(feature = "socketcan", target_os = "linux")
))]
mod stamp;
#[cfg(feature = "tokio")]
pub use asynch::{AnyInput, Port, PortError, PortErrorKind, PortInput, PortReader, READER_WAIT};
