//! Receiving one datagram with its sender and, on Linux, the kernel's receive timestamp
//! (`SO_TIMESTAMPNS` on the receive socket, read as a control message and put on the monotonic
//! clock: see `port::stamp`). Elsewhere datagrams come without stamps.
//!
//! The same for the port's task (a non-blocking socket read through tokio's readiness) and for
//! its reader thread (a blocking one): both call [`Stamps::recv`]; a read that finds the socket
//! empty (or waits for nothing until its timeout) sets the floor of the conversion.

use std::net::SocketAddr;
use std::time::Instant;

#[cfg(target_os = "linux")]
mod imp {
    use crate::port::stamp::{self, KernelClock};
    use nix::errno::Errno;
    use nix::sys::socket::{recvmsg, MsgFlags, SockaddrIn};
    use std::io::{self, IoSliceMut};
    use std::net::SocketAddr;
    use std::os::fd::{AsFd, AsRawFd};
    use std::time::Instant;

    /// The room for a datagram's stamp and the conversion of stamps.
    #[derive(Clone, Debug)]
    pub(crate) struct Stamps {
        control: Vec<u8>,
        clock: KernelClock,
    }

    impl Stamps {
        /// For a socket about to be opened.
        pub(crate) fn new() -> Self {
            Stamps {
                control: stamp::control_space(),
                clock: KernelClock::new(),
            }
        }

        /// Asks the kernel to stamp what `socket` receives and to count what it drops, and
        /// gives the socket a long receive queue.
        pub(crate) fn enable(socket: &impl AsFd) -> io::Result<()> {
            stamp::enlarge_queue(socket);
            stamp::enable(socket)
        }

        /// One datagram from `socket` into `buf`: its length, sender and receive time.
        pub(crate) fn recv<S: AsRawFd>(
            &mut self,
            socket: &S,
            buf: &mut [u8],
        ) -> io::Result<super::Datagram> {
            let mut iov = [IoSliceMut::new(buf)];
            let fd = socket.as_raw_fd();
            let called = Instant::now();
            match recvmsg::<SockaddrIn>(fd, &mut iov, Some(&mut self.control), MsgFlags::empty()) {
                Ok(m) => {
                    let reading = self.clock.read();
                    let at = stamp::of_message(&m).map(|t| reading.convert(t));
                    let dropped = stamp::dropped(&m);
                    Ok((m.bytes, m.address.map(SocketAddr::from), at, dropped))
                }
                Err(e) => {
                    if e == Errno::EAGAIN {
                        // Found empty (or nothing came until the timeout): what comes next
                        // arrived after the call began.
                        self.clock.drained(called);
                    }
                    Err(e.into())
                }
            }
        }
    }
}

#[cfg(not(target_os = "linux"))]
mod imp {
    use std::io;
    use std::net::SocketAddr;

    /// No stamps on this system.
    #[derive(Clone, Debug)]
    pub(crate) struct Stamps;

    /// A socket that receives a datagram without waiting for readiness itself.
    pub(crate) trait RecvFrom {
        fn recv_from_now(&self, buf: &mut [u8]) -> io::Result<(usize, SocketAddr)>;
    }

    impl RecvFrom for std::net::UdpSocket {
        fn recv_from_now(&self, buf: &mut [u8]) -> io::Result<(usize, SocketAddr)> {
            self.recv_from(buf)
        }
    }

    impl RecvFrom for tokio::net::UdpSocket {
        fn recv_from_now(&self, buf: &mut [u8]) -> io::Result<(usize, SocketAddr)> {
            self.try_recv_from(buf)
        }
    }

    impl Stamps {
        pub(crate) fn new() -> Self {
            Stamps
        }
        pub(crate) fn enable<S>(_: &S) -> io::Result<()> {
            Ok(())
        }
        pub(crate) fn recv<S: RecvFrom>(
            &mut self,
            socket: &S,
            buf: &mut [u8],
        ) -> io::Result<super::Datagram> {
            socket
                .recv_from_now(buf)
                .map(|(n, from)| (n, Some(from), None, None))
        }
    }
}

pub(super) use imp::Stamps;

/// A datagram received: its length, its sender (`None`: not an IPv4 address, so none of ours),
/// its receive time and the socket's count of datagrams dropped on a full queue so far.
pub(super) type Datagram = (usize, Option<SocketAddr>, Option<Instant>, Option<u32>);
