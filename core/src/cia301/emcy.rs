//! Emergency objects: producer (0x1014 COB-ID, 0x1015 inhibit in 100 µs, 0x1001 error register,
//! 0x1003 history kept by the node) and consumer decoding.
//!
//! **The CAN FD form (feature `fd`).** CANopen FD (CiA 1301) gives the EMCY message a longer
//! form with further fields. Their exact layout is not taken here: no public source of it was
//! at hand, and a layout guessed field by field would be wrong in a way no test here could
//! show. What is built is the conservative form that any reading of it must accept: a node on
//! a CANopen FD network sends the classic eight bytes (error code, error register, five
//! manufacturer bytes, [`EmcyMessage::to_bytes`]) in a CAN FD frame of 8 bytes, and a
//! consumer decodes a CAN FD EMCY of at least 8 bytes by those same first eight bytes
//! ([`EmcyMessage::from_fd_frame`]), handing back the bytes after them uninterpreted (at most
//! 56: the frame's, nothing is copied) for an application that knows their layout. A shorter
//! one is malformed, as a classic EMCY of another length than 8 is.

use crate::cia301::service::ServiceOutput;
use crate::frame::cob_id::CobId;
use crate::frame::instant::{shift_back, Duration, Instant};
use crate::frame::queue::Bounded;
#[cfg(feature = "fd")]
use crate::frame::FdFrame;
use crate::frame::Malformed;
use crate::frame::{Frame, Id};

/// Error register (0x1001) bits.
pub mod register {
    /// Generic error: set whenever any error is active.
    pub const GENERIC: u8 = 0x01;
    /// Current.
    pub const CURRENT: u8 = 0x02;
    /// Voltage.
    pub const VOLTAGE: u8 = 0x04;
    /// Temperature.
    pub const TEMPERATURE: u8 = 0x08;
    /// Communication error (overrun, error state).
    pub const COMMUNICATION: u8 = 0x10;
    /// Device profile specific.
    pub const PROFILE: u8 = 0x20;
    /// Manufacturer specific.
    pub const MANUFACTURER: u8 = 0x80;
}

/// Standard error codes the stack itself raises.
pub mod code {
    /// Error reset or no error.
    pub const NO_ERROR: u16 = 0x0000;
    /// Generic error.
    pub const GENERIC: u16 = 0x1000;
    /// CAN overrun (objects lost).
    pub const CAN_OVERRUN: u16 = 0x8110;
    /// CAN in error passive mode.
    pub const CAN_PASSIVE: u16 = 0x8120;
    /// Life guard error or heartbeat error.
    pub const LIFE_GUARD: u16 = 0x8130;
    /// Recovered from bus-off.
    pub const BUS_OFF_RECOVERED: u16 = 0x8140;
    /// PDO not processed due to length error.
    pub const PDO_LENGTH: u16 = 0x8210;
    /// PDO length exceeded.
    pub const PDO_LENGTH_EXCEEDED: u16 = 0x8220;
    /// Unexpected SYNC data length.
    pub const SYNC_LENGTH: u16 = 0x8240;
    /// RPDO timeout.
    pub const RPDO_TIMEOUT: u16 = 0x8250;
    /// Data set error: a configuration the device needs is wrong (the SRDOs', CiA 304, when
    /// the node refuses operational).
    pub const DATA_SET: u16 = 0x6300;
}

/// One EMCY message: error code, error register, five manufacturer bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct EmcyMessage {
    /// Error code (0x0000 = error reset).
    pub code: u16,
    /// Error register (0x1001) at the time of the message.
    pub register: u8,
    /// Manufacturer-specific bytes.
    pub data: [u8; 5],
}

