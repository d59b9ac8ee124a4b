//! The server's transfers past their first frame: a read's answer (expedited, or the start of
//! segments from a snapshot), each segment either way, and the checks a write's target passes.

use super::{Phase, UsdoServer};
use crate::cia1301::usdo::codec::{Msg, UsdoPayload, EXPEDITED_MAX, SEGMENT_MAX};
use crate::cia301::sdo::TransferBuffer;
use crate::frame::instant::Instant;
use crate::od::abort::AbortCode;
use crate::od::ObjectAccess;

impl<B: TransferBuffer, const SESSIONS: usize> UsdoServer<B, SESSIONS> {
    #[allow(clippy::too_many_arguments)]
    pub(super) fn upload<A: ObjectAccess + ?Sized>(
        &mut self,
        now: Instant,
        c: u8,
        session: u8,
        index: u16,
        sub: u8,
        broadcast: bool,
        od: &A,
    ) {
        let r = od.read(index, sub).and_then(|v| {
            let ty = od.entry(index, sub)?.def.data_type as u8;
            Ok((v, ty))
        });
        let (value, data_type) = match r {
            Ok(x) => x,
            Err(code) => return self.abort(c, session, index, sub, code),
        };
        if let Some(data) = UsdoPayload::new(value).filter(|_| value.len() <= EXPEDITED_MAX) {
            self.stats.completed += 1;
            return self.send(
                c,
                session,
                Msg::UploadExpedited {
                    index,
                    sub,
                    data_type,
                    data,
                },
            );
        }
        if broadcast {
            return self.abort(c, session, index, sub, AbortCode::UNSUPPORTED_ACCESS);
        }
        let Some(i) = self.take(now, c, session, index, sub) else {
            return;
        };
        // A snapshot: the client reads one consistent value even if the entry changes.
        let s = &mut self.slots[i];
        if value.len() > s.buf.limit() {
            return self.abort_slot(i, AbortCode::OUT_OF_MEMORY);
        }
        s.buf.reserve(value.len());
        if !s.buf.extend(value) {
            return self.abort_slot(i, AbortCode::OUT_OF_MEMORY);
        }
        s.phase = Some(Phase::Upload {
            toggle: false,
            offset: 0,
        });
        let size = value.len() as u32;
        self.send(
            c,
            session,
            Msg::UploadSegmented {
                index,
                sub,
                data_type,
                size,
            },
        );
    }

    /// A segment request or a download segment (`Some((last, data))`) in `session`.
    pub(super) fn segment<A: ObjectAccess + ?Sized>(
        &mut self,
        now: Instant,
        c: u8,
        session: u8,
        toggle: bool,
        down: Option<(bool, UsdoPayload)>,
        od: &mut A,
    ) {
        let Some(i) = self
            .slot_of(c)
            .filter(|&i| self.slots[i].session == session)
        else {
            return self.abort(c, session, 0, 0, AbortCode::COMMAND_SPECIFIER);
        };
        let s = &mut self.slots[i];
        s.deadline = Some(now + self.timeout);
        match (s.phase, down) {
            (Some(Phase::Download { toggle: t, size }), Some((last, data))) => {
                if t != toggle {
                    return self.abort_slot(i, AbortCode::TOGGLE_BIT);
                }
                if s.buf.len() + data.bytes().len() > size {
                    return self.abort_slot(i, AbortCode::LENGTH_TOO_HIGH);
                }
                if !s.buf.extend(data.bytes()) {
                    return self.abort_slot(i, AbortCode::OUT_OF_MEMORY);
                }
                if !last {
                    s.phase = Some(Phase::Download { toggle: !t, size });
                    return self.send(c, session, Msg::DownloadSegmentAck { toggle });
                }
                if s.buf.len() < size {
                    return self.abort_slot(i, AbortCode::LENGTH_TOO_LOW);
                }
                let (index, sub) = (s.index, s.sub);
                let r = od.write(now, index, sub, s.buf.as_slice());
                self.free(i);
                self.finish(
                    c,
                    session,
                    index,
                    sub,
                    r,
                    Msg::DownloadSegmentAck { toggle },
                );
            }
            (Some(Phase::Upload { toggle: t, offset }), None) => {
                if t != toggle {
                    return self.abort_slot(i, AbortCode::TOGGLE_BIT);
                }
                let len = s.buf.len();
                let end = (offset + SEGMENT_MAX).min(len);
                let Some(data) = UsdoPayload::new(&s.buf.as_slice()[offset..end]) else {
                    return self.abort_slot(i, AbortCode::GENERAL);
                };
                let last = end == len;
                s.phase = Some(Phase::Upload {
                    toggle: !t,
                    offset: end,
                });
                if last {
                    self.stats.completed += 1;
                    self.free(i);
                }
                self.send(c, session, Msg::UploadSegmentData { toggle, last, data });
            }
            _ => self.abort_slot(i, AbortCode::COMMAND_SPECIFIER),
        }
    }
}

/// A data type given (not 0) must be the entry's.
pub(super) fn check_type<A: ObjectAccess + ?Sized>(
    od: &A,
    index: u16,
    sub: u8,
    ty: u8,
) -> Result<(), AbortCode> {
    if ty != 0 && od.entry(index, sub)?.def.data_type as u8 != ty {
        return Err(AbortCode::TYPE_MISMATCH);
    }
    Ok(())
}

/// A segmented download's target: it exists, is writable from the bus, and holds `size` bytes.
pub(super) fn check_target<A: ObjectAccess + ?Sized>(
    od: &A,
    index: u16,
    sub: u8,
    size: usize,
) -> Result<(), AbortCode> {
    let e = od.entry(index, sub)?;
    if !e.def.access.writable() {
        return Err(AbortCode::READ_ONLY);
    }
    match e.def.data_type.fixed_size() {
        Some(n) if size > n => Err(AbortCode::LENGTH_TOO_HIGH),
        Some(n) if size < n => Err(AbortCode::LENGTH_TOO_LOW),
        None if size > e.def.storage_size() => Err(AbortCode::LENGTH_TOO_HIGH),
        _ => Ok(()),
    }
}
