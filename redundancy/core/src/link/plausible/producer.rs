//! A watched node's producer time changed at run time: rule 1 follows an SDO download to its
//! 0x1017:00.
//!
//! CiA 301 lets anyone with an SDO client write a node's heartbeat producer time while it
//! runs (a service tool on the bus, the application through the master's own client), and
//! the node beats at the new period at once. Rule 1 judges a node's heartbeats by the period
//! it was watched with: a board whose period was halved beats twice as fast as that, exactly
//! as two devices sharing its node-ID would, and was taken for them (suspect within 110 ms,
//! and reset by its master). The layer sees every frame, so it follows the change itself: an
//! expedited download of a value to a watched node's 0x1017:00 (from its own station or from
//! any other client) is remembered, and the server's confirmation makes it the node's period.
//! An abort forgets it. A value of zero (heartbeat off) changes nothing: the node falls silent,
//! which its consumers report as they must. The consumer times are not touched (CiA 301: they
//! are the consumers' own objects).
//!
//! Memory: one pending value per watched node.

use super::{Plausibility, ON};
use duocan_core::{Duration, Frame, Id, NodeId};

/// The producer heartbeat time's object, sub-index 0.
const PRODUCER_TIME: [u8; 3] = [0x17, 0x10, 0x00];

impl Plausibility {
    /// An SDO frame on the bus, received or sent by this station: a download to a watched
    /// node's producer time and its confirmation (see the module documentation).
    #[inline]
    pub(crate) fn on_sdo(&mut self, frame: &Frame) {
        if !ON || self.table.is_none() {
            return;
        }
        let Id::Standard(id @ 0x581..=0x67F) = frame.id() else {
            return;
        };
        let d = frame.data();
        if d.len() != 8 || d[1..4] != PRODUCER_TIME || id & 0x7F == 0 {
            return;
        }
        let Some(node) = NodeId::new((id & 0x7F) as u8) else {
            return;
        };
        let Some(i) = self.find(node) else {
            return;
        };
        if id >= 0x600 {
            // A download request: expedited (command specifier 1, e set), its size if given.
            if d[0] & 0xE2 != 0x22 {
                return;
            }
            let size = if d[0] & 0x01 != 0 {
                4 - usize::from((d[0] >> 2) & 3)
            } else {
                4
            };
            let mut value = [0u8; 4];
            value[..size].copy_from_slice(&d[4..4 + size]);
            let value = u32::from_le_bytes(value);
            // A value beyond 16 bits is refused by the server: nothing changes.
            self.at(i).producer = u16::try_from(value).ok();
            return;
        }
        let pending = self.at(i).producer.take();
        if let (0x60, Some(ms)) = (d[0], pending) {
            if ms != 0 {
                self.watch(node, Duration::from_millis(u64::from(ms)));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sdo(id: u16, data: [u8; 8]) -> Frame {
        Frame::from_array(Id::Standard(id), data)
    }
    fn period(p: &Plausibility, node: u8) -> Option<u64> {
        p.entry(NodeId::must(node)).map(|w| w.period)
    }

    #[test]
    fn a_confirmed_download_to_0x1017_is_the_new_period_and_nothing_else_is() {
        let mut p = Plausibility::new(None);
        assert!(p.watch(NodeId::must(0x10), Duration::from_millis(20)));
        let request = |v: u16| {
            let [lo, hi] = v.to_le_bytes();
            sdo(0x610, [0x2B, 0x17, 0x10, 0x00, lo, hi, 0, 0])
        };
        let done = sdo(0x590, [0x60, 0x17, 0x10, 0x00, 0, 0, 0, 0]);
        // Requested, not confirmed yet: unchanged.
        p.on_sdo(&request(10));
        assert_eq!(period(&p, 0x10), Some(20_000));
        p.on_sdo(&done);
        assert_eq!(period(&p, 0x10), Some(10_000));
        // Aborted: unchanged, and a later confirmation without a request changes nothing.
        p.on_sdo(&request(40));
        p.on_sdo(&sdo(
            0x590,
            [0x80, 0x17, 0x10, 0x00, 0x00, 0x00, 0x09, 0x06],
        ));
        p.on_sdo(&done);
        assert_eq!(period(&p, 0x10), Some(10_000));
        // Zero (heartbeat off) and values beyond 16 bits change nothing.
        p.on_sdo(&request(0));
        p.on_sdo(&done);
        p.on_sdo(&sdo(0x610, [0x23, 0x17, 0x10, 0x00, 0, 0, 1, 0]));
        p.on_sdo(&done);
        assert_eq!(period(&p, 0x10), Some(10_000));
        // Four bytes without a size, one byte with one: both read.
        p.on_sdo(&sdo(0x610, [0x22, 0x17, 0x10, 0x00, 50, 0, 0, 0]));
        p.on_sdo(&done);
        assert_eq!(period(&p, 0x10), Some(50_000));
        p.on_sdo(&sdo(0x610, [0x2F, 0x17, 0x10, 0x00, 30, 0xFF, 0xFF, 0xFF]));
        p.on_sdo(&done);
        assert_eq!(period(&p, 0x10), Some(30_000));
        // Another object, another node, a segmented download: not followed.
        p.on_sdo(&sdo(0x610, [0x2B, 0x16, 0x10, 0x01, 5, 0, 0, 0]));
        p.on_sdo(&sdo(0x590, [0x60, 0x16, 0x10, 0x01, 0, 0, 0, 0]));
        p.on_sdo(&sdo(0x611, [0x2B, 0x17, 0x10, 0x00, 5, 0, 0, 0]));
        p.on_sdo(&sdo(0x591, [0x60, 0x17, 0x10, 0x00, 0, 0, 0, 0]));
        p.on_sdo(&sdo(0x610, [0x21, 0x17, 0x10, 0x00, 2, 0, 0, 0]));
        p.on_sdo(&done);
        assert_eq!(period(&p, 0x10), Some(30_000));
        assert_eq!(period(&p, 0x11), None);
    }
}
