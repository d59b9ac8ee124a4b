//! python-can's `udp_multicast` wire format: one msgpack map per frame.
//!
//! Decoding is strict about shape as well as content: a frame is a map of scalars (its `data`
//! may be an array of integers), so the decoder refuses anything nested deeper (a few hundred
//! bytes of nested arrays would otherwise recurse until the stack runs out) and any bytes after
//! the map.
//!
//! CAN FD frames travel as python-can packs them: `is_fd` true, `bitrate_switch` and
//! `error_state_indicator` the BRS and ESI flags, `dlc` the payload's length in bytes (python-can
//! calls the length `dlc`), up to 64. [`decode`] takes classic frames only (an FD one is
//! [`DecodeError::Fd`]); [`decode_any`] takes both, and refuses an FD frame whose length is not
//! a CAN FD length or above 64, or that claims to be a remote frame, naming what was wrong.

use crate::frame::fd::{FdFrameError, FD_MAX_LEN};
use crate::frame::{FdFrame, Frame, Id};
use rmpv::Value;
use std::fmt;

/// How deep the decoder may recurse. rmpv counts one level for each value, map, array, string
/// and binary body: a map (2) whose key or value is a string, binary or array (2) of scalars (1)
/// needs 5, the deepest thing a python-can frame holds. One array more is refused.
const FRAME_DEPTH: usize = 5;

/// Why a datagram is not a classic CAN frame.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum DecodeError {
    /// Not msgpack, or truncated.
    NotMsgpack,
    /// Msgpack nested deeper than a frame is (arrays in arrays, maps in maps).
    TooDeep,
    /// Bytes after the map: the datagram holds more than one frame's worth.
    TrailingBytes(usize),
    /// Msgpack, but not a map.
    NotAMap,
    /// A required key is missing or has the wrong type.
    Field(&'static str),
    /// An error frame (python-can `is_error_frame`).
    ErrorFrame,
    /// A CAN FD frame.
    Fd,
    /// Identifier, DLC or data out of range for classic CAN.
    Invalid(crate::frame::FrameError),
    /// A CAN FD frame that is not one: more than 64 bytes, a length between the CAN FD steps,
    /// or a remote frame.
    InvalidFd(FdFrameError),
}

/// A decoded frame, classic or CAN FD ([`decode_any`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UdpFrame {
    /// A classic data or remote frame.
    Frame(Frame),
    /// A CAN FD frame.
    Fd(FdFrame),
}

impl fmt::Display for DecodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DecodeError::NotMsgpack => f.write_str("not a msgpack value (garbage or truncated)"),
            DecodeError::TooDeep => write!(
                f,
                "msgpack nested deeper than a frame (more than {FRAME_DEPTH} levels)"
            ),
            DecodeError::TrailingBytes(n) => write!(f, "{n} bytes after the frame's map"),
            DecodeError::NotAMap => f.write_str("msgpack value is not a map"),
            DecodeError::Field(k) => write!(f, "key {k:?} missing or of the wrong type"),
            DecodeError::ErrorFrame => f.write_str("error frame"),
            DecodeError::Fd => f.write_str("CAN FD frame on a classic CAN bus"),
            DecodeError::Invalid(e) => write!(f, "{e}"),
            DecodeError::InvalidFd(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for DecodeError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            DecodeError::Invalid(e) => Some(e),
            DecodeError::InvalidFd(e) => Some(e),
            _ => None,
        }
    }
}

/// Encodes a frame as python-can's `pack_message` does (same keys, same order, same types).
pub fn encode(frame: &Frame, timestamp: f64, channel: Option<&str>) -> Vec<u8> {
    let (raw, ext) = match frame.id() {
        Id::Standard(r) => (r as u32, false),
        Id::Extended(r) => (r, true),
    };
    let map = Value::Map(vec![
        (Value::from("timestamp"), Value::F64(timestamp)),
        (Value::from("arbitration_id"), Value::from(raw)),
        (Value::from("is_extended_id"), Value::Boolean(ext)),
        (
            Value::from("is_remote_frame"),
            Value::Boolean(frame.is_remote()),
        ),
        (Value::from("is_error_frame"), Value::Boolean(false)),
        (
            Value::from("channel"),
            channel.map(Value::from).unwrap_or(Value::Nil),
        ),
        (Value::from("dlc"), Value::from(frame.dlc())),
        (Value::from("data"), Value::Binary(frame.data().to_vec())),
        (Value::from("is_fd"), Value::Boolean(false)),
        (Value::from("bitrate_switch"), Value::Boolean(false)),
        (Value::from("error_state_indicator"), Value::Boolean(false)),
    ]);
    let mut buf = Vec::with_capacity(160);
    // Writing into a Vec cannot fail.
    let _ = rmpv::encode::write_value(&mut buf, &map);
    buf
}

