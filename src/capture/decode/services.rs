//! The small services: NMT, SYNC, TIME, EMCY, error control, LSS and the flying master.

use super::frames::{DecodedFrame, Hex};
use super::kind::{FlyingMasterFrame, Kind};
use crate::cia301::emcy::EmcyMessage;
use crate::cia301::nmt::{NmtCommand, NmtState, NmtTarget};
use crate::frame::cob_id::NodeId;
use crate::frame::Frame;
use core::fmt;

/// A [`DecodedFrame::Malformed`].
pub(super) fn bad(kind: Kind, node: Option<NodeId>, problem: String) -> DecodedFrame {
    DecodedFrame::Malformed {
        kind,
        node,
        problem,
    }
}

/// `2 bytes, a heartbeat has 1 (05 00)`, or the remote frame named.
pub(super) fn wrong_length(frame: &Frame, what: &str, expected: &str) -> String {
    if frame.is_remote() {
        return format!("remote frame, {what} carries data");
    }
    let n = frame.data().len();
    let unit = if n == 1 { "byte" } else { "bytes" };
    let bytes = match n {
        0 => String::new(),
        _ => format!(" ({})", Hex(frame.data())),
    };
    format!("{n} {unit}, {what} has {expected}{bytes}")
}

/// The NMT command and target of a two-byte payload.
pub(super) fn nmt_payload(d: &[u8]) -> Result<(NmtCommand, NmtTarget), String> {
    let [cs, node] = d else {
        return Err(format!("{} bytes, an NMT command has 2", d.len()));
    };
    let command = NmtCommand::from_code(*cs)
        .ok_or_else(|| format!("command specifier {cs:#04x} is no NMT command"))?;
    let target = match node {
        0 => NmtTarget::All,
        n => {
            NmtTarget::Node(NodeId::new(*n).ok_or_else(|| format!("node-ID {n} is outside 1-127"))?)
        }
    };
    Ok((command, target))
}

pub(super) fn nmt(frame: &Frame) -> DecodedFrame {
    if frame.is_remote() || frame.data().len() != 2 {
        return bad(Kind::Nmt, None, wrong_length(frame, "an NMT command", "2"));
    }
    match nmt_payload(frame.data()) {
        Ok((command, target)) => DecodedFrame::Nmt { command, target },
        Err(problem) => bad(Kind::Nmt, None, problem),
    }
}

pub(super) fn sync(frame: &Frame) -> DecodedFrame {
    match (frame.is_remote(), frame.data()) {
        (false, []) => DecodedFrame::Sync { counter: None },
        (false, [c]) => DecodedFrame::Sync { counter: Some(*c) },
        _ => bad(Kind::Sync, None, wrong_length(frame, "a SYNC", "0 or 1")),
    }
}

pub(super) fn time(frame: &Frame) -> DecodedFrame {
    match (frame.is_remote(), frame.data()) {
        (false, [a, b, c, d, e, g]) => DecodedFrame::Time {
            millis: u32::from_le_bytes([*a, *b, *c, *d]) & 0x0FFF_FFFF,
            days: u16::from_le_bytes([*e, *g]),
        },
        _ => bad(Kind::Time, None, wrong_length(frame, "a TIME", "6")),
    }
}

/// `TIME 2026-11-24 08:03:12.345`: the days count from 1984-01-01 (CiA 301 TIME_OF_DAY).
pub(super) fn time_text(f: &mut fmt::Formatter<'_>, days: u16, millis: u32) -> fmt::Result {
    // 1984-01-01 is day 5113 after 1970-01-01.
    let (y, m, d) = civil(5113 + days as i64);
    let s = millis / 1000;
    write!(
        f,
        "TIME {y:04}-{m:02}-{d:02} {:02}:{:02}:{:02}.{:03}",
        s / 3600,
        s / 60 % 60,
        s % 60,
        millis % 1000
    )
}

/// The Gregorian date of day `z` after 1970-01-01 (the days-to-civil algorithm).
fn civil(z: i64) -> (i64, u32, u32) {
    let z = z + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = (doy - (153 * mp + 2) / 5 + 1) as u32;
    let m = if mp < 10 { mp + 3 } else { mp - 9 } as u32;
    let y = yoe + era * 400 + i64::from(m <= 2);
    (y, m, d)
}

