//! The railway 29-bit profile as a [`FrameClassifier`]: the dual-bus layer's reachability,
//! heartbeat evaluation and same-function merge over the railway 29-bit identifier scheme.
//!
//! - **Heartbeats**: data frames of one byte on [`RailFunction::Heartbeat`] at a node's board
//!   address.
//! - **Senders**: whatever a device sends (fault report, heartbeat, guarding answer, command
//!   answer, state change, state answer, SDO response) names its board; frames the
//!   interlocking sends to an address (NMT, SYNC, command, state query, SDO request, remote
//!   guarding requests) name no sender.
//! - **Functions**: state changes. Boards A and B of a pair report the same field devices on
//!   the same I/O ports under the same objects, so the key is (port, index, sub-index)
//!   ([`state_function`]) and their frames merge into one stream. Their CRCs differ (each
//!   covers its own board's address), so A and B are compared on the checked payload, not on
//!   the bytes.

use super::FrameClassifier;
use duocan_core::profile::railway::{split, Payload, RailFunction, RailwayProfile};
use duocan_core::profile::{IdProfile, ProfileFrame};
use duocan_core::{Frame, NodeId};

/// The function key of state changes of I/O `port`, object (`index`, `sub`): what
/// [`DualBus::pairs`](crate::DualBus::pairs)`().latest(pair, member, key)` takes.
pub const fn state_function(port: u8, index: u16, sub: u8) -> u32 {
    ((port as u32 & 0xF) << 24) | ((index as u32) << 8) | sub as u32
}

impl FrameClassifier for RailwayProfile {
    #[inline]
    fn heartbeat_of(&self, frame: &Frame) -> Option<NodeId> {
        if frame.is_remote() || frame.dlc() != 1 {
            return None;
        }
        match self.classify(frame.id(), false) {
            Some(ProfileFrame::Heartbeat(n)) => Some(n),
            _ => None,
        }
    }
    #[inline]
    fn sender(&self, frame: &Frame) -> Option<NodeId> {
        if frame.is_remote() {
            return None;
        }
        let (code, address) = split(frame.id())?;
        let f = RailFunction::from_code(code)?;
        if !f.from_device() || (f.node_level() && address.port() != 0) {
            return None;
        }
        self.node_at(address)
    }
    #[inline]
    fn function(&self, frame: &Frame) -> Option<(NodeId, u32)> {
        if frame.is_remote() {
            return None;
        }
        let (code, address) = split(frame.id())?;
        if code != RailFunction::StateChange.code() {
            return None;
        }
        let node = self.node_at(address)?;
        // A payload too short to name its object still belongs to its port's stream.
        let (index, sub) = match frame.data() {
            [lo, hi, sub, ..] => (u16::from_le_bytes([*lo, *hi]), *sub),
            _ => (0, 0),
        };
        Some((node, state_function(address.port(), index, sub)))
    }
    fn same_value(&self, a: &Frame, b: &Frame) -> bool {
        match (Payload::decode(a), Payload::decode(b)) {
            (Ok(x), Ok(y)) => x == y,
            // A frame that fails its check agrees with nothing but an identical copy.
            _ => a.data() == b.data(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use duocan_core::profile::railway::safety::{FieldState, PointPosition};
    use duocan_core::profile::railway::{id, DeviceAddress};
    use duocan_core::Id;

    const A: DeviceAddress = DeviceAddress::board_at(1, 1, 1, 1);
    const B: DeviceAddress = DeviceAddress::board_at(1, 1, 1, 2);

    fn profile() -> RailwayProfile {
        RailwayProfile::with(&[(NodeId::must(2), A), (NodeId::must(3), B)]).unwrap()
    }

    #[test]
    fn heartbeats_senders_and_functions() {
        let p = profile();
        let n = NodeId::must;
        let hb = Frame::from_array(id(RailFunction::Heartbeat, A), [5]);
        assert_eq!(p.heartbeat_of(&hb), Some(n(2)));
        assert_eq!(p.sender(&hb), Some(n(2)));
        let long_hb = Frame::from_array(id(RailFunction::Heartbeat, A), [5, 0]);
        assert_eq!(p.heartbeat_of(&long_hb), None);
        let guard_rq = Frame::remote(id(RailFunction::NodeGuarding, B), 1).unwrap();
        assert_eq!(
            (p.heartbeat_of(&guard_rq), p.sender(&guard_rq)),
            (None, None)
        );
        let guard_answer = Frame::from_array(id(RailFunction::NodeGuarding, B), [0x85]);
        assert_eq!(p.sender(&guard_answer), Some(n(3)));

        let state = FieldState::Point(PointPosition::Normal).payload(1);
        let from_a = state.encode(id(RailFunction::StateChange, A.with_port(2)));
        let from_b = state.encode(id(RailFunction::StateChange, B.with_port(2)));
        let key = state_function(2, 0x6100, 1);
        assert_eq!(p.sender(&from_a), Some(n(2)));
        assert_eq!(p.function(&from_a), Some((n(2), key)));
        assert_eq!(
            p.function(&from_b),
            Some((n(3), key)),
            "A and B: one function"
        );
        let port3 = state.encode(id(RailFunction::StateChange, B.with_port(3)));
        assert_ne!(p.function(&port3).unwrap().1, key);

        // Sent by the interlocking to a board: no sender, no function.
        let cmd = state.encode(id(RailFunction::Command, A.with_port(2)));
        assert_eq!((p.sender(&cmd), p.function(&cmd)), (None, None));
        let nmt = Frame::from_array(RailwayProfile::NMT, [1, 0]);
        assert_eq!(p.sender(&nmt), None);
        // A heartbeat on an I/O port, an unknown board, an 11-bit frame: nobody's.
        let odd = Frame::from_array(id(RailFunction::Heartbeat, A.with_port(1)), [5]);
        assert_eq!((p.heartbeat_of(&odd), p.sender(&odd)), (None, None));
        let short = Frame::from_array(id(RailFunction::StateChange, A), [0]);
        assert_eq!(p.function(&short), Some((n(2), state_function(0, 0, 0))));
        let unknown = Frame::from_array(
            id(
                RailFunction::StateChange,
                DeviceAddress::board_at(9, 9, 9, 9),
            ),
            [0; 6],
        );
        assert_eq!((p.sender(&unknown), p.function(&unknown)), (None, None));
        assert_eq!(p.sender(&Frame::from_array(Id::Standard(0x702), [5])), None);
    }

    #[test]
    fn a_and_b_agree_on_the_value_despite_their_crcs() {
        let p = profile();
        let id_a = id(RailFunction::StateChange, A.with_port(2));
        let id_b = id(RailFunction::StateChange, B.with_port(2));
        let normal = FieldState::Point(PointPosition::Normal).payload(1);
        let (a, b) = (normal.encode(id_a), normal.encode(id_b));
        assert_ne!(a.data(), b.data(), "the CRCs differ");
        assert!(p.same_value(&a, &b));
        let moving = FieldState::Point(PointPosition::Moving)
            .payload(1)
            .encode(id_b);
        assert!(!p.same_value(&a, &moving));
        // A corrupted copy is a different value.
        let mut d = [0u8; 6];
        d.copy_from_slice(b.data());
        d[5] ^= 1;
        let bad = Frame::new(id_b, &d).unwrap();
        assert!(!p.same_value(&a, &bad));
        assert!(p.same_value(&bad, &bad));
    }
}
