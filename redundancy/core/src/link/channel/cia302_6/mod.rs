//! CiA 302-6 network redundancy (active-standby), for interoperating with standard devices.
//!
//! - One *default* and one *redundant* channel. Application traffic (PDO, SDO, SYNC, EMCY, NMT)
//!   goes out on the active channel only; heartbeats and boot-ups on both.
//! - Frames are accepted from both channels, so that nothing is lost while the nodes of a
//!   network switch one after the other: heartbeats (sent on both) through the exactly-once
//!   merger, application frames (sent on one) as they come.
//! - **Evaluation** counts heartbeats per producer on the default channel:
//!   - power-on (first own boot-up) + 0x1F60 sub 2: if some producer gave fewer than 3, switch
//!     to redundant;
//!   - reset communication (every later own boot-up) returns to the default channel, and after
//!     0x1F60 sub 3, if some producer gave none, switch to redundant;
//!   - while on redundant, in consecutive windows of sub 2 (sub 3 if sub 2 is zero; one
//!     unbounded window if both are), as soon as every producer gave 3 or more, switch back.
//!
//!   The producers are the nodes of 0x1016; if none are configured, every node whose
//!   heartbeat was heard on either channel in the window. A zero evaluation time skips that
//!   evaluation.
//! - **Channel error counter** (sub 5): each failed transmission on the default channel adds 4
//!   (capped at the threshold, sub 4), each success subtracts 1 (floor 0). Reaching the
//!   threshold disables the default channel (until the counter drops below it again, through
//!   successful heartbeats, which still go out on both) and switches to redundant. A threshold of
//!   zero disables the counter. If sub 1 (maximum transmit delay) is not zero, a frame handed to
//!   the default channel without an outcome within that time counts as failed, so the driver
//!   must report `TxOk`/`TxFailed`.
//! - **Indicate active interface.** A node that switches by its own decision sends CAN-ID 0x7F,
//!   DLC 0, on the new channel. A node that hears 0x7F makes that channel active (without
//!   indicating in turn). 0x7F is consumed by the layer.
//!
//! Units: subs 1–3 are milliseconds (public material does not fix them; ms is what the other
//! CiA 301 times use).

use super::{switched, ChannelPolicy, FrameInfo, PortMask, RxRoute, BOTH};
use crate::link::events::{LinkEvent, LinkEventKind, SwitchReason};
use crate::link::health::Health;
use crate::link::outbox::Outbox;
use duocan_core::frame::instant::{earliest, next_on_grid, shift_back};
use duocan_core::machine::PortStatus;
use duocan_core::NodeSet;
use duocan_core::{Duration, Frame, Id, Instant, NodeId};

/// The "indicate active interface" identifier.
pub const INDICATE_ACTIVE_ID: u16 = 0x7F;
/// Heartbeats per producer a window needs (power-on evaluation and switching back).
pub const REQUIRED_HEARTBEATS: u8 = 3;
/// Transmissions on the default channel tracked for the maximum transmit delay.
const PENDING: usize = 64;

/// The "indicate active interface" frame.
pub fn indicate_active() -> Frame {
    Frame::from_array(Id::Standard(INDICATE_ACTIVE_ID), [])
}

/// CiA 302-6 configuration (0x1F60 and the producers of 0x1016).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub struct Cia3026Config {
    /// Port of the default channel (0 or 1); the other is the redundant channel.
    pub default_channel: u8,
    /// 0x1F60 sub 1: maximum transmit delay (zero: not checked).
    pub max_tx_delay: Duration,
    /// 0x1F60 sub 2: heartbeat evaluation time after power-on.
    pub eval_power_on: Duration,
    /// 0x1F60 sub 3: heartbeat evaluation time after reset communication.
    pub eval_reset: Duration,
    /// 0x1F60 sub 4: channel error counter threshold (zero: counter disabled).
    pub error_threshold: u8,
    /// Heartbeat producers to evaluate (empty: every producer heard).
    pub producers: NodeSet,
}

