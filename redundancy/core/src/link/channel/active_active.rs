//! Active-active: every logical frame goes out on every port that is not failed (and on both
//! when neither is known to reach anyone, unless one is held by a babble); a failed port still
//! carries the node's own heartbeats, one at a time, as probes; every received frame goes
//! through the exactly-once merger. No channel to switch.

use super::{ChannelPolicy, FrameInfo, PortMask, RxRoute, BOTH};
use crate::link::health::{Health, PortState};
use crate::link::outbox::Outbox;
use duocan_core::machine::PortStatus;
use duocan_core::{Duration, Frame, Instant};

/// The active-active policy.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ActiveActive;

impl ChannelPolicy for ActiveActive {
    fn route_tx(
        &mut self,
        _: Instant,
        _: &Frame,
        info: &FrameInfo,
        h: &Health,
        _: &mut Outbox,
    ) -> PortMask {
        // No port is known to reach anyone (none ok or suspect, or the one that is has just
        // had a frame go unacknowledged: a cut next to this node): both get everything,
        // because sending nowhere is certain silence, and a port marked failed may reach
        // someone again (its bus repaired the moment the other one was cut).
        // Except a port failed for a transmit stall while the other is not: what it is handed
        // waits behind the babble and comes out, stale, when the babble ends.
        if !h.port(0).proven() && !h.port(1).proven() {
            return match [h.port(0).stalled(), h.port(1).stalled()] {
                [true, false] => 0b10,
                [false, true] => 0b01,
                _ => BOTH,
            };
        }
        let mut mask = (h.usable(0) as u8) | (h.usable(1) as u8) << 1;
        // A failed port still carries this node's own heartbeats, one at a time: so that the
        // peers hear at once that its bus works again, and use it, whatever back-off their
        // own re-initialisation of that port runs (the other bus may fail the next instant).
        // A port failed for a transmit stall too: receiving tells nothing of its transmitter
        // (a controller that sends late hears the network fine), so the probe is the test.
        // The stall rule judges it like any frame: late (behind a babble, a slow
        // controller), it is flushed before it could come out stale, and the port stays
        // failed; confirmed in time, the port recovers.
        if info.heartbeat.is_some() {
            for p in 0..2 {
                let port = h.port(p);
                if port.state() == PortState::Failed && port.in_flight().is_none_or(|n| n == 0) {
                    mask |= 1 << p;
                }
            }
        }
        mask
    }
    fn on_rx(&mut self, _: Instant, _: usize, _: &Frame, _: &FrameInfo, _: &mut Outbox) -> RxRoute {
        RxRoute::Merge
    }
    fn on_status(&mut self, _: Instant, _: usize, _: PortStatus, _: &mut Outbox) {}
    fn handle_timeout(&mut self, _: Instant, _: &mut Outbox) {}
    fn poll_timeout(&self) -> Option<Instant> {
        None
    }
    fn active(&self) -> Option<usize> {
        None
    }
    fn select(&mut self, _: Instant, _: usize, _: &mut Outbox) -> bool {
        false
    }
    fn step_back(&mut self, _: Duration) {}
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::health::HealthConfig;
    use duocan_core::machine::ErrorCause;
    use duocan_core::Id;

    #[test]
    fn fan_out_skips_a_failed_port_but_never_leaves_the_node_mute() {
        let mut h = Health::new(HealthConfig::default(), Duration::from_millis(10));
        let mut out = Outbox::new();
        let f = Frame::from_array(Id::Standard(0x705), [5]);
        let info = FrameInfo { heartbeat: None };
        let mut p = ActiveActive;
        let t = Instant::ZERO;
        assert_eq!(p.route_tx(t, &f, &info, &h, &mut out), 0b11);
        h.on_status(t, 0, PortStatus::Down(ErrorCause::InterfaceDown), &mut out);
        assert_eq!(p.route_tx(t, &f, &info, &h, &mut out), 0b10);
        h.on_status(t, 1, PortStatus::Down(ErrorCause::InterfaceDown), &mut out);
        assert_eq!(
            p.route_tx(t, &f, &info, &h, &mut out),
            0b11,
            "both failed: try both"
        );
        // One re-initialised (recovering, unproven), the other failed: still both.
        h.on_status(t, 1, PortStatus::Up, &mut out);
        assert_eq!(h.port(1).state(), crate::PortState::Recovering);
        assert_eq!(p.route_tx(t, &f, &info, &h, &mut out), 0b11);
        // Once a port is proven again, a failed one gets nothing.
        h.on_rx(t, t, 1, crate::link::health::RxOutcome::Delivered, &mut out);
        h.on_rx(
            t + Duration::from_millis(200),
            t + Duration::from_millis(200),
            1,
            crate::link::health::RxOutcome::Delivered,
            &mut out,
        );
        assert_eq!(h.port(1).state(), crate::PortState::Ok);
        assert_eq!(p.route_tx(t, &f, &info, &h, &mut out), 0b10);
    }
}