/// The EMCY of eight bytes.
pub(super) fn emcy_payload(frame: &Frame) -> Result<EmcyMessage, String> {
    EmcyMessage::from_frame(frame).map_err(|_| wrong_length(frame, "an EMCY", "8"))
}

pub(super) fn emcy(node: NodeId, frame: &Frame) -> DecodedFrame {
    match emcy_payload(frame) {
        Ok(emcy) => DecodedFrame::Emcy { node, emcy },
        Err(problem) => bad(Kind::Emcy, Some(node), problem),
    }
}

/// The state and toggle bit of a one-byte error-control payload.
pub(super) fn state_payload(frame: &Frame) -> Result<(NmtState, bool), String> {
    match frame.data() {
        [b] => NmtState::from_code(b & 0x7F)
            .map(|s| (s, b & 0x80 != 0))
            .ok_or_else(|| format!("state byte {b:#04x} is no NMT state")),
        _ => Err(wrong_length(frame, "a heartbeat", "1")),
    }
}

pub(super) fn error_control(node: NodeId, frame: &Frame) -> DecodedFrame {
    if frame.is_remote() {
        return DecodedFrame::GuardingRequest { node };
    }
    match state_payload(frame) {
        Ok((state, toggle)) => DecodedFrame::Heartbeat {
            node,
            state,
            toggle,
        },
        Err(problem) => bad(Kind::Heartbeat, Some(node), problem),
    }
}

pub(super) fn lss(request: bool, frame: &Frame) -> DecodedFrame {
    match (frame.is_remote(), frame.data()) {
        (false, [cs, rest @ ..]) => DecodedFrame::Lss {
            request,
            cs: *cs,
            data: rest.to_vec(),
        },
        _ => bad(Kind::Lss, None, wrong_length(frame, "an LSS frame", "8")),
    }
}

/// The CiA 305 name of an LSS command specifier.
pub(super) fn lss_name(request: bool, cs: u8) -> Option<&'static str> {
    Some(match (request, cs) {
        (true, 0x04) => "switch state global",
        (true, 0x40) => "switch state selective, vendor-ID",
        (true, 0x41) => "switch state selective, product code",
        (true, 0x42) => "switch state selective, revision",
        (true, 0x43) => "switch state selective, serial number",
        (false, 0x44) => "switch state selective answer",
        (_, 0x11) => "configure node-ID",
        (_, 0x13) => "configure bit timing",
        (true, 0x15) => "activate bit timing",
        (_, 0x17) => "store configuration",
        (true, 0x46) => "identify remote slave, vendor-ID",
        (true, 0x47) => "identify remote slave, product code",
        (true, 0x48) => "identify remote slave, revision low",
        (true, 0x49) => "identify remote slave, revision high",
        (true, 0x4A) => "identify remote slave, serial low",
        (true, 0x4B) => "identify remote slave, serial high",
        (true, 0x4C) => "identify non-configured slaves",
        (false, 0x4F) => "identify slave answer",
        (false, 0x50) => "identify non-configured answer",
        (true, 0x51) => "fastscan",
        (_, 0x5A) => "inquire vendor-ID",
        (_, 0x5B) => "inquire product code",
        (_, 0x5C) => "inquire revision",
        (_, 0x5D) => "inquire serial number",
        (_, 0x5E) => "inquire node-ID",
        _ => return None,
    })
}

pub(super) fn flying_master(fm: FlyingMasterFrame, frame: &Frame) -> DecodedFrame {
    if frame.is_remote() {
        return bad(
            Kind::FlyingMaster,
            None,
            format!("{fm}: remote frame, the flying master sends data frames"),
        );
    }
    if !fm.carries_rank() {
        // The machines ignore any payload of the three requests; so does the decoder.
        return DecodedFrame::FlyingMaster {
            frame: fm,
            rank: None,
        };
    }
    match frame.data() {
        [p, n] => match NodeId::new(*n) {
            Some(node) => DecodedFrame::FlyingMaster {
                frame: fm,
                rank: Some((*p, node)),
            },
            None => bad(
                Kind::FlyingMaster,
                None,
                format!("{fm}: node-ID {n} is outside 1-127"),
            ),
        },
        _ => bad(
            Kind::FlyingMaster,
            None,
            format!(
                "{fm}: {}",
                wrong_length(frame, "it", "2 (priority, node-ID)")
            ),
        ),
    }
}