// Builders: the struct is `#[non_exhaustive]` (it may gain fields), so code outside the crate
// starts from a constructor or `Default` and sets what it needs.
impl Cia3026Config {
    /// The configuration with [`default_channel`](Self::default_channel) replaced.
    #[must_use]
    pub fn with_default_channel(mut self, default_channel: u8) -> Self {
        self.default_channel = default_channel;
        self
    }
    /// The configuration with [`max_tx_delay`](Self::max_tx_delay) replaced.
    #[must_use]
    pub fn with_max_tx_delay(mut self, max_tx_delay: Duration) -> Self {
        self.max_tx_delay = max_tx_delay;
        self
    }
    /// The configuration with [`eval_power_on`](Self::eval_power_on) replaced.
    #[must_use]
    pub fn with_eval_power_on(mut self, eval_power_on: Duration) -> Self {
        self.eval_power_on = eval_power_on;
        self
    }
    /// The configuration with [`eval_reset`](Self::eval_reset) replaced.
    #[must_use]
    pub fn with_eval_reset(mut self, eval_reset: Duration) -> Self {
        self.eval_reset = eval_reset;
        self
    }
    /// The configuration with [`error_threshold`](Self::error_threshold) replaced.
    #[must_use]
    pub fn with_error_threshold(mut self, error_threshold: u8) -> Self {
        self.error_threshold = error_threshold;
        self
    }
    /// The configuration with [`producers`](Self::producers) replaced.
    #[must_use]
    pub fn with_producers(mut self, producers: NodeSet) -> Self {
        self.producers = producers;
        self
    }
}