/// Encodes a CAN FD frame as python-can's `pack_message` does for a message with `is_fd`:
/// `dlc` is the length in bytes, BRS and ESI are `bitrate_switch` and `error_state_indicator`.
pub fn encode_fd(frame: &FdFrame, timestamp: f64, channel: Option<&str>) -> Vec<u8> {
    let (raw, ext) = match frame.id() {
        Id::Standard(r) => (r as u32, false),
        Id::Extended(r) => (r, true),
    };
    let map = Value::Map(vec![
        (Value::from("timestamp"), Value::F64(timestamp)),
        (Value::from("arbitration_id"), Value::from(raw)),
        (Value::from("is_extended_id"), Value::Boolean(ext)),
        (Value::from("is_remote_frame"), Value::Boolean(false)),
        (Value::from("is_error_frame"), Value::Boolean(false)),
        (
            Value::from("channel"),
            channel.map(Value::from).unwrap_or(Value::Nil),
        ),
        (Value::from("dlc"), Value::from(frame.len())),
        (Value::from("data"), Value::Binary(frame.data().to_vec())),
        (Value::from("is_fd"), Value::Boolean(true)),
        (Value::from("bitrate_switch"), Value::Boolean(frame.brs())),
        (
            Value::from("error_state_indicator"),
            Value::Boolean(frame.esi()),
        ),
    ]);
    let mut buf = Vec::with_capacity(224);
    // Writing into a Vec cannot fail.
    let _ = rmpv::encode::write_value(&mut buf, &map);
    buf
}

/// Decodes a datagram into a classic frame and its timestamp (0.0 if absent or not a number).
/// A CAN FD frame is [`DecodeError::Fd`]: [`decode_any`] takes those too.
pub fn decode(datagram: &[u8]) -> Result<(Frame, f64), DecodeError> {
    match decode_with(datagram, false)? {
        (UdpFrame::Frame(f), t) => Ok((f, t)),
        (UdpFrame::Fd(_), _) => Err(DecodeError::Fd),
    }
}

/// Decodes a datagram into a classic or CAN FD frame and its timestamp.
pub fn decode_any(datagram: &[u8]) -> Result<(UdpFrame, f64), DecodeError> {
    decode_with(datagram, true)
}

