//! The client's side of a transfer past its request: each answer of the server, checked
//! against the transfer's state, session, object, toggle and sizes.

use super::{State, UsdoClient};
use crate::cia1301::usdo::answer_id;
use crate::cia1301::usdo::codec::{Msg, Usdo, UsdoDecodeError};
use crate::cia1301::usdo::event::UsdoErrorKind;
use crate::cia301::sdo::TransferBuffer;
use crate::frame::fd::FdFrame;
use crate::frame::instant::Instant;
use crate::od::abort::AbortCode;

impl<B: TransferBuffer> UsdoClient<B> {
    /// A frame from the bus: an answer to the running transfer is taken, anything else
    /// ignored.
    pub fn handle_frame(&mut self, now: Instant, frame: &FdFrame) {
        let Some(t) = self.t.filter(|t| frame.id() == answer_id(t.server)) else {
            return;
        };
        let ours = |dest: u8, session: u8| dest == self.node.raw() && session == t.session;
        let msg = match Usdo::decode(frame.data()) {
            Ok(u) if ours(u.dest, u.session) => u.msg,
            Err(UsdoDecodeError::Bad {
                dest,
                session,
                code,
            }) if ours(dest, session) => {
                return self.fail(now, code);
            }
            _ => {
                self.stats.ignored += 1;
                return;
            }
        };
        if matches!(
            msg,
            Msg::DownloadSegmentAck { .. } | Msg::UploadSegmentData { .. }
        ) {
            // Two segment answers in a row differ (the toggle alternates): an equal one is a
            // second copy, such as the dual-bus layer's late twin.
            if self.last == Some(*frame) {
                self.stats.repeats += 1;
                return;
            }
            self.last = Some(*frame);
        }
        if let Some(t) = &mut self.t {
            t.deadline = now + t.timeout;
        }
        let same = |index: u16, sub: u8| (index, sub) == (t.index, t.sub);
        match (t.state, msg) {
            (_, Msg::Abort { code, .. }) => self.end(now, Err(UsdoErrorKind::Server(code))),
            (State::DownloadExpedited | State::DownloadInit, Msg::DownloadAck { index, sub })
                if !same(index, sub) =>
            {
                self.fail(now, AbortCode::PARAMETER_INCOMPATIBLE)
            }
            (State::DownloadExpedited, Msg::DownloadAck { .. }) => self.end(now, Ok(())),
            (State::DownloadInit, Msg::DownloadAck { .. }) => self.next_segment(false, 0),
            (State::Download { toggle, end, .. }, Msg::DownloadSegmentAck { toggle: a }) => {
                if a != toggle {
                    self.fail(now, AbortCode::TOGGLE_BIT)
                } else if end == self.buf.len() {
                    self.end(now, Ok(()))
                } else {
                    self.next_segment(!toggle, end)
                }
            }
            (
                State::UploadInit,
                Msg::UploadExpedited {
                    index, sub, data, ..
                },
            ) => {
                if !same(index, sub) {
                    return self.fail(now, AbortCode::PARAMETER_INCOMPATIBLE);
                }
                if data.bytes().len() > self.limit || !self.buf.extend(data.bytes()) {
                    return self.fail(now, AbortCode::OUT_OF_MEMORY);
                }
                self.end(now, Ok(()))
            }
            (
                State::UploadInit,
                Msg::UploadSegmented {
                    index, sub, size, ..
                },
            ) => {
                let size = size as usize;
                if !same(index, sub) {
                    return self.fail(now, AbortCode::PARAMETER_INCOMPATIBLE);
                }
                if size > self.limit {
                    return self.fail(now, AbortCode::OUT_OF_MEMORY);
                }
                self.buf.reserve(size);
                self.set_state(State::Upload {
                    toggle: false,
                    size,
                });
                self.send(Msg::UploadSegment { toggle: false });
            }
            (
                State::Upload { toggle, size },
                Msg::UploadSegmentData {
                    toggle: a,
                    last,
                    data,
                },
            ) => {
                let bytes = data.bytes();
                if a != toggle {
                    return self.fail(now, AbortCode::TOGGLE_BIT);
                }
                if self.buf.len() + bytes.len() > size || !self.buf.extend(bytes) {
                    return self.fail(now, AbortCode::LENGTH_TOO_HIGH);
                }
                if !last {
                    self.set_state(State::Upload {
                        toggle: !toggle,
                        size,
                    });
                    return self.send(Msg::UploadSegment { toggle: !toggle });
                }
                if self.buf.len() < size {
                    return self.fail(now, AbortCode::LENGTH_TOO_LOW);
                }
                self.end(now, Ok(()))
            }
            _ => self.fail(now, AbortCode::COMMAND_SPECIFIER),
        }
    }
}