impl Default for Cia3026Config {
    /// Default channel on port 0, no transmit delay check, 1 s evaluation windows, threshold 16
    /// (four failed transmissions in a row), producers as heard.
    fn default() -> Self {
        Cia3026Config {
            default_channel: 0,
            max_tx_delay: Duration::ZERO,
            eval_power_on: Duration::from_millis(1000),
            eval_reset: Duration::from_millis(1000),
            error_threshold: 16,
            producers: NodeSet::EMPTY,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Phase {
    /// Not booted yet.
    Idle,
    PowerOn {
        until: Instant,
    },
    Reset {
        until: Instant,
    },
    /// On default, nothing to evaluate.
    Running,
    /// On redundant, waiting for the default channel's heartbeats.
    Redundant {
        window_end: Option<Instant>,
    },
}

/// The CiA 302-6 policy.
#[derive(Clone, Debug)]
pub struct Cia3026 {
    cfg: Cia3026Config,
    active: usize,
    counter: u8,
    disabled: bool,
    phase: Phase,
    booted: bool,
    counts: [u8; 128],
    heard: NodeSet,
    pending: heapless::Deque<Instant, PENDING>,
    /// Outcomes still to come for transmissions already counted as timed out.
    late: u32,
}

impl Cia3026 {
    /// On the default channel, waiting for the node's boot-up.
    #[must_use]
    pub fn new(cfg: Cia3026Config) -> Self {
        let cfg = Cia3026Config {
            default_channel: cfg.default_channel.min(1),
            ..cfg
        };
        Cia3026 {
            cfg,
            active: cfg.default_channel as usize,
            counter: 0,
            disabled: false,
            phase: Phase::Idle,
            booted: false,
            counts: [0; 128],
            heard: NodeSet::EMPTY,
            pending: heapless::Deque::new(),
            late: 0,
        }
    }
    /// The configuration.
    pub fn config(&self) -> &Cia3026Config {
        &self.cfg
    }
    /// The active channel.
    pub fn active_channel(&self) -> usize {
        self.active
    }
    /// The channel error counter (0x1F60 sub 5).
    pub fn error_counter(&self) -> u8 {
        self.counter
    }
    /// True while the error counter keeps the default channel disabled.
    pub fn default_disabled(&self) -> bool {
        self.disabled
    }
    /// Heartbeats of `node` counted on the default channel in the current window.
    pub fn heartbeats(&self, node: NodeId) -> u8 {
        self.counts[node.raw() as usize]
    }
    /// The end of the evaluation window in progress, if any.
    pub fn evaluation_deadline(&self) -> Option<Instant> {
        match self.phase {
            Phase::PowerOn { until } | Phase::Reset { until } => Some(until),
            Phase::Redundant { window_end } => window_end,
            Phase::Idle | Phase::Running => None,
        }
    }

    fn default(&self) -> usize {
        self.cfg.default_channel as usize
    }
    fn redundant(&self) -> usize {
        1 - self.default()
    }
    fn recheck(&self) -> Option<Duration> {
        [self.cfg.eval_power_on, self.cfg.eval_reset]
            .into_iter()
            .find(|d| !d.is_zero())
    }
    fn new_window(&mut self) {
        self.counts = [0; 128];
        self.heard = NodeSet::EMPTY;
    }
    fn producers(&self) -> NodeSet {
        if self.cfg.producers.is_empty() {
            self.heard
        } else {
            self.cfg.producers
        }
    }
    /// The producer with the fewest heartbeats on default.
    fn weakest(&self) -> Option<(NodeId, u8)> {
        self.producers()
            .iter()
            .map(|n| (n, self.counts[n.raw() as usize]))
            .min_by_key(|(_, c)| *c)
    }
    fn settle_phase(&mut self, at: Instant) {
        self.phase = if self.active == self.default() {
            Phase::Running
        } else {
            Phase::Redundant {
                window_end: self.recheck().map(|d| at + d),
            }
        };
    }

    fn switch(
        &mut self,
        at: Instant,
        to: usize,
        reason: SwitchReason,
        indicate: bool,
        out: &mut Outbox,
    ) {
        if to == self.active {
            return;
        }
        let from = self.active;
        self.active = to;
        switched(out, at, from, to, reason);
        if indicate {
            out.frame(to, indicate_active());
        }
        self.new_window();
        self.settle_phase(at);
    }

    fn boot_up(&mut self, now: Instant, out: &mut Outbox) {
        let power_on = !self.booted;
        self.booted = true;
        if !power_on {
            // Reset communication: 0x1F60 is a communication object, the channel state resets.
            let d = self.default();
            self.switch(now, d, SwitchReason::ResetCommunication, true, out);
            self.counter = 0;
            self.disabled = false;
        }
        let window = if power_on {
            self.cfg.eval_power_on
        } else {
            self.cfg.eval_reset
        };
        self.new_window();
        if window.is_zero() {
            self.settle_phase(now);
        } else if power_on {
            self.phase = Phase::PowerOn {
                until: now + window,
            };
        } else {
            self.phase = Phase::Reset {
                until: now + window,
            };
        }
    }

    fn evaluate(&mut self, at: Instant, out: &mut Outbox) {
        let reason = match self.phase {
            Phase::PowerOn { .. } => match self.weakest() {
                Some((node, count)) if count < REQUIRED_HEARTBEATS => {
                    Some(SwitchReason::PowerOnEvaluation { node, count })
                }
                _ => None,
            },
            Phase::Reset { .. } => match self.weakest() {
                Some((node, 0)) => Some(SwitchReason::ResetEvaluation { node }),
                _ => None,
            },
            _ => None,
        };
        match reason {
            Some(r) if self.active == self.default() => {
                let to = self.redundant();
                self.switch(at, to, r, true, out);
            }
            _ => {
                self.new_window();
                self.settle_phase(at);
            }
        }
    }

    fn tx_error(&mut self, at: Instant, out: &mut Outbox) {
        let threshold = self.cfg.error_threshold;
        if threshold == 0 {
            return;
        }
        self.counter = self.counter.saturating_add(4).min(threshold);
        if self.counter >= threshold && !self.disabled {
            self.disabled = true;
            out.event(LinkEvent {
                at,
                kind: LinkEventKind::DefaultDisabled {
                    counter: self.counter,
                },
            });
            if self.active == self.default() {
                let to = self.redundant();
                let counter = self.counter;
                self.switch(at, to, SwitchReason::TxErrors { counter }, true, out);
            }
        }
    }

    fn tx_outcome(&mut self) {
        if self.late > 0 {
            self.late -= 1;
        } else {
            self.pending.pop_front();
        }
    }
}

impl ChannelPolicy for Cia3026 {
    fn route_tx(
        &mut self,
        now: Instant,
        frame: &Frame,
        info: &FrameInfo,
        _: &Health,
        out: &mut Outbox,
    ) -> PortMask {
        if info.is_boot_up(frame) {
            self.boot_up(now, out);
        }
        let mask = if info.heartbeat.is_some() {
            BOTH
        } else {
            1 << self.active
        };
        if !self.cfg.max_tx_delay.is_zero() && mask & (1 << self.default()) != 0 {
            if self.pending.is_full() {
                // The driver does not report outcomes fast enough; keep the newest.
                self.pending.pop_front();
            }
            let _ = self.pending.push_back(now);
        }
        mask
    }

    fn on_rx(
        &mut self,
        now: Instant,
        port: usize,
        frame: &Frame,
        info: &FrameInfo,
        out: &mut Outbox,
    ) -> RxRoute {
        if frame.id() == Id::Standard(INDICATE_ACTIVE_ID) && !frame.is_remote() && frame.dlc() == 0
        {
            self.switch(now, port, SwitchReason::Indicated, false, out);
            return RxRoute::Ignore;
        }
        if let Some(n) = info.heartbeat {
            self.heard.insert(n);
            if port == self.default() {
                let c = &mut self.counts[n.raw() as usize];
                *c = c.saturating_add(1);
                if matches!(self.phase, Phase::Redundant { .. })
                    && !self.disabled
                    && self
                        .weakest()
                        .is_some_and(|(_, c)| c >= REQUIRED_HEARTBEATS)
                {
                    let d = self.default();
                    self.switch(now, d, SwitchReason::HeartbeatsBack, true, out);
                }
            }
            return RxRoute::Merge;
        }
        // Application traffic travels on one channel only, so it is never doubled; it is
        // accepted from either, so that nothing is lost while the nodes switch one after the
        // other. (Merging it would be wrong: an unchanged cyclic frame sent before a switch on
        // one channel and after it on the other would look like a twin.)
        RxRoute::Direct
    }

    fn on_status(&mut self, now: Instant, port: usize, status: PortStatus, out: &mut Outbox) {
        if port != self.default() {
            return;
        }
        match status {
            PortStatus::TxOk => {
                self.tx_outcome();
                self.counter = self.counter.saturating_sub(1);
                if self.disabled && self.counter < self.cfg.error_threshold {
                    self.disabled = false;
                }
            }
            PortStatus::TxFailed(_) => {
                self.tx_outcome();
                self.tx_error(now, out);
            }
            _ => {}
        }
    }

    fn handle_timeout(&mut self, now: Instant, out: &mut Outbox) {
        if !self.cfg.max_tx_delay.is_zero() {
            while let Some(&sent) = self.pending.front() {
                let due = sent + self.cfg.max_tx_delay;
                if due > now {
                    break;
                }
                self.pending.pop_front();
                self.late = self.late.saturating_add(1);
                self.tx_error(due, out);
            }
        }
        match self.phase {
            Phase::PowerOn { until } | Phase::Reset { until } if until <= now => {
                self.evaluate(until, out);
            }
            Phase::Redundant {
                window_end: Some(end),
            } if end <= now => {
                // Whole windows that passed without enough heartbeats: start a fresh one.
                // Computed, not stepped: after a jump ahead (or at the end of time) a loop of
                // `next += step` would run for every window missed, or for ever.
                let step = self.recheck().unwrap_or(Duration::MAX);
                let next = next_on_grid(end, step, now);
                self.new_window();
                self.phase = Phase::Redundant {
                    window_end: Some(next),
                };
            }
            _ => {}
        }
    }

    fn poll_timeout(&self) -> Option<Instant> {
        let pending = if self.cfg.max_tx_delay.is_zero() {
            None
        } else {
            self.pending.front().map(|t| *t + self.cfg.max_tx_delay)
        };
        earliest(pending, self.evaluation_deadline())
    }

    fn active(&self) -> Option<usize> {
        Some(self.active)
    }

    fn select(&mut self, now: Instant, port: usize, out: &mut Outbox) -> bool {
        self.switch(now, port.min(1), SwitchReason::Command, true, out);
        true
    }

    fn step_back(&mut self, by: Duration) {
        match &mut self.phase {
            Phase::PowerOn { until } | Phase::Reset { until } => *until = *until - by,
            Phase::Redundant { window_end } => shift_back(window_end, by),
            Phase::Idle | Phase::Running => {}
        }
        for t in self.pending.iter_mut() {
            *t = *t - by;
        }
    }
}

#[cfg(test)]
mod tests;
