//! The port's blocking side: a reader thread reads the socket, and writes the device's answers
//! on it; the port's task sends on the same socket without waiting.
//!
//! Why `recvmmsg` and `sendmmsg`: one system call takes every frame already queued on the
//! socket (up to [`BATCH`]), waiting only for the first, and one sends the answers to all of
//! them. A bare loop pays a `read` and a `write` per frame; under load, when frames queue up,
//! the reader pays one of each per batch, and with a single frame waiting it does what the bare
//! loop does. The frames are handed on one by one, in the order the kernel queued them, and the
//! answers go out in the order they were written: the runtime sees exactly what a `read` loop
//! would, and the bus what a `write` loop would.
//!
//! Each frame of a batch carries the kernel's receive timestamp (a control message of its own
//! in the batch), put on the monotonic clock with the clocks read once per batch, right after
//! the call returned (see `port::stamp`). A batch of fewer than [`BATCH`] frames found the
//! socket empty: the next batch's frames arrived after the call began.

use super::{PortInput, PortReader, RxState, TokioCanSocket, CAN_EFF_FLAG, CAN_MTU, CAN_RTR_FLAG};
use crate::frame::{Frame, Id};
use crate::machine::PortStatus;
use crate::port::asynch::{timed_out, READER_WAIT};
use crate::port::stamp::{self, KernelClock};
use crate::port::PortError;
use nix::sys::socket::{recvmmsg, send, sendmmsg, MsgFlags, MultiHeaders};
use socketcan::Socket;
use std::io::{self, IoSlice, IoSliceMut};
use std::os::fd::AsRawFd;
use std::sync::Arc;

/// Frames taken from the socket per system call at most.
const BATCH: usize = 16;

std::thread_local! {
    /// The message headers of `recvmmsg` (with room for each frame's stamp) and of
    /// `sendmmsg`, made once per reader thread (no allocation per read). Per thread, not per
    /// reader: they hold raw pointers, so they cannot move to another thread with the reader.
    static HEADERS: core::cell::RefCell<Option<[MultiHeaders<()>; 2]>> =
        const { core::cell::RefCell::new(None) };
}

/// Runs `f` with this thread's receive and send headers.
fn with_headers<R>(f: impl FnOnce(&mut [MultiHeaders<()>; 2]) -> R) -> R {
    HEADERS.with_borrow_mut(|h| {
        f(h.get_or_insert_with(|| {
            [
                MultiHeaders::preallocate(BATCH, Some(stamp::control_space())),
                MultiHeaders::preallocate(BATCH, None),
            ]
        }))
    })
}

/// Makes this thread's headers afresh at the next call. The kernel writes back into each
/// header the room its message's control data took, and `recvmmsg` offers that room the next
/// time: a message that came without a stamp leaves its header no room for one, and the next
/// stamp in it is cut off (`MSG_CTRUNC`).
#[cold]
fn renew_headers() {
    HEADERS.with_borrow_mut(|h| *h = None);
}

/// Reads (and writes answers) by blocking, each call waiting at most [`READER_WAIT`].
pub(super) struct Reader {
    ifname: String,
    socket: Arc<socketcan::CanSocket>,
    rx: RxState,
    /// The last batch: the kernel's frames, each one's length in bytes and receive timestamp.
    raw: [[u8; CAN_MTU]; BATCH],
    len: [usize; BATCH],
    at: [Option<std::time::Instant>; BATCH],
    /// Puts the kernel's stamps on the monotonic clock.
    clock: KernelClock,
    /// Transmissions are confirmed: one frame per read, each looked at first (see
    /// [`super::next_is_own`]); `own`: the batch's frame is the echo of one the socket sent.
    confirm: bool,
    own: bool,
    /// Frames of the batch handed on so far, and in it.
    next: usize,
    got: usize,
    /// Frames written and not yet sent (as the kernel takes them), and how many of them are
    /// sent already.
    tx: [[u8; CAN_MTU]; BATCH],
    tx_len: usize,
    tx_sent: usize,
}

