//! Channel policies: which port(s) a logical frame goes out on, which received frames go up,
//! and when the active channel changes. One trait, three policies:
//!
//! - [`active_active`]: both buses carry everything; the receive merger makes one stream.
//! - [`cia302_6`]: CiA 302-6 network redundancy: one active channel, heartbeats on both,
//!   heartbeat evaluation and a transmit-error counter switch channels.
//! - [`ecss`]: ECSS-E-ST-50-15C bus toggling: one active bus; a slave toggles when the
//!   redundancy master's heartbeat is lost.

pub mod active_active;
#[cfg(feature = "cia302-6")]
pub mod cia302_6;
#[cfg(feature = "ecss")]
pub mod ecss;

#[cfg(any(feature = "cia302-6", feature = "ecss"))]
use crate::link::events::{LinkEvent, LinkEventKind, SwitchReason};
use crate::link::health::Health;
use crate::link::outbox::Outbox;
use core::fmt;
use duocan_core::machine::PortStatus;
use duocan_core::{Duration, Frame, Instant, NodeId};

pub use active_active::ActiveActive;
#[cfg(feature = "cia302-6")]
pub use cia302_6::{Cia3026, Cia3026Config};
#[cfg(feature = "ecss")]
pub use ecss::{Ecss, EcssConfig, EcssRole};

/// Ports a frame goes out on: bit `p` set for port `p`.
pub type PortMask = u8;
/// Both ports.
pub const BOTH: PortMask = 0b11;

/// What the layer knows about a frame before a policy sees it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameInfo {
    /// Heartbeat or boot-up of this node.
    pub heartbeat: Option<NodeId>,
}

impl FrameInfo {
    /// True for a boot-up message (a heartbeat with state 0).
    pub fn is_boot_up(&self, frame: &Frame) -> bool {
        self.heartbeat.is_some() && frame.data() == [0]
    }
}

/// Where a received frame goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RxRoute {
    /// Through the exactly-once merger; a twin is expected on the other port (so a port that
    /// never sees twins is silent).
    Merge,
    /// Up as it is (only one port carries it).
    Direct,
    /// Not for the application (inactive bus, link-layer frame).
    Ignore,
}

/// A channel policy.
pub trait ChannelPolicy {
    /// Ports a logical frame goes out on. May queue link-layer frames of its own in `out`.
    fn route_tx(
        &mut self,
        now: Instant,
        frame: &Frame,
        info: &FrameInfo,
        health: &Health,
        out: &mut Outbox,
    ) -> PortMask;
    /// Where a frame received on `port` goes.
    fn on_rx(
        &mut self,
        now: Instant,
        port: usize,
        frame: &Frame,
        info: &FrameInfo,
        out: &mut Outbox,
    ) -> RxRoute;
    /// A port driver reported something.
    fn on_status(&mut self, now: Instant, port: usize, status: PortStatus, out: &mut Outbox);
    /// Time passed.
    fn handle_timeout(&mut self, now: Instant, out: &mut Outbox);
    /// Earliest deadline.
    #[must_use]
    fn poll_timeout(&self) -> Option<Instant>;
    /// The active channel, for single-channel policies.
    fn active(&self) -> Option<usize>;
    /// Makes `port` the active channel by command; false if the policy has none.
    fn select(&mut self, now: Instant, port: usize, out: &mut Outbox) -> bool;
    /// The caller's clock stepped back `by` (the clock contract, see [`crate::link`]): every
    /// time the policy holds moves back with it.
    fn step_back(&mut self, by: Duration);
}

/// Which policy a layer runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ModeKind {
    /// Both buses active.
    ActiveActive,
    /// CiA 302-6 active-standby.
    Cia302_6,
    /// ECSS bus toggling.
    EcssToggle,
}

impl fmt::Display for ModeKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            ModeKind::ActiveActive => "active-active",
            ModeKind::Cia302_6 => "CiA 302-6 active-standby",
            ModeKind::EcssToggle => "ECSS bus toggle",
        })
    }
}

/// The policy of a layer: one of the three, behind [`ChannelPolicy`].
// Not boxed: no heap on no_std targets, and a layer holds exactly one.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
pub enum Policy {
    /// Both buses active.
    ActiveActive(ActiveActive),
    /// CiA 302-6.
    #[cfg(feature = "cia302-6")]
    Cia302_6(Cia3026),
    /// ECSS bus toggling.
    #[cfg(feature = "ecss")]
    EcssToggle(Ecss),
}

impl Policy {
    /// Which one.
    pub fn kind(&self) -> ModeKind {
        match self {
            Policy::ActiveActive(_) => ModeKind::ActiveActive,
            #[cfg(feature = "cia302-6")]
            Policy::Cia302_6(_) => ModeKind::Cia302_6,
            #[cfg(feature = "ecss")]
            Policy::EcssToggle(_) => ModeKind::EcssToggle,
        }
    }
    fn inner(&mut self) -> &mut dyn ChannelPolicy {
        match self {
            Policy::ActiveActive(p) => p,
            #[cfg(feature = "cia302-6")]
            Policy::Cia302_6(p) => p,
            #[cfg(feature = "ecss")]
            Policy::EcssToggle(p) => p,
        }
    }
    fn inner_ref(&self) -> &dyn ChannelPolicy {
        match self {
            Policy::ActiveActive(p) => p,
            #[cfg(feature = "cia302-6")]
            Policy::Cia302_6(p) => p,
            #[cfg(feature = "ecss")]
            Policy::EcssToggle(p) => p,
        }
    }
}

impl ChannelPolicy for Policy {
    fn route_tx(
        &mut self,
        now: Instant,
        frame: &Frame,
        info: &FrameInfo,
        health: &Health,
        out: &mut Outbox,
    ) -> PortMask {
        self.inner().route_tx(now, frame, info, health, out)
    }
    fn on_rx(
        &mut self,
        now: Instant,
        port: usize,
        frame: &Frame,
        info: &FrameInfo,
        out: &mut Outbox,
    ) -> RxRoute {
        self.inner().on_rx(now, port, frame, info, out)
    }
    fn on_status(&mut self, now: Instant, port: usize, status: PortStatus, out: &mut Outbox) {
        self.inner().on_status(now, port, status, out)
    }
    fn handle_timeout(&mut self, now: Instant, out: &mut Outbox) {
        self.inner().handle_timeout(now, out)
    }
    fn poll_timeout(&self) -> Option<Instant> {
        self.inner_ref().poll_timeout()
    }
    fn active(&self) -> Option<usize> {
        self.inner_ref().active()
    }
    fn select(&mut self, now: Instant, port: usize, out: &mut Outbox) -> bool {
        self.inner().select(now, port, out)
    }
    fn step_back(&mut self, by: Duration) {
        self.inner().step_back(by)
    }
}

/// Reports a channel change (the policies with one active channel).
#[cfg(any(feature = "cia302-6", feature = "ecss"))]
pub(crate) fn switched(
    out: &mut Outbox,
    at: Instant,
    from: usize,
    to: usize,
    reason: SwitchReason,
) {
    out.event(LinkEvent {
        at,
        kind: LinkEventKind::Channel {
            from: from as u8,
            to: to as u8,
            reason,
        },
    });
}