impl EmcyMessage {
    /// The eight bytes on the wire.
    pub fn to_bytes(&self) -> [u8; 8] {
        let c = self.code.to_le_bytes();
        let d = self.data;
        [c[0], c[1], self.register, d[0], d[1], d[2], d[3], d[4]]
    }
    /// What the error code means, as CiA 301's table of standard codes names it (the class
    /// for codes the table lists only by their first digits): [`code_text`].
    #[must_use]
    pub fn text(&self) -> &'static str {
        code_text(self.code)
    }
    /// True for an error reset (code 0x0000: the node's errors are gone).
    #[must_use]
    pub fn is_reset(&self) -> bool {
        self.code >> 8 == 0
    }
    /// Decodes a received EMCY frame (exactly 8 data bytes).
    pub fn from_frame(frame: &Frame) -> Result<EmcyMessage, Malformed> {
        if frame.is_remote() {
            return Err(Malformed::UnexpectedRemote);
        }
        match frame.data() {
            [c0, c1, reg, d @ ..] if d.len() == 5 => Ok(EmcyMessage {
                code: u16::from_le_bytes([*c0, *c1]),
                register: *reg,
                data: [d[0], d[1], d[2], d[3], d[4]],
            }),
            d => Err(Malformed::WrongLength {
                expected: 8,
                got: d.len() as u8,
            }),
        }
    }
}

#[cfg(feature = "fd")]
impl EmcyMessage {
    /// Decodes a received CAN FD EMCY (feature `fd`): the classic eight bytes first, then the
    /// rest of the frame, uninterpreted (empty for an 8-byte frame). Fewer than 8 bytes are
    /// [`Malformed::WrongLength`].
    pub fn from_fd_frame(frame: &FdFrame) -> Result<(EmcyMessage, &[u8]), Malformed> {
        match frame.data() {
            [c0, c1, reg, d0, d1, d2, d3, d4, rest @ ..] => Ok((
                EmcyMessage {
                    code: u16::from_le_bytes([*c0, *c1]),
                    register: *reg,
                    data: [*d0, *d1, *d2, *d3, *d4],
                },
                rest,
            )),
            d => Err(Malformed::WrongLength {
                expected: 8,
                got: d.len() as u8,
            }),
        }
    }
}

/// The meaning of an EMCY error code by CiA 301's table of standard codes: the exact entry
/// where the table has one (0x8130 "life guard or heartbeat error"), else the class its high
/// digits name (0x2310 "current, device output side"), else "device specific" (0xFFxx) or
/// "unknown error code".
#[must_use]
pub const fn code_text(code: u16) -> &'static str {
    match code {
        0x0000..=0x00FF => "error reset or no error",
        0x8110 => "CAN overrun (objects lost)",
        0x8120 => "CAN in error passive mode",
        0x8130 => "life guard or heartbeat error",
        0x8140 => "recovered from bus off",
        0x8150 => "CAN-ID collision",
        0x8210 => "PDO not processed due to length error",
        0x8220 => "PDO length exceeded",
        0x8230 => "DAM MPDO not processed, destination object not available",
        0x8240 => "unexpected SYNC data length",
        0x8250 => "RPDO timeout",
        _ => match code >> 8 {
            0x10 => "generic error",
            0x20 => "current",
            0x21 => "current, device input side",
            0x22 => "current inside the device",
            0x23 => "current, device output side",
            0x30 => "voltage",
            0x31 => "mains voltage",
            0x32 => "voltage inside the device",
            0x33 => "output voltage",
            0x40 => "temperature",
            0x41 => "ambient temperature",
            0x42 => "device temperature",
            0x50 => "device hardware",
            0x60 => "device software",
            0x61 => "internal software",
            0x62 => "user software",
            0x63 => "data set",
            0x70 => "additional modules",
            0x80 => "monitoring",
            0x81 => "communication",
            0x82 => "protocol error",
            0x90 => "external error",
            0xF0 => "additional functions",
            0xFF => "device specific",
            _ => "unknown error code",
        },
    }
}

/// The EMCY producer: active errors, the error register they imply, and the inhibit-timed
/// transmit queue.
#[derive(Debug, Default)]
pub struct EmcyProducer {
    id: Option<Id>,
    inhibit: Duration,
    last_sent: Option<Instant>,
    pending: Bounded<EmcyMessage, 8>,
    active: heapless::Vec<(u16, u8), 8>,
}

impl EmcyProducer {
    /// Applies 0x1014 and 0x1015 (inhibit in 100 µs units).
    pub fn configure(&mut self, cob: CobId, inhibit_100us: u16) {
        self.id = if cob.is_valid() { cob.can_id() } else { None };
        self.inhibit = Duration::from_micros(inhibit_100us as u64 * 100);
    }