impl Reader {
    /// Turns the port's socket into a blocking one shared with the reader; the reader hands on
    /// the statuses the port had not handed on yet, and converts stamps from where the port's
    /// `clock` is. On failure the socket comes back as it was.
    #[allow(clippy::type_complexity)]
    pub(super) fn new(
        ifname: &str,
        s: TokioCanSocket,
        rx: &mut RxState,
        clock: KernelClock,
        confirm: bool,
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
            raw: [[0; CAN_MTU]; BATCH],
            len: [0; BATCH],
            at: [None; BATCH],
            clock,
            confirm,
            own: false,
            next: 0,
            got: 0,
            tx: [[0; CAN_MTU]; BATCH],
            tx_len: 0,
            tx_sent: 0,
        };
        Ok((reader, socket))
    }

    /// Takes what is queued on the socket (at least one frame, waiting for it at most
    /// [`READER_WAIT`]) into the batch.
    fn fill(&mut self) -> io::Result<()> {
        let fd = self.socket.as_raw_fd();
        // Confirming: the next frame is looked at (waiting for it) and taken alone, so that an
        // echo is told from a frame of the bus.
        let room = if self.confirm {
            self.own = super::next_is_own(&*self.socket, MsgFlags::empty())?;
            1
        } else {
            BATCH
        };
        let (raw, lens, ats, clock) = (&mut self.raw, &mut self.len, &mut self.at, &mut self.clock);
        let counters = &self.rx.counters;
        let (n, cut) = with_headers(|[h, _]| {
            let mut slices = raw.each_mut().map(|b| [IoSliceMut::new(b)]);
            // Taken before the call: should it find the socket empty (fewer than a batch),
            // what comes after it arrived after this (a reading taken after the call returns
            // may be late by as long as the thread is held up in between).
            let called = std::time::Instant::now();
            let got = recvmmsg(
                fd,
                h,
                slices.iter_mut().take(room),
                MsgFlags::MSG_WAITFORONE,
                None,
            )
            .map_err(io::Error::from)?;
            let reading = clock.read();
            let (mut n, mut cut) = (0, false);
            for ((len, at), m) in lens.iter_mut().zip(ats.iter_mut()).zip(got) {
                *len = m.bytes;
                *at = stamp::of_message(&m).map(|t| reading.convert(t));
                if let Some(d) = stamp::dropped(&m) {
                    counters.rx_overrun_total(d);
                }
                cut |= m.flags.contains(MsgFlags::MSG_CTRUNC);
                n += 1;
            }
            if n < room {
                clock.drained(called);
            }
            Ok::<_, io::Error>((n, cut))
        })?;
        if cut {
            renew_headers();
        }
        self.next = 0;
        self.got = n;
        Ok(())
    }

    /// Sends the written frames not sent yet, from the first: how many the kernel took.
    fn send_batch(&mut self) -> io::Result<usize> {
        let fd = self.socket.as_raw_fd();
        let frames = &self.tx[self.tx_sent..self.tx_len];
        if let [one] = frames {
            // One frame (a lone request's answer): a plain send is the kernel's shorter path.
            let n = send(fd, one, MsgFlags::empty()).map_err(io::Error::from)?;
            return if n == CAN_MTU {
                Ok(1)
            } else {
                Err(io::Error::new(
                    io::ErrorKind::WriteZero,
                    format!("short write: {n} of {CAN_MTU} bytes"),
                ))
            };
        }
        with_headers(|[_, h]| {
            let slices: heapless::Vec<[IoSlice<'_>; 1], BATCH> =
                frames.iter().map(|b| [IoSlice::new(b)]).collect();
            let addrs = [None::<()>; BATCH];
            let sent =
                sendmmsg(fd, h, &slices, addrs, [], MsgFlags::empty()).map_err(io::Error::from)?;
            Ok(sent.count())
        })
    }

    /// The next input of the last batch, if one is left.
    fn next_in_batch(&mut self) -> Option<PortInput> {
        loop {
            if let Some(x) = self.rx.status() {
                return Some(x);
            }
            if self.next >= self.got {
                return None;
            }
            let i = self.next;
            self.next += 1;
            if self.own {
                return Some(PortInput::Status(PortStatus::TxOk));
            }
            let raw = &self.raw[i][..self.len[i].min(CAN_MTU)];
            if let Some(x) = self.rx.accept_kernel(&self.ifname, raw, self.at[i]) {
                return Some(x);
            }
        }
    }
}

impl Drop for Reader {
    fn drop(&mut self) {
        // Frames kept and never sent (the thread stopped first) are counted, not forgotten.
        for _ in self.tx_sent..self.tx_len {
            self.rx.counters.tx_dropped();
        }
    }
}

impl PortReader for Reader {
    fn read(&mut self) -> Result<Option<PortInput>, PortError> {
        loop {
            if let Some(x) = self.next_in_batch() {
                return Ok(Some(x));
            }
            match self.fill() {
                Ok(()) => {}
                Err(e) if timed_out(&e) => return Ok(None),
                Err(e) => return Err(PortError::io(&self.ifname, "read failed", e)),
            }
        }
    }

