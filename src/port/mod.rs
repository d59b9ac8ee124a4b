//! Real CAN ports: what the runtime reads frames from and writes frames to.
//!
//! A `Port` (with the `tokio` feature) is one CAN interface as seen by an async driver: it yields received frames and
//! controller status (`PortInput`), sends frames, and can be re-opened after a failure. Input a
//! port cannot represent as a classic [`Frame`](crate::Frame) (CAN FD, a bad DLC, a garbage datagram) is counted
//! in its [`PortCounters`] and logged, never returned as an error: a bus full of junk must not
//! stop the runtime. An `Err` from a port means the port itself is unusable (interface down,
//! socket closed) and the runtime reports it as [`PortStatus::Down`](crate::PortStatus::Down) and starts re-opening it.
//!
//! Implementations: `socketcan` (Linux SocketCAN, feature `socketcan`), `udp` (python-can's
//! `udp_multicast` bus, feature `udp`), and for no_std targets the synchronous [`embedded`]
//! adapter, which drives a [`Device`](crate::Device) over `embedded_can::nb::Can` drivers.

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
#[cfg(feature = "tokio")]
pub use asynch::{Port, PortError, PortErrorKind, PortInput};