    /// The error register implied by the active errors.
    pub fn register(&self) -> u8 {
        let bits = self.active.iter().fold(0, |acc, (_, r)| acc | r);
        if self.active.is_empty() {
            0
        } else {
            bits | register::GENERIC
        }
    }

    /// Records an active error and queues its message. Returns the message (for the history), or
    /// `None` if the same code is already active (no repeated EMCY for a standing error).
    pub fn raise(&mut self, code: u16, register_bits: u8, data: [u8; 5]) -> Option<EmcyMessage> {
        if self.active.iter().any(|(c, _)| *c == code) {
            return None;
        }
        if self.active.push((code, register_bits)).is_err() {
            // Table full: the error is still reported, and GENERIC stays set via the others.
        }
        let msg = EmcyMessage {
            code,
            register: self.register(),
            data,
        };
        self.pending.push(msg);
        Some(msg)
    }

    /// Clears an active error; when none remain, queues the error-reset message (code 0x0000).
    /// Returns true if `code` was active.
    pub fn clear(&mut self, code: u16) -> bool {
        let before = self.active.len();
        self.active.retain(|(c, _)| *c != code);
        if self.active.len() == before {
            return false;
        }
        if self.active.is_empty() {
            self.pending.push(EmcyMessage {
                code: code::NO_ERROR,
                register: 0,
                data: [0; 5],
            });
        }
        true
    }

