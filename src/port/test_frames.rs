//! Frames for property tests across the crate (tests only). The protocol core has the same
//! strategy for its own tests; a crate's `#[cfg(test)]` items are not seen by the crates above
//! it, so this crate keeps its copy.

use crate::frame::{Frame, Id, EXTENDED_ID_MAX, STANDARD_ID_MAX};
use proptest::prelude::*;

/// Any classic frame: data or remote, 11- or 29-bit identifier, 0 to 8 bytes.
pub(crate) fn any_frame() -> impl Strategy<Value = Frame> {
    let id = prop_oneof![
        (0u16..=STANDARD_ID_MAX).prop_map(Id::Standard),
        (0u32..=EXTENDED_ID_MAX).prop_map(Id::Extended),
    ];
    (
        id,
        any::<bool>(),
        proptest::collection::vec(any::<u8>(), 0..=8),
    )
        .prop_map(|(id, rtr, data)| {
            if rtr {
                Frame::remote(id, data.len() as u8).unwrap()
            } else {
                Frame::new(id, &data).unwrap()
            }
        })
}
