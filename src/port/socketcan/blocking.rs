//! The port's blocking side: a reader thread reads the socket as a bare loop does, and writes
//! the device's answers on it; the port's task sends on the same socket without waiting.

use super::{PortInput, PortReader, RxState, TokioCanSocket};
use crate::frame::{Frame, Id};
use crate::port::asynch::{timed_out, READER_WAIT};
use crate::port::PortError;
use nix::sys::socket::{send, MsgFlags};
use socketcan::{CanFrame, Socket};
use std::io;
use std::os::fd::AsRawFd;
use std::sync::Arc;

/// Reads (and writes answers) by blocking, each call waiting at most [`READER_WAIT`].
pub(super) struct Reader {
    ifname: String,
    socket: Arc<socketcan::CanSocket>,
    rx: RxState,
}

impl Reader {
    /// Turns the port's socket into a blocking one shared with the reader; the reader hands on
    /// the statuses the port had not handed on yet. On failure the socket comes back as it
    /// was.
    #[allow(clippy::type_complexity)]
    pub(super) fn new(
        ifname: &str,
        s: TokioCanSocket,
        rx: &mut RxState,
    ) -> Result<(Reader, Arc<socketcan::CanSocket>), (TokioCanSocket, io::Error)> {
        let set = |s: &socketcan::CanSocket| {
            s.set_read_timeout(READER_WAIT)?;
            s.set_write_timeout(READER_WAIT)?;
            s.set_nonblocking(false)
        };
        if let Err(e) = set(s.0.get_ref()) {
            let _ = s.0.get_ref().set_nonblocking(true);
            return Err((s, e));
        }
        // Out of tokio's epoll: the thread waits in `read` itself.
        let socket = Arc::new(s.0.into_inner());
        let reader = Reader {
            ifname: ifname.to_owned(),
            socket: socket.clone(),
            rx: RxState {
                counters: rx.counters.clone(),
                pending: core::mem::take(&mut rx.pending),
            },
        };
        Ok((reader, socket))
    }
}

impl PortReader for Reader {
    fn read(&mut self) -> Result<Option<PortInput>, PortError> {
        loop {
            if let Some(x) = self.rx.status() {
                return Ok(Some(x));
            }
            match self.socket.read_frame() {
                Ok(raw) => {
                    if let Some(x) = self.rx.accept(&self.ifname, &raw) {
                        return Ok(Some(x));
                    }
                }
                Err(e) if timed_out(&e) => return Ok(None),
                Err(e) => return Err(PortError::io(&self.ifname, "read failed", e)),
            }
        }
    }

    fn write(&mut self, frame: &Frame) -> Result<bool, PortError> {
        match self.socket.write_frame(&CanFrame::from(frame)) {
            Err(e) if timed_out(&e) => Ok(false),
            r => self
                .rx
                .sent(&self.ifname, r)
                .map(|()| true)
                .map_err(|(e, _)| e),
        }
    }
}

/// Sends `f` on the blocking socket `s` without waiting: `WouldBlock` when its buffer is full.
pub(super) fn send_now(s: &socketcan::CanSocket, f: &Frame) -> io::Result<()> {
    let bytes = can_frame_bytes(f);
    match send(s.as_raw_fd(), &bytes, MsgFlags::MSG_DONTWAIT) {
        Ok(n) if n == bytes.len() => Ok(()),
        Ok(n) => Err(io::Error::new(
            io::ErrorKind::WriteZero,
            format!("short write: {n} of {} bytes", bytes.len()),
        )),
        Err(errno) => Err(io::Error::from(errno)),
    }
}

/// The kernel's `struct can_frame` for `f`: identifier with its flags, length, three reserved
/// bytes, eight data bytes.
fn can_frame_bytes(f: &Frame) -> [u8; 16] {
    const EFF: u32 = 0x8000_0000;
    const RTR: u32 = 0x4000_0000;
    let mut id = match f.id() {
        Id::Standard(x) => u32::from(x),
        Id::Extended(x) => x | EFF,
    };
    if f.is_remote() {
        id |= RTR;
    }
    let mut out = [0u8; 16];
    out[..4].copy_from_slice(&id.to_ne_bytes());
    out[4] = f.dlc();
    out[8..8 + f.data().len()].copy_from_slice(f.data());
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use socketcan::{EmbeddedFrame, Frame as _};

    proptest! {
        /// The bytes sent without waiting are the socketcan crate's own frame, field by field.
        #[test]
        fn the_frame_sent_without_waiting_is_the_kernels(f in crate::frame::tests::any_frame()) {
            let b = can_frame_bytes(&f);
            let c = CanFrame::from(&f);
            prop_assert_eq!(u32::from_ne_bytes([b[0], b[1], b[2], b[3]]), c.id_word());
            prop_assert_eq!(usize::from(b[4]), c.dlc());
            prop_assert_eq!(&b[8..8 + f.data().len()], EmbeddedFrame::data(&c));
        }
    }
}
