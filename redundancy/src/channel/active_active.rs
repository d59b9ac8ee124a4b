//! Active-active: every logical frame goes out on every port that is not failed; every received
//! frame goes through the exactly-once merger. No channel to switch.

use super::{ChannelPolicy, FrameInfo, PortMask, RxRoute};
use crate::health::Health;
use crate::outbox::Outbox;
use duocan::machine::PortStatus;
use duocan::{Frame, Instant};

/// The active-active policy.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ActiveActive;

impl ChannelPolicy for ActiveActive {
    fn route_tx(
        &mut self,
        _: Instant,
        _: &Frame,
        _: &FrameInfo,
        h: &Health,
        _: &mut Outbox,
    ) -> PortMask {
        // A failed port gets nothing until it has recovered.
        (h.usable(0) as u8) | (h.usable(1) as u8) << 1
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
}