fn decode_with(datagram: &[u8], fd: bool) -> Result<(UdpFrame, f64), DecodeError> {
    let mut rd = datagram;
    let v = rmpv::decode::read_value_with_max_depth(&mut rd, FRAME_DEPTH).map_err(|e| match e {
        rmpv::decode::Error::DepthLimitExceeded => DecodeError::TooDeep,
        _ => DecodeError::NotMsgpack,
    })?;
    if !rd.is_empty() {
        return Err(DecodeError::TrailingBytes(rd.len()));
    }
    let Value::Map(entries) = v else {
        return Err(DecodeError::NotAMap);
    };
    let get = |k: &str| {
        entries
            .iter()
            .find(|(key, _)| key.as_str() == Some(k))
            .map(|(_, v)| v)
    };
    let flag = |k: &'static str, default: bool| match get(k) {
        None | Some(Value::Nil) => Ok(default),
        Some(Value::Boolean(b)) => Ok(*b),
        Some(_) => Err(DecodeError::Field(k)),
    };
    if flag("is_error_frame", false)? {
        return Err(DecodeError::ErrorFrame);
    }
    let is_fd = flag("is_fd", false)?;
    if is_fd && !fd {
        return Err(DecodeError::Fd);
    }
    let raw = get("arbitration_id")
        .and_then(Value::as_u64)
        .ok_or(DecodeError::Field("arbitration_id"))?;
    let raw = u32::try_from(raw).map_err(|_| DecodeError::Field("arbitration_id"))?;
    let ext = flag("is_extended_id", raw > crate::frame::STANDARD_ID_MAX as u32)?;
    let id = if ext {
        Id::extended(raw)
    } else {
        u16::try_from(raw).ok().and_then(Id::standard)
    }
    .ok_or(DecodeError::Invalid(crate::frame::FrameError::BadId {
        raw,
    }))?;
    let dlc = get("dlc")
        .and_then(Value::as_u64)
        .ok_or(DecodeError::Field("dlc"))?;
    let timestamp = get("timestamp").and_then(Value::as_f64).unwrap_or(0.0);
    if is_fd {
        if flag("is_remote_frame", false)? {
            return Err(DecodeError::InvalidFd(FdFrameError::Remote));
        }
        let mut bytes = [0u8; FD_MAX_LEN];
        let data = payload(get("data"), dlc, &mut bytes, FD_MAX_LEN).map_err(|e| {
            e.unwrap_or_else(|len| DecodeError::InvalidFd(FdFrameError::TooLong { len }))
        })?;
        if dlc != data.len() as u64 {
            return Err(DecodeError::Field("dlc"));
        }
        let f = FdFrame::new(id, data)
            .map_err(DecodeError::InvalidFd)?
            .with_brs(flag("bitrate_switch", false)?)
            .with_esi(flag("error_state_indicator", false)?);
        return Ok((UdpFrame::Fd(f), timestamp));
    }
    if flag("is_remote_frame", false)? {
        let dlc = u8::try_from(dlc)
            .map_err(|_| DecodeError::Invalid(crate::frame::FrameError::TooLong { len: 255 }))?;
        let f = Frame::remote(id, dlc).map_err(DecodeError::Invalid)?;
        return Ok((UdpFrame::Frame(f), timestamp));
    }
    let mut bytes = [0u8; 8];
    let data = payload(get("data"), dlc, &mut bytes, 8).map_err(|e| {
        e.unwrap_or_else(|len| DecodeError::Invalid(crate::frame::FrameError::TooLong { len }))
    })?;
    if dlc != data.len() as u64 {
        return Err(DecodeError::Field("dlc"));
    }
    let f = Frame::new(id, data).map_err(DecodeError::Invalid)?;
    Ok((UdpFrame::Frame(f), timestamp))
}

