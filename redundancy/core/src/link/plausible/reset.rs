//! A master reset a watched node: the boot-up it asked for ends a bus's verdict.
//!
//! Rule 1's verdict on a bus ends when the bucket drains, at calm heartbeats, or at a boot-up
//! after one calm heartbeat: the node alone at its pace. A master that resets a node *because*
//! a second device shared its node-ID often does so the moment the other device falls silent:
//! the node's last heartbeats still alternated with the other's states, none counted as calm,
//! and its boot-up was dropped with the verdict. The master above never saw it boot, so it
//! neither configured the board nor let it join its pair; and rule 2 then took the board,
//! heard again later on one bus only (its other transceiver dead), for an impostor. The pair
//! had no board to run when its other member died.
//!
//! So an NMT reset (node or communication) addressed to a watched node, or to all, sent by
//! this station or seen on the bus, is remembered on each bus, and the node's next boot-up on
//! that bus ends the verdict there. Should the other device still beat, the bucket, emptied as
//! at every boot-up, flags it again within a few periods (rule 1). A reset whose boot-up never
//! comes ends at most one later verdict, at that boot-up.
//!
//! Memory: one bit per watched node and bus.

use super::{Plausibility, ON};
use duocan_core::{Frame, Id, NodeId};

impl Plausibility {
    /// An NMT command on the bus, received or sent by this station (see the module
    /// documentation).
    #[inline]
    pub(crate) fn on_nmt(&mut self, frame: &Frame) {
        if !ON || self.table.is_none() || frame.id() != Id::Standard(0) {
            return;
        }
        let &[0x81 | 0x82, target] = frame.data() else {
            return;
        };
        if target == 0 {
            if let Some(t) = self.table.as_deref_mut() {
                for w in t.watched.iter_mut() {
                    w.reset = 0b11;
                }
            }
        } else if let Some(i) = NodeId::new(target).and_then(|n| self.find(n)) {
            self.at(i).reset = 0b11;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use duocan_core::Duration;

    fn nmt(cs: u8, node: u8) -> Frame {
        Frame::new(Id::Standard(0), &[cs, node]).expect("two bytes")
    }
    fn flags(p: &Plausibility, node: u8) -> [bool; 2] {
        p.entry(NodeId::must(node))
            .map_or([false; 2], |w| [0, 1].map(|b| w.reset & (1 << b) != 0))
    }

    #[test]
    fn a_reset_of_the_node_or_of_all_is_remembered_on_both_buses_and_nothing_else_is() {
        let mut p = Plausibility::new(None);
        for n in [0x10, 0x11] {
            assert!(p.watch(NodeId::must(n), Duration::from_millis(20)));
        }
        // Start, stop, pre-operational: not a reset.
        for cs in [0x01, 0x02, 0x80] {
            p.on_nmt(&nmt(cs, 0x10));
        }
        // A malformed command (three bytes) and another identifier are not read.
        p.on_nmt(&Frame::new(Id::Standard(0), &[0x81, 0x10, 0]).expect("three bytes"));
        p.on_nmt(&Frame::new(Id::Standard(1), &[0x81, 0x10]).expect("two bytes"));
        assert_eq!(flags(&p, 0x10), [false; 2]);
        p.on_nmt(&nmt(0x81, 0x10));
        assert_eq!(flags(&p, 0x10), [true; 2]);
        assert_eq!(flags(&p, 0x11), [false; 2]);
        p.on_nmt(&nmt(0x82, 0));
        assert_eq!(flags(&p, 0x11), [true; 2]);
    }
}
