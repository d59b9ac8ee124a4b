//! What a port task is to do: the commands queued for it, and the batch it takes of them at
//! once ([`Outbox`]), CAN FD frames beside the commands that stand for them.

use crate::frame::{FdFrame, Frame};
use crate::machine::PortRequest;
use std::collections::VecDeque;

/// What a port task does besides reading: write a frame, re-initialise the port.
///
/// A CAN FD frame is not carried here: it waits in a queue of its own (72 bytes a frame), and
/// [`PortCmd::SendFd`] only keeps its place among the other commands, so that a classic
/// command stays as small as a classic frame.
#[derive(Debug)]
pub(crate) enum PortCmd {
    Send(Frame),
    /// Send the oldest CAN FD frame of the port's FD queue (moved along with this command).
    SendFd,
    Request(PortRequest),
}

/// CAN FD frames a port task takes from its FD queue at once.
const FD_BATCH: usize = 8;

/// A port task's batch of work taken from its queue (fixed size: no allocation per frame): the
/// commands, and the CAN FD frames their [`PortCmd::SendFd`] stand for, in the same order.
pub(crate) struct Outbox {
    cmds: heapless::Deque<PortCmd, 32>,
    fd: heapless::Deque<FdFrame, FD_BATCH>,
}

impl Outbox {
    pub const fn new() -> Self {
        Outbox {
            cmds: heapless::Deque::new(),
            fd: heapless::Deque::new(),
        }
    }
    pub fn is_empty(&self) -> bool {
        self.cmds.is_empty()
    }
    pub fn is_full(&self) -> bool {
        self.cmds.is_full()
    }
    /// Adds a command that is not [`PortCmd::SendFd`] (that one comes with its frame:
    /// [`Outbox::push_fd`]).
    pub fn push_back(&mut self, cmd: PortCmd) -> Result<(), PortCmd> {
        self.cmds.push_back(cmd)
    }
    /// Adds a [`PortCmd::SendFd`] and its frame; the frame back if there is no room.
    pub fn push_fd(&mut self, f: FdFrame) -> Result<(), FdFrame> {
        if self.cmds.is_full() || self.fd.is_full() {
            return Err(f);
        }
        let _ = self.fd.push_back(f);
        let _ = self.cmds.push_back(PortCmd::SendFd);
        Ok(())
    }
    /// Room for a [`PortCmd::SendFd`] and its frame.
    pub fn has_fd_room(&self) -> bool {
        !self.cmds.is_full() && !self.fd.is_full()
    }
    pub fn pop_front(&mut self) -> Option<PortCmd> {
        self.cmds.pop_front()
    }
    /// The frame of the [`PortCmd::SendFd`] just popped.
    pub fn pop_fd(&mut self) -> Option<FdFrame> {
        self.fd.pop_front()
    }
}

/// Moves the frames at the head of `q` (up to its first other command) into `into`, as many as
/// it has room for; true when something is left in `q`.
pub(super) fn take_frames(q: &mut VecDeque<PortCmd>, into: &mut Outbox) -> Option<bool> {
    while !into.is_full() && matches!(q.front(), Some(PortCmd::Send(_))) {
        if let Some(c) = q.pop_front() {
            let _ = into.push_back(c);
        }
    }
    Some(!q.is_empty())
}

/// Moves the oldest of `q` into `into`, as many as it has room for; a [`PortCmd::SendFd`]
/// takes its frame, the oldest of `fd`, along.
pub(crate) fn move_into(q: &mut VecDeque<PortCmd>, fd: &mut VecDeque<FdFrame>, into: &mut Outbox) {
    while move_one(q, fd, into) {}
}

/// Moves the oldest of `q` into `into` if it has room for it; false if not (or `q` is empty).
pub(super) fn move_one(
    q: &mut VecDeque<PortCmd>,
    fd: &mut VecDeque<FdFrame>,
    into: &mut Outbox,
) -> bool {
    match q.front() {
        None => false,
        Some(PortCmd::SendFd) => {
            if !into.has_fd_room() {
                return false;
            }
            q.pop_front();
            // Queued together: a command without its frame is a frame dropped already.
            if let Some(f) = fd.pop_front() {
                let _ = into.push_fd(f);
            }
            true
        }
        Some(_) => {
            if into.is_full() {
                return false;
            }
            if let Some(c) = q.pop_front() {
                let _ = into.push_back(c);
            }
            true
        }
    }
}