/// A frame's `data`: binary, or a list of integers (a peer that packed without
/// `use_bin_type`) copied into `bytes`, at most `max` of them (`Err(Err(len))` for more).
fn payload<'a>(
    data: Option<&'a Value>,
    dlc: u64,
    bytes: &'a mut [u8],
    max: usize,
) -> Result<&'a [u8], Result<DecodeError, usize>> {
    match data {
        Some(Value::Binary(b)) => Ok(b),
        Some(Value::Array(items)) => {
            if items.len() > max {
                return Err(Err(items.len()));
            }
            for (slot, it) in bytes.iter_mut().zip(items) {
                *slot = it
                    .as_u64()
                    .and_then(|b| u8::try_from(b).ok())
                    .ok_or(Ok(DecodeError::Field("data")))?;
            }
            Ok(&bytes[..items.len()])
        }
        Some(Value::Nil) | None if dlc == 0 => Ok(&[]),
        _ => Err(Ok(DecodeError::Field("data"))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Bytes python-can 4.6 (`msgpack.packb(..., use_bin_type=True)`) produced for
    /// `Message(timestamp=1.5, arbitration_id=0x601, data=[0x40, 0x18, 0x10, 1, 0, 0, 0, 0])`.
    const PYTHON_SDO_HEX: &str = concat!(
        "8ba974696d657374616d70cb3ff8000000000000ae6172626974726174696f6e5f6964cd0601ae69",
        "735f657874656e6465645f6964c2af69735f72656d6f74655f6672616d65c2ae69735f6572726f72",
        "5f6672616d65c2a76368616e6e656cc0a3646c6308a464617461c4084018100100000000a569735f",
        "6664c2ae626974726174655f737769746368c2b56572726f725f73746174655f696e64696361746f",
        "72c2",
    );

    fn python_sdo() -> Vec<u8> {
        (0..PYTHON_SDO_HEX.len())
            .step_by(2)
            .map(|i| u8::from_str_radix(&PYTHON_SDO_HEX[i..i + 2], 16).unwrap())
            .collect()
    }

    #[test]
    fn encodes_byte_for_byte_like_python_can() {
        let f = Frame::from_array(Id::Standard(0x601), [0x40, 0x18, 0x10, 1, 0, 0, 0, 0]);
        let py = python_sdo();
        assert_eq!(encode(&f, 1.5, None), py);
        assert_eq!(decode(&py).unwrap(), (f, 1.5));
    }

    #[test]
    fn garbage_and_truncation_are_errors() {
        assert_eq!(decode(&[]), Err(DecodeError::NotMsgpack));
        assert!(decode(&[0xc1]).is_err());
        assert_eq!(decode(&[0x93, 1, 2, 3]), Err(DecodeError::NotAMap));
        let py = python_sdo();
        for n in 0..py.len() {
            assert!(decode(&py[..n]).is_err(), "prefix {n} decoded");
        }
        let fd = encode(&Frame::from_array(Id::Standard(1), [1]), 0.0, None);
        let fd: Vec<u8> = replace(&fd, b"is_fd\xc2", b"is_fd\xc3");
        assert_eq!(decode(&fd), Err(DecodeError::Fd));
        let err = replace(
            &encode(&Frame::from_array(Id::Standard(1), [1]), 0.0, None),
            b"is_error_frame\xc2",
            b"is_error_frame\xc3",
        );
        assert_eq!(decode(&err), Err(DecodeError::ErrorFrame));
        let bad_dlc = replace(
            &encode(&Frame::from_array(Id::Standard(1), [1]), 0.0, None),
            b"dlc\x01",
            b"dlc\x05",
        );
        assert_eq!(decode(&bad_dlc), Err(DecodeError::Field("dlc")));
        let bad_id = replace(
            &encode(&Frame::from_array(Id::Standard(0x7FF), [1]), 0.0, None),
            b"\xcd\x07\xff",
            b"\xcd\x08\x00",
        );
        assert!(matches!(decode(&bad_id), Err(DecodeError::Invalid(_))));
    }

    #[test]
    fn nesting_deeper_than_a_frame_is_refused() {
        // ~500 bytes of nested arrays: refused at the depth limit, not at the stack's end.
        let mut nested = vec![0x91; 500];
        nested.push(0x00);
        assert_eq!(decode(&nested), Err(DecodeError::TooDeep));
        // A frame whose `data` is an array of integers is as deep as a frame goes: accepted.
        let f = Frame::from_array(Id::Standard(0x181), [1, 2]);
        let as_list = replace(
            &encode(&f, 0.0, None),
            b"data\xc4\x02\x01\x02",
            b"data\x92\x01\x02",
        );
        assert_eq!(decode(&as_list), Ok((f, 0.0)));
        // One array more (a list holding a list) is refused.
        let deeper = replace(&as_list, b"data\x92\x01\x02", b"data\x92\x01\x91\x02");
        assert_eq!(decode(&deeper), Err(DecodeError::TooDeep));
        // So is a map nested in a key's value.
        let map_in_map = replace(&as_list, b"data\x92\x01\x02", b"data\x81\x01\x92\x01\x02");
        assert_eq!(decode(&map_in_map), Err(DecodeError::TooDeep));
    }

    #[test]
    fn bytes_after_the_map_are_refused() {
        let f = Frame::from_array(Id::Standard(0x181), [1, 2]);
        let good = encode(&f, 0.0, None);
        let mut one_more = good.clone();
        one_more.push(0xc0);
        assert_eq!(decode(&one_more), Err(DecodeError::TrailingBytes(1)));
        let two_frames = [good.clone(), good.clone()].concat();
        assert_eq!(
            decode(&two_frames),
            Err(DecodeError::TrailingBytes(good.len()))
        );
        assert_eq!(
            DecodeError::TrailingBytes(3).to_string(),
            "3 bytes after the frame's map"
        );
    }

    /// Bytes python-can 4.6.1's `pack_message` produced for `Message(timestamp=1.5,
    /// arbitration_id=0x181, is_extended_id=False, is_fd=True, bitrate_switch=True,
    /// data=bytes(range(12)))`.
    const PYTHON_FD_HEX: &str = concat!(
        "8ba974696d657374616d70cb3ff8000000000000ae6172626974726174696f6e5f6964cd0181ae69",
        "735f657874656e6465645f6964c2af69735f72656d6f74655f6672616d65c2ae69735f6572726f72",
        "5f6672616d65c2a76368616e6e656cc0a3646c630ca464617461c40c000102030405060708090a0b",
        "a569735f6664c3ae626974726174655f737769746368c3b56572726f725f73746174655f696e6469",
        "6361746f72c2",
    );

    fn unhex(s: &str) -> Vec<u8> {
        (0..s.len())
            .step_by(2)
            .map(|i| u8::from_str_radix(&s[i..i + 2], 16).unwrap())
            .collect()
    }

    fn fd(data: &[u8]) -> FdFrame {
        FdFrame::new(Id::Standard(0x181), data).unwrap()
    }

    #[test]
    fn fd_frames_encode_byte_for_byte_like_python_can() {
        let data: Vec<u8> = (0..12).collect();
        let f = fd(&data).with_brs(true);
        let py = unhex(PYTHON_FD_HEX);
        assert_eq!(encode_fd(&f, 1.5, None), py);
        assert_eq!(decode_any(&py), Ok((UdpFrame::Fd(f), 1.5)));
        // The classic decoder refuses it, naming why.
        assert_eq!(decode(&py), Err(DecodeError::Fd));
        // A classic frame through `decode_any` is a classic frame.
        assert_eq!(
            decode_any(&python_sdo()).unwrap().0,
            UdpFrame::Frame(Frame::from_array(
                Id::Standard(0x601),
                [0x40, 0x18, 0x10, 1, 0, 0, 0, 0]
            ))
        );
    }

    #[test]
    fn malformed_fd_frames_are_errors_naming_what_was_wrong() {
        let good = encode_fd(&fd(&[7; 12]), 0.0, None);
        // Ten bytes: not a CAN FD length.
        let ten = replace(
            &replace(&good, b"dlc\x0c", b"dlc\x0a"),
            &[b"data\xc4\x0c".as_slice(), &[7; 12]].concat(),
            &[b"data\xc4\x0a".as_slice(), &[7; 10]].concat(),
        );
        let e = decode_any(&ten).unwrap_err();
        assert_eq!(
            e,
            DecodeError::InvalidFd(FdFrameError::NotFdLength { len: 10 })
        );
        assert!(e.to_string().contains("10 bytes"), "{e}");
        // 65 bytes as a list: too long.
        let list: Vec<u8> = [&[0xdc, 0, 65][..], &[1; 65]].concat();
        let long = replace(
            &replace(&good, b"dlc\x0c", b"dlc\x41"),
            &[b"data\xc4\x0c".as_slice(), &[7; 12]].concat(),
            &[b"data".as_slice(), &list].concat(),
        );
        assert_eq!(
            decode_any(&long),
            Err(DecodeError::InvalidFd(FdFrameError::TooLong { len: 65 }))
        );
        // A remote FD frame.
        let remote = replace(&good, b"is_remote_frame\xc2", b"is_remote_frame\xc3");
        assert_eq!(
            decode_any(&remote),
            Err(DecodeError::InvalidFd(FdFrameError::Remote))
        );
        // DLC and data disagree; a flag of the wrong type.
        let bad_dlc = replace(&good, b"dlc\x0c", b"dlc\x10");
        assert_eq!(decode_any(&bad_dlc), Err(DecodeError::Field("dlc")));
        let bad_brs = replace(&good, b"bitrate_switch\xc2", b"bitrate_switch\x01");
        assert_eq!(
            decode_any(&bad_brs),
            Err(DecodeError::Field("bitrate_switch"))
        );
        for n in 0..good.len() {
            assert!(decode_any(&good[..n]).is_err(), "prefix {n} decoded");
        }
    }

    fn replace(hay: &[u8], from: &[u8], to: &[u8]) -> Vec<u8> {
        let i = hay
            .windows(from.len())
            .position(|w| w == from)
            .expect("pattern present");
        let mut v = hay.to_vec();
        v.splice(i..i + from.len(), to.iter().copied());
        v
    }

    proptest! {
        #[test]
        fn round_trip(f in crate::frame::arbitrary::any_frame(), ts in 0.0f64..2e9) {
            prop_assert_eq!(decode(&encode(&f, ts, Some("can0"))).unwrap(), (f, ts));
        }

        #[test]
        fn fd_round_trip(f in crate::frame::arbitrary::any_fd_frame(), ts in 0.0f64..2e9) {
            prop_assert_eq!(
                decode_any(&encode_fd(&f, ts, Some("can0"))).unwrap(),
                (UdpFrame::Fd(f), ts)
            );
        }

        #[test]
        fn arbitrary_bytes_never_panic_either_decoder(b in proptest::collection::vec(any::<u8>(), 0..300)) {
            let _ = decode_any(&b);
        }

        #[test]
        fn arbitrary_bytes_never_panic(b in proptest::collection::vec(any::<u8>(), 0..300)) {
            let _ = decode(&b);
        }
    }
}