    fn read_ready(&mut self) -> Option<PortInput> {
        self.next_in_batch()
    }

    fn write(&mut self, frame: &Frame) -> Result<bool, PortError> {
        if self.tx_len == BATCH && !self.flush()? {
            return Ok(false);
        }
        self.tx[self.tx_len] = can_frame_bytes(frame);
        self.tx_len += 1;
        Ok(true)
    }

    fn flush(&mut self) -> Result<bool, PortError> {
        while self.tx_sent < self.tx_len {
            match self.send_batch() {
                Ok(0) => return Ok(false),
                Ok(n) => {
                    let n = n.min(self.tx_len - self.tx_sent);
                    for _ in 0..n {
                        let _ = self.rx.sent(&self.ifname, Ok(()));
                    }
                    self.tx_sent += n;
                }
                Err(e) if timed_out(&e) => return Ok(false),
                Err(e) => {
                    // The frame the kernel refused is dropped; the rest are tried next time,
                    // unless the interface is gone.
                    self.tx_sent += 1;
                    let Err((e, gone)) = self.rx.sent(&self.ifname, Err(e)) else {
                        continue;
                    };
                    if gone {
                        for _ in self.tx_sent..self.tx_len {
                            self.rx.counters.tx_dropped();
                        }
                        self.tx_sent = self.tx_len;
                    }
                    if self.tx_sent == self.tx_len {
                        self.tx_len = 0;
                        self.tx_sent = 0;
                    }
                    return Err(e);
                }
            }
        }
        self.tx_len = 0;
        self.tx_sent = 0;
        Ok(true)
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
    let mut id = match f.id() {
        Id::Standard(x) => u32::from(x),
        Id::Extended(x) => x | CAN_EFF_FLAG,
    };
    if f.is_remote() {
        id |= CAN_RTR_FLAG;
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
        fn the_frame_sent_without_waiting_is_the_kernels(f in crate::frame::arbitrary::any_frame()) {
            let b = can_frame_bytes(&f);
            let c = crate::port::socketcan::socketcan_frame(&f);
            prop_assert_eq!(u32::from_ne_bytes([b[0], b[1], b[2], b[3]]), c.id_word());
            prop_assert_eq!(usize::from(b[4]), c.dlc());
            prop_assert_eq!(&b[8..8 + f.data().len()], EmbeddedFrame::data(&c));
        }

        /// A frame read in a batch is the frame sent, counted as one.
        #[test]
        fn a_kernel_frame_reads_back_as_the_frame(f in crate::frame::arbitrary::any_frame()) {
            let mut rx = rx();
            prop_assert_eq!(
                rx.accept_kernel("vcan0", &can_frame_bytes(&f), None),
                Some(PortInput::Frame(f, None))
            );
            prop_assert_eq!(rx.counters.snapshot().rx_frames, 1);
        }

        /// An error frame read in a batch gives the statuses the socketcan crate's own error
        /// frame gives, and no frame.
        #[test]
        fn a_kernel_error_frame_reads_as_the_crates(bits in 0u32..0x200, data in any::<[u8; 8]>()) {
            let mut raw = [0u8; 16];
            raw[..4].copy_from_slice(&(bits | crate::port::error_frame::CAN_ERR_FLAG).to_ne_bytes());
            raw[4] = 8;
            raw[8..].copy_from_slice(&data);
            let mut rx = rx();
            prop_assert_eq!(rx.accept_kernel("vcan0", &raw, None), None);
            let want = super::super::decode_error_frame(
                &socketcan::CanErrorFrame::new_error(bits, &data).unwrap(),
            );
            prop_assert_eq!(&rx.pending, &want);
            prop_assert_eq!(rx.counters.snapshot().rx_error_frames, 1);
        }
    }

    fn rx() -> RxState {
        RxState {
            counters: crate::port::PortCounters::new(),
            pending: Default::default(),
        }
    }

    /// What is not a classic frame's 16 bytes (a CAN FD frame's 72) is counted, not read.
    #[test]
    fn a_kernel_frame_of_another_size_is_refused() {
        let mut rx = rx();
        assert_eq!(rx.accept_kernel("vcan0", &[0u8; 72], None), None);
        assert_eq!(rx.accept_kernel("vcan0", &[0u8; 15], None), None);
        assert_eq!(rx.counters.snapshot().rx_invalid, 2);
        assert_eq!(rx.counters.snapshot().rx_frames, 0);
    }
}
