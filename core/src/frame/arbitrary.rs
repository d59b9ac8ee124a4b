//! Strategies for property tests of code that takes frames (feature `proptest`): duocan's own
//! decoders, captures and ports are tested with them, and an application's frame handling can
//! be too.
//!
//! ```
//! use duocan_core::frame::arbitrary::any_frame;
//! use proptest::prelude::*;
//!
//! proptest! {
//!     // `#[test]` in a test module; called by hand here.
//!     fn at_most_eight_bytes(f in any_frame()) {
//!         prop_assert!(f.data().len() <= 8);
//!     }
//! }
//! at_most_eight_bytes();
//! ```

use super::fd::{FdFrame, FD_LENGTHS};
use super::{Frame, Id, EXTENDED_ID_MAX, STANDARD_ID_MAX};
use proptest::prelude::*;

/// Any identifier, 11- or 29-bit.
fn any_id() -> impl Strategy<Value = Id> {
    prop_oneof![
        (0u16..=STANDARD_ID_MAX).prop_map(Id::Standard),
        (0u32..=EXTENDED_ID_MAX).prop_map(Id::Extended),
    ]
}

/// Any classic frame: data or remote, 11- or 29-bit identifier, 0 to 8 bytes.
pub fn any_frame() -> impl Strategy<Value = Frame> {
    (
        any_id(),
        any::<bool>(),
        proptest::collection::vec(any::<u8>(), 0..=8),
    )
        // Every drawn identifier and length is valid: nothing is filtered out, and nothing
        // can panic in a caller's test.
        .prop_filter_map("a valid frame", |(id, rtr, data)| {
            if rtr {
                Frame::remote(id, data.len() as u8).ok()
            } else {
                Frame::new(id, &data).ok()
            }
        })
}

/// Any CAN FD frame: 11- or 29-bit identifier, each of the 16 lengths, BRS and ESI either way.
pub fn any_fd_frame() -> impl Strategy<Value = FdFrame> {
    (
        any_id(),
        proptest::sample::select(&FD_LENGTHS[..]),
        proptest::collection::vec(any::<u8>(), 64),
        any::<bool>(),
        any::<bool>(),
    )
        // Every drawn length is a CAN FD length: nothing is filtered out.
        .prop_filter_map("a valid CAN FD frame", |(id, len, bytes, brs, esi)| {
            FdFrame::new(id, &bytes[..usize::from(len)])
                .ok()
                .map(|f| f.with_brs(brs).with_esi(esi))
        })
}
