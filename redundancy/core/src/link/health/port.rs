//! One port's health: its state with what only that state knows, its counters, and the
//! records the rules of the parent module ([`super`]) keep per port.

use super::{HealthConfig, HealthCounters};
use duocan_core::frame::instant::shift_back;
use duocan_core::machine::ErrorCause;
use duocan_core::{Duration, Instant};

pub use duocan_core::machine::PortState;

/// Causes that make a port unusable at once.
pub(super) const fn is_fatal(c: ErrorCause) -> bool {
    matches!(
        c,
        ErrorCause::BusOff | ErrorCause::InterfaceDown | ErrorCause::Transceiver
    )
}

/// A port's state with what only that state knows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Condition {
    Ok,
    Suspect,
    Failed {
        /// The back-off ends: the port is re-initialised.
        reinit_at: Instant,
        /// Traffic (a frame, the driver's "up") revives it; not after a transmit stall or a
        /// repeated bus-off, where only the back-off re-initialisation or a frame it was
        /// handed confirmed in time (a probe) does.
        revive_on_rx: bool,
    },
    Recovering {
        /// Its first frame since it recovers: the probation runs from there.
        probation_from: Option<Instant>,
    },
}

impl Condition {
    pub(super) const fn state(self) -> PortState {
        match self {
            Condition::Ok => PortState::Ok,
            Condition::Suspect => PortState::Suspect,
            Condition::Failed { .. } => PortState::Failed,
            Condition::Recovering { .. } => PortState::Recovering,
        }
    }
}

/// State and counters of one port.
#[derive(Clone, Debug)]
pub struct PortHealth {
    /// The state, with the data of that state.
    pub(super) cond: Condition,
    pub(super) since: Instant,
    /// In a state entered for a fault that may have lost frames (see [`PortHealth::back`]).
    pub(super) lossy: bool,
    pub(super) back: Instant,
    /// See [`PortHealth::intact_since`].
    pub(super) intact: Option<Instant>,
    /// Start of the current silence: last frame, entry into recovering, or start of observation.
    pub(super) silence_ref: Option<Instant>,
    /// First first-copy on the other port since this port's last frame.
    pub(super) first_missed: Option<Instant>,
    /// Newest first-copy on the other port since this port's last frame.
    pub(super) last_missed: Option<Instant>,
    pub(super) last_error: Option<Instant>,
    pub(super) attempt: u32,
    pub(super) backoff: Duration,
    /// Lagging beyond the maximum window (the figure that made it so): suspect for that, and
    /// not ok again on traffic until the lag is within the maximum again.
    pub(super) lagging: Option<Duration>,
    /// Frames without an outcome yet, oldest first.
    pub(super) outstanding: heapless::Deque<Handed, OUTSTANDING>,
    /// The newest frame confirmed sent (`TxOk`).
    pub(super) last_sent: Option<Handed>,
    /// The last frames confirmed sent, each with the instant of its confirmation (not of its
    /// hand-over), oldest first: when the other port's oldest waiting frame changes, its
    /// twin's confirmation here is the stall rule's reference.
    #[cfg(feature = "stall-log")]
    pub(super) confirmations: heapless::Deque<Handed, CONFIRMATIONS>,
    /// When its driver last confirmed a transmission (`TxOk`): its bus worked then.
    pub(super) confirmed: Option<Instant>,
    /// When the other port was first seen to have sent a frame handed over no earlier than this
    /// port's oldest waiting one: the stall rule's reference (twins must follow within the
    /// window). Cleared whenever that oldest frame changes.
    pub(super) overtaken: Option<Instant>,
    /// The driver confirms successful transmissions (`TxOk`); only then can silence about a
    /// handed-over frame mean a stall.
    pub(super) reports_outcomes: bool,
    /// Its last transmission was not acknowledged (no-ack) and it has neither sent nor
    /// received a frame since: nobody is reached through it now.
    pub(super) unacknowledged: bool,
    /// When that was reported: only a frame on its bus later than this (by its receive
    /// timestamp) is news that the bus works; a reader running behind still hands over frames
    /// from before the cut.
    pub(super) unacknowledged_at: Instant,
    /// How long after its receive timestamp its last frame was handed over: a reader that
    /// runs behind hands over the twins of the other port's first copies that much later.
    pub(super) rx_delay: Duration,
    /// Went bus-off again before it was back, and no transmission has been confirmed since:
    /// its transmitter is not shown to work, so received frames alone end no probation.
    pub(super) tx_unproven: bool,
    pub(super) counters: HealthCounters,
}

/// A frame handed to a port: when, and which logical frame it is a copy of (the layer numbers
/// them as they are sent: both ports' copies of one frame have the same number, and a later
/// frame a later one, also within an instant).
// Packed to 12 bytes (not 16): two ports keep 64 each, in every layer of a small device.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(C, packed(4))]
pub(super) struct Handed {
    pub(super) at: Instant,
    pub(super) seq: u32,
}

impl Handed {
    /// Handed over no later than `other` (sequence numbers wrap).
    pub(super) fn no_later_than(self, other: Handed) -> bool {
        other.seq.wrapping_sub(self.seq) < 1 << 31
    }
}

/// Transmissions tracked per port for the stall rule.
pub(super) const OUTSTANDING: usize = 64;

#[cfg(feature = "stall-log")]
/// Confirmations remembered per port for the stall rule: a twin confirmed further back than
/// this many frames (a port that far behind) is judged from the oldest remembered, a bound
/// that is late, never early.
pub(super) const CONFIRMATIONS: usize = 16;

