//! What the layer needs to know about a frame beyond its bytes: whose heartbeat it is, which
//! node sent it, and which process-data function it carries. The predefined connection set is
//! one implementation; a deployment-specific identifier scheme plugs in by implementing
//! [`FrameClassifier`], as the railway 29-bit profile
//! ([`RailwayProfile`](duocan_core::profile::railway::RailwayProfile)) does here.

use duocan_core::frame::cob_id::predefined::{self, Function};
use duocan_core::profile::{IdProfile, Predefined, ProfileFrame};
use duocan_core::{Frame, NodeId};

/// Classifies frames for the dual-bus layer.
pub trait FrameClassifier {
    /// The node whose heartbeat (or boot-up) this is: a data frame on its error-control
    /// identifier.
    fn heartbeat_of(&self, frame: &Frame) -> Option<NodeId>;
    /// The node that produced the frame, if the identifier tells (heartbeats, EMCY, process
    /// data, SDO responses). Used for per-node reachability.
    fn sender(&self, frame: &Frame) -> Option<NodeId>;
    /// The process-data function the frame carries, as (producer, function key). Frames of the
    /// two members of a pair with the same function key carry the same function and are merged
    /// into one stream.
    fn function(&self, frame: &Frame) -> Option<(NodeId, u32)>;
    /// Whether two frames of one function, one from each member of a pair, carry the same
    /// value (otherwise a discrepancy is timed). By default: the same bytes. A scheme whose
    /// payload holds something member-specific (the railway CRC covers the sender's address)
    /// compares the value only.
    fn same_value(&self, a: &Frame, b: &Frame) -> bool {
        a.data() == b.data()
    }
}

/// The predefined connection set: heartbeat 0x700+n; senders from EMCY 0x80+n, TPDO1–4,
/// SDO server responses 0x580+n and error control; functions are TPDO1–4 (key 1–4).
impl FrameClassifier for Predefined {
    #[inline]
    fn heartbeat_of(&self, frame: &Frame) -> Option<NodeId> {
        match self.classify(frame.id(), frame.is_remote()) {
            Some(ProfileFrame::Heartbeat(n)) if frame.dlc() == 1 => Some(n),
            _ => None,
        }
    }
    #[inline]
    fn sender(&self, frame: &Frame) -> Option<NodeId> {
        if frame.is_remote() {
            // Remote frames are requests: sent by whoever wants the data.
            return None;
        }
        match predefined::classify(frame.id()) {
            Function::Emcy(n)
            | Function::Tpdo(_, n)
            | Function::SdoTx(n)
            | Function::ErrorControl(n) => Some(n),
            _ => None,
        }
    }
    #[inline]
    fn function(&self, frame: &Frame) -> Option<(NodeId, u32)> {
        if frame.is_remote() {
            return None;
        }
        match predefined::classify(frame.id()) {
            Function::Tpdo(k, n) => Some((n, k as u32)),
            _ => None,
        }
    }
}

/// Any [`IdProfile`] as a classifier: heartbeats and senders from the fixed-identifier services
/// (error control, default EMCY); no process-data functions.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ProfileClassifier<P>(pub P);

impl<P: IdProfile> FrameClassifier for ProfileClassifier<P> {
    fn heartbeat_of(&self, frame: &Frame) -> Option<NodeId> {
        match self.0.classify(frame.id(), frame.is_remote()) {
            Some(ProfileFrame::Heartbeat(n)) if frame.dlc() == 1 => Some(n),
            _ => None,
        }
    }
    fn sender(&self, frame: &Frame) -> Option<NodeId> {
        if frame.is_remote() {
            return None;
        }
        match self.0.classify(frame.id(), false) {
            Some(
                ProfileFrame::Heartbeat(n) | ProfileFrame::Guarding(n) | ProfileFrame::Emcy(n),
            ) => Some(n),
            _ => None,
        }
    }
    fn function(&self, _: &Frame) -> Option<(NodeId, u32)> {
        None
    }
}

impl<C: FrameClassifier + ?Sized> FrameClassifier for &C {
    fn heartbeat_of(&self, frame: &Frame) -> Option<NodeId> {
        (**self).heartbeat_of(frame)
    }
    fn sender(&self, frame: &Frame) -> Option<NodeId> {
        (**self).sender(frame)
    }
    fn function(&self, frame: &Frame) -> Option<(NodeId, u32)> {
        (**self).function(frame)
    }
    fn same_value(&self, a: &Frame, b: &Frame) -> bool {
        (**self).same_value(a, b)
    }
}

mod railway;
pub use railway::state_function;

#[cfg(test)]
mod tests {
    use super::*;
    use duocan_core::Id;

    #[test]
    fn predefined_classification() {
        let p = Predefined;
        let hb = Frame::from_array(Id::Standard(0x712), [5]);
        let tpdo2 = Frame::from_array(Id::Standard(0x285), [1, 2]);
        let rpdo = Frame::from_array(Id::Standard(0x205), [1]);
        let guard_rq = Frame::remote(Id::Standard(0x712), 1).unwrap();
        let n = |x| NodeId::new(x);
        assert_eq!(p.heartbeat_of(&hb), n(0x12));
        assert_eq!(p.heartbeat_of(&guard_rq), None);
        assert_eq!(p.sender(&hb), n(0x12));
        assert_eq!(p.sender(&guard_rq), None);
        assert_eq!(p.sender(&rpdo), None);
        assert_eq!(p.function(&tpdo2), Some((NodeId::must(5), 2)));
        assert_eq!(p.function(&rpdo), None);
        let pc = ProfileClassifier(Predefined);
        assert_eq!(pc.heartbeat_of(&hb), n(0x12));
        assert_eq!(pc.sender(&tpdo2), None);
    }
}
