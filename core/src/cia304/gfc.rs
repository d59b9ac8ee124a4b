//! The global fail-safe command (GFC): one frame without data on identifier 0x001, the highest
//! priority after NMT, that tells every safety device to take its safe state at once instead of
//! waiting for its SCT to run out.
//!
//! It is in use when 0x1300 holds 1. A node sends it on the application's request
//! ([`crate::node::Node::gfc_send`]); on receiving it, the node puts all its SRDO consumers in
//! their safe state and reports it ([`SrdoEvent::Gfc`](super::srdo::SrdoEvent::Gfc)):
//! that event is the application's safe-state hook. The GFC carries no data and no checksum, so
//! it can only make a device safer, never deliver a value.

use crate::frame::{Frame, Id};

/// The GFC identifier.
pub const GFC_ID: Id = Id::Standard(0x001);

/// The GFC frame.
#[must_use]
pub const fn gfc_frame() -> Frame {
    Frame::from_array(GFC_ID, [])
}

/// True if `frame` is a GFC (a data frame on 0x001; its length does not matter: CiA 304 sends it
/// empty, and a longer one is still a request to be safe).
#[must_use]
pub fn is_gfc(frame: &Frame) -> bool {
    frame.id() == GFC_ID && !frame.is_remote()
}