    /// Active error codes.
    pub fn active(&self) -> impl Iterator<Item = u16> + '_ {
        self.active.iter().map(|(c, _)| *c)
    }

    /// Messages dropped because the queue was full.
    pub fn dropped(&self) -> u32 {
        self.pending.dropped()
    }

    /// Next frame if the inhibit time allows it at `now`.
    #[must_use]
    pub fn poll_frame(&mut self, now: Instant) -> Option<Frame> {
        if self.pending.is_empty() || self.id.is_none() {
            return None;
        }
        if let Some(last) = self.last_sent {
            if now < last + self.inhibit {
                return None;
            }
        }
        let msg = self.pending.pop()?;
        self.last_sent = Some(now);
        Some(Frame::from_array(self.id?, msg.to_bytes()))
    }

    /// Sends every waiting message the inhibit time lets go at `now`, if the NMT state allows
    /// EMCY (otherwise they wait); on a CANopen FD network (feature `fd`) in CAN FD frames.
    pub fn handle_timeout<O: ServiceOutput>(&mut self, now: Instant, out: &mut O) {
        if !out.nmt_state().services().emcy {
            return;
        }
        while let Some(f) = self.poll_frame(now) {
            #[cfg(feature = "fd")]
            if out.fd_network() {
                // A data frame of 8 bytes: always a CAN FD frame.
                if let Ok(fd) = FdFrame::try_from(f) {
                    out.send_fd(fd);
                }
                continue;
            }
            out.send(f);
        }
    }

    /// The caller's clock stepped back `by` (the clock contract, [`crate::frame::instant`]).
    pub fn step_back(&mut self, by: Duration) {
        shift_back(&mut self.last_sent, by);
    }

    /// When the inhibit time lets the next waiting message go.
    #[must_use]
    pub fn poll_timeout(&self) -> Option<Instant> {
        if self.pending.is_empty() || self.id.is_none() {
            return None;
        }
        Some(self.last_sent.map_or(Instant::ZERO, |l| l + self.inhibit))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn standard_codes_have_their_text() {
        assert_eq!(code_text(0x8250), "RPDO timeout");
        assert_eq!(code_text(0x2310), "current, device output side");
        assert_eq!(code_text(0x8199), "communication");
        assert_eq!(code_text(0xFF42), "device specific");
        assert_eq!(code_text(0xA000), "unknown error code");
        let m = EmcyMessage {
            code: 0,
            register: 0,
            data: [0; 5],
        };
        assert!(m.is_reset());
        assert_eq!(m.text(), "error reset or no error");
    }

    #[test]
    fn frame_layout_byte_for_byte() {
        let m = EmcyMessage {
            code: 0x8130,
            register: 0x11,
            data: [1, 2, 3, 4, 5],
        };
        assert_eq!(m.to_bytes(), [0x30, 0x81, 0x11, 1, 2, 3, 4, 5]);
        let f = Frame::from_array(Id::Standard(0x85), m.to_bytes());
        assert_eq!(EmcyMessage::from_frame(&f), Ok(m));
        let short = Frame::new(Id::Standard(0x85), &[0x30, 0x81]).unwrap();
        assert_eq!(
            EmcyMessage::from_frame(&short),
            Err(Malformed::WrongLength {
                expected: 8,
                got: 2
            })
        );
    }

    #[cfg(feature = "fd")]
    #[test]
    fn the_can_fd_form_is_the_classic_eight_bytes_then_the_rest_uninterpreted() {
        use crate::cia301::nmt::NmtState;
        use crate::cia301::service::Recorder;
        let m = EmcyMessage {
            code: 0x8210,
            register: 0x11,
            data: [1, 0, 0, 0, 0],
        };
        let mut bytes = [0xEE; 20];
        bytes[..8].copy_from_slice(&m.to_bytes());
        let f = FdFrame::new(Id::Standard(0x85), &bytes).unwrap();
        assert_eq!(EmcyMessage::from_fd_frame(&f), Ok((m, &[0xEE; 12][..])));
        let short = FdFrame::new(Id::Standard(0x85), &bytes[..7]).unwrap();
        assert_eq!(
            EmcyMessage::from_fd_frame(&short),
            Err(Malformed::WrongLength {
                expected: 8,
                got: 7
            })
        );
        // A producer on a CANopen FD network sends it in a CAN FD frame of 8 bytes.
        let mut p = EmcyProducer::default();
        p.configure(CobId(0x85), 0);
        p.raise(0x8210, register::COMMUNICATION, [1, 0, 0, 0, 0]);
        let mut out = Recorder::new(NmtState::Operational);
        out.fd = true;
        p.handle_timeout(Instant::ZERO, &mut out);
        assert!(out.frames.is_empty());
        assert_eq!(out.fd_frames.len(), 1);
        assert_eq!(out.fd_frames[0].data(), &m.to_bytes());
    }

    #[test]
    fn inhibit_time_spaces_messages() {
        let mut p = EmcyProducer::default();
        p.configure(CobId(0x85), 10); // 1 ms
        p.raise(0x1000, 0, [0; 5]);
        p.raise(0x8130, register::COMMUNICATION, [0; 5]);
        let t0 = Instant::from_millis(5);
        assert!(p.poll_frame(t0).is_some());
        assert!(p.poll_frame(t0).is_none());
        assert_eq!(p.poll_timeout(), Some(Instant::from_millis(6)));
        let f = p.poll_frame(Instant::from_millis(6)).unwrap();
        assert_eq!(f.data()[2], register::GENERIC | register::COMMUNICATION);
    }

    #[test]
    fn timeout_sends_what_the_inhibit_time_allows_and_nothing_when_stopped() {
        use crate::cia301::nmt::NmtState;
        use crate::cia301::service::Recorder;
        let mut p = EmcyProducer::default();
        p.configure(CobId(0x85), 10); // 1 ms
        p.raise(0x1000, 0, [0; 5]);
        p.raise(0x8130, register::COMMUNICATION, [0; 5]);
        let mut out = Recorder::new(NmtState::Stopped);
        p.handle_timeout(Instant::ZERO, &mut out);
        assert!(out.frames.is_empty(), "stopped: EMCY waits");
        let mut out = Recorder::new(NmtState::Operational);
        p.handle_timeout(Instant::ZERO, &mut out);
        assert_eq!(out.frames.len(), 1, "the inhibit time holds the second");
        p.handle_timeout(Instant::from_millis(1), &mut out);
        assert_eq!(out.frames.len(), 2);
        assert!(out.events.is_empty());
    }

    #[test]
    fn clearing_the_last_error_sends_error_reset() {
        let mut p = EmcyProducer::default();
        p.configure(CobId(0x85), 0);
        p.raise(0x1000, 0, [0; 5]);
        assert!(
            p.raise(0x1000, 0, [0; 5]).is_none(),
            "standing error is not repeated"
        );
        p.poll_frame(Instant::ZERO).unwrap();
        assert!(p.clear(0x1000));
        assert_eq!(p.register(), 0);
        let f = p.poll_frame(Instant::ZERO).unwrap();
        assert_eq!(f.data(), &[0, 0, 0, 0, 0, 0, 0, 0]);
    }
}
