//! python-can's `udp_multicast` wire format: one msgpack map per frame.
//!
//! Decoding is strict about shape as well as content: a frame is a map of scalars (its `data`
//! may be an array of integers), so the decoder refuses anything nested deeper (a few hundred
//! bytes of nested arrays would otherwise recurse until the stack runs out) and any bytes after
//! the map.

use crate::frame::{Frame, Id};
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
        }
    }
}

impl std::error::Error for DecodeError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            DecodeError::Invalid(e) => Some(e),
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

/// Decodes a datagram into a classic frame and its timestamp (0.0 if absent or not a number).
pub fn decode(datagram: &[u8]) -> Result<(Frame, f64), DecodeError> {
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
    if flag("is_fd", false)? {
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
    if flag("is_remote_frame", false)? {
        let dlc = u8::try_from(dlc)
            .map_err(|_| DecodeError::Invalid(crate::frame::FrameError::TooLong { len: 255 }))?;
        let f = Frame::remote(id, dlc).map_err(DecodeError::Invalid)?;
        return Ok((f, timestamp));
    }
    let mut bytes = [0u8; 8];
    let data: &[u8] = match get("data") {
        Some(Value::Binary(b)) => b,
        Some(Value::Array(items)) => {
            // A peer that packed a list of ints (msgpack without use_bin_type).
            if items.len() > 8 {
                return Err(DecodeError::Invalid(crate::frame::FrameError::TooLong {
                    len: items.len(),
                }));
            }
            for (slot, it) in bytes.iter_mut().zip(items) {
                *slot = it
                    .as_u64()
                    .and_then(|b| u8::try_from(b).ok())
                    .ok_or(DecodeError::Field("data"))?;
            }
            &bytes[..items.len()]
        }
        Some(Value::Nil) | None if dlc == 0 => &[],
        _ => return Err(DecodeError::Field("data")),
    };
    if dlc != data.len() as u64 {
        return Err(DecodeError::Field("dlc"));
    }
    let f = Frame::new(id, data).map_err(DecodeError::Invalid)?;
    Ok((f, timestamp))
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
        fn arbitrary_bytes_never_panic(b in proptest::collection::vec(any::<u8>(), 0..300)) {
            let _ = decode(&b);
        }
    }
}
