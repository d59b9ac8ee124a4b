//! How a driver runs the master: the [`Machine`] implementation. Frames and timeouts go to its
//! node, then to its SDO client while a transfer may be running (an idle client is skipped: it
//! has nothing to say until a transfer starts), then the boot and error-control machinery pumps
//! what they produced.
//!
//! CAN FD frames (feature `fd`) go to the node only: on a CANopen FD network the master's node
//! serves USDO (CiA 1301) from its dictionary as any node does (its configuration's
//! [`NodeConfig::fd`](crate::node::NodeConfig::fd)), so a tool reads and writes the master's
//! objects there too. The master's own client stays SDO (its boot and configuration of slaves).

use super::*;

impl<D: ObjectDictionary, P: IdProfile> Machine for Master<D, P> {
    type Event = MasterEvent;
    type LinkCommand = core::convert::Infallible;

    fn handle_frame(&mut self, now: Instant, frame: &Frame) {
        self.watch_own_clock(now);
        self.node.handle_frame(now, frame);
        if !self.sdo_idle {
            self.sdo.handle_frame(now, frame);
        }
        self.pump(now);
    }

    fn handle_timeout(&mut self, now: Instant) {
        self.watch_own_clock(now);
        self.node.handle_timeout(now);
        if !self.sdo_idle {
            self.sdo.handle_timeout(now);
        }
        self.pump(now);
        self.on_timers(now);
        self.pump(now);
    }

    fn poll_transmit(&mut self) -> Option<Frame> {
        if let Some(f) = self.nmt_out.pop_front() {
            return Some(f);
        }
        if let Some(f) = self.node.poll_transmit() {
            return Some(f);
        }
        if self.sdo_idle {
            return None;
        }
        let f = self.sdo.poll_transmit();
        // Drained and nothing running: nothing can come out of it until a transfer starts.
        self.sdo_idle = f.is_none() && self.sdo.in_flight() == 0;
        f
    }

    fn poll_timeout(&self) -> Option<Instant> {
        let sdo = if self.sdo_idle {
            None
        } else {
            self.sdo.poll_timeout()
        };
        earliest_of([self.node.poll_timeout(), sdo, self.deadline()])
    }

    fn poll_event(&mut self) -> Option<MasterEvent> {
        self.events.pop_front()
    }

    #[cfg(feature = "fd")]
    fn handle_frame_fd(&mut self, now: Instant, frame: &crate::frame::FdFrame) {
        self.watch_own_clock(now);
        self.node.handle_frame_fd(now, frame);
        // A USDO write to the master's dictionary has the reactions of an SDO one.
        self.pump(now);
    }

    #[cfg(feature = "fd")]
    fn poll_transmit_fd(&mut self) -> Option<crate::frame::FdFrame> {
        self.node.poll_transmit_fd()
    }
}