#[cfg(feature = "stall-log")]
impl Handed {
    /// The instant the first of `log`'s frames handed over no earlier than `self` was confirmed:
    /// its twin's confirmation, or (the twin not in the log any more) the earliest bound known.
    pub(super) fn twin_confirmed(
        self,
        log: &heapless::Deque<Handed, CONFIRMATIONS>,
    ) -> Option<Instant> {
        log.iter().find(|c| self.no_later_than(**c)).map(|c| c.at)
    }
}

impl PortHealth {
    pub(super) fn new(cfg: &HealthConfig) -> Self {
        PortHealth {
            cond: Condition::Ok,
            since: Instant::ZERO,
            lossy: false,
            back: Instant::ZERO,
            intact: Some(Instant::ZERO),
            silence_ref: None,
            first_missed: None,
            last_missed: None,
            last_error: None,
            attempt: 0,
            backoff: cfg.reinit_first,
            lagging: None,
            outstanding: heapless::Deque::new(),
            #[cfg(feature = "stall-log")]
            confirmations: heapless::Deque::new(),
            last_sent: None,
            confirmed: None,
            overtaken: None,
            reports_outcomes: false,
            unacknowledged: false,
            unacknowledged_at: Instant::ZERO,
            rx_delay: Duration::ZERO,
            tx_unproven: false,
            counters: HealthCounters::default(),
        }
    }
    /// Current state.
    pub fn state(&self) -> PortState {
        self.cond.state()
    }
    /// When it entered the current state.
    pub fn since(&self) -> Instant {
        self.since
    }
    /// When it last came back to ok from a fault that may have lost frames (it failed, or a
    /// transmission or its controller failed); a suspicion for silence or lag alone does not
    /// count. Frames sent on its bus before then may be lost, not late.
    pub fn back(&self) -> Instant {
        self.back
    }
    /// Since when frames sent on its bus have reached it, as far as its health knows: since
    /// it was last ok after a state in which they may not have (failed, recovering, suspect
    /// for errors, and with `silence` for silence; not for a lag alone); `None` while it is in
    /// such a state.
    pub(crate) fn intact_since(&self, silence: bool) -> Option<Instant> {
        if silence {
            self.intact
        } else {
            (!self.lossy).then_some(self.back)
        }
    }
    /// How long after its receive timestamp its last frame was handed over: its bus is shown
    /// up to that long before the present.
    pub(crate) fn rx_delay(&self) -> Duration {
        self.rx_delay
    }
    /// Counters.
    pub fn counters(&self) -> &HealthCounters {
        &self.counters
    }
    /// Re-initialisation attempts since the port was last ok.
    pub fn attempts(&self) -> u32 {
        self.attempt
    }
    /// When the next re-initialisation is due (failed ports).
    pub fn next_reinit(&self) -> Option<Instant> {
        match self.cond {
            Condition::Failed { reinit_at, .. } => Some(reinit_at),
            _ => None,
        }
    }
    /// Its last transmission was not acknowledged and it has neither sent nor received a
    /// frame since: nobody is reached through it now (a cut cable next to this node).
    pub fn unacknowledged(&self) -> bool {
        self.unacknowledged
    }
    /// Whether frames sent through it are known to reach someone: it works (ok or suspect) and
    /// its last transmission was not left unacknowledged.
    pub fn proven(&self) -> bool {
        self.state().is_trusted() && !self.unacknowledged
    }
    /// How many frames handed to it wait for an outcome (its driver reports outcomes), or
    /// `None` if its driver does not report them.
    pub fn in_flight(&self) -> Option<usize> {
        self.reports_outcomes.then_some(self.outstanding.len())
    }
    /// When the oldest frame waiting for an outcome was handed to it (its driver reports
    /// outcomes and one waits).
    pub fn in_flight_since(&self) -> Option<Instant> {
        self.outstanding
            .front()
            .filter(|_| self.reports_outcomes)
            .map(|h| h.at)
    }
    /// The lag that makes it suspect: it lags beyond the maximum skew window
    /// (see [`crate::link::lag`]).
    pub fn lagging(&self) -> Option<Duration> {
        self.lagging
    }
    pub(super) fn step_back(&mut self, by: Duration) {
        self.since = self.since - by;
        self.back = self.back - by;
        self.unacknowledged_at = self.unacknowledged_at - by;
        match &mut self.cond {
            Condition::Failed { reinit_at, .. } => *reinit_at = *reinit_at - by,
            Condition::Recovering { probation_from } => shift_back(probation_from, by),
            Condition::Ok | Condition::Suspect => {}
        }
        for t in [
            &mut self.silence_ref,
            &mut self.first_missed,
            &mut self.last_missed,
            &mut self.last_error,
            &mut self.overtaken,
            &mut self.intact,
            &mut self.confirmed,
            &mut self.counters.last_rx,
        ] {
            shift_back(t, by);
        }
        if let Some((t, _)) = &mut self.counters.last_error {
            *t = *t - by;
        }
        for h in self.outstanding.iter_mut().chain(self.last_sent.as_mut()) {
            h.at = h.at - by;
        }
        #[cfg(feature = "stall-log")]
        for h in &mut self.confirmations {
            h.at = h.at - by;
        }
    }
    /// Failed, and traffic would revive it (not after a transmit stall, which only its
    /// re-initialisation or a probe confirmed in time ends).
    pub fn revives_on_traffic(&self) -> bool {
        matches!(
            self.cond,
            Condition::Failed {
                revive_on_rx: true,
                ..
            }
        )
    }
    /// Failed for a transmit stall (a babbling controller holds its bus, or its own
    /// controller sends late): what it is handed would come out stale; or for a bus-off
    /// again before it was back (its transmitter fails: see the controller reports in
    /// [`super`]).
    pub fn stalled(&self) -> bool {
        matches!(
            self.cond,
            Condition::Failed {
                revive_on_rx: false,
                ..
            }
        )
    }
}
