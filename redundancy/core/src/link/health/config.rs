//! What port health is configured with, and what it counts.

use duocan_core::machine::ErrorCause;
use duocan_core::{Duration, Instant};

/// Timing of the health rules.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub struct HealthConfig {
    /// Silence after which a port fails. Default 300 ms: 3 × a 100 ms guarding period.
    pub silence_limit: Duration,
    /// Silence after which a port is suspect (default: a third of the limit, i.e. one guarding
    /// period). Zero or not below the limit: no silence-suspect step.
    pub suspect_after: Duration,
    /// A suspect port is ok again at the first frame received this long after its last error
    /// report (default: one guarding period).
    pub error_hold: Duration,
    /// A recovering port is ok again at the first frame received this long after its first one
    /// (default: one guarding period). Zero: at the first frame.
    pub probation: Duration,
    /// Back-off before the first re-initialisation of a failed port (default 100 ms).
    pub reinit_first: Duration,
    /// Longest back-off (default 10 s).
    pub reinit_max: Duration,
    /// Apply the silence rule (off in bus-toggle mode, where the inactive bus is quiet by
    /// design).
    pub silence_detection: bool,
    /// Oldest a frame handed to a port may get without a transmit outcome before the port is
    /// flushed and failed (zero: never). Applies once the port's driver has reported an outcome
    /// (drivers that cannot tell are never judged). The dual-bus configuration sets it to the
    /// skew window less the frame time in active-active mode (3 ms by default, see
    /// [`DualBusConfig::frame_time`](crate::DualBusConfig::frame_time)); the layer sets it to
    /// zero in the other modes.
    pub tx_stall: Duration,
}

// Builders: the struct is `#[non_exhaustive]` (it may gain fields), so code outside the crate
// starts from a constructor or `Default` and sets what it needs.
impl HealthConfig {
    /// The configuration with [`silence_limit`](Self::silence_limit) replaced.
    #[must_use]
    pub fn with_silence_limit(mut self, silence_limit: Duration) -> Self {
        self.silence_limit = silence_limit;
        self
    }
    /// The configuration with [`suspect_after`](Self::suspect_after) replaced.
    #[must_use]
    pub fn with_suspect_after(mut self, suspect_after: Duration) -> Self {
        self.suspect_after = suspect_after;
        self
    }
    /// The configuration with [`error_hold`](Self::error_hold) replaced.
    #[must_use]
    pub fn with_error_hold(mut self, error_hold: Duration) -> Self {
        self.error_hold = error_hold;
        self
    }
    /// The configuration with [`probation`](Self::probation) replaced.
    #[must_use]
    pub fn with_probation(mut self, probation: Duration) -> Self {
        self.probation = probation;
        self
    }
    /// The configuration with [`reinit_first`](Self::reinit_first) replaced.
    #[must_use]
    pub fn with_reinit_first(mut self, reinit_first: Duration) -> Self {
        self.reinit_first = reinit_first;
        self
    }
    /// The configuration with [`reinit_max`](Self::reinit_max) replaced.
    #[must_use]
    pub fn with_reinit_max(mut self, reinit_max: Duration) -> Self {
        self.reinit_max = reinit_max;
        self
    }
    /// The configuration with [`silence_detection`](Self::silence_detection) replaced.
    #[must_use]
    pub fn with_silence_detection(mut self, silence_detection: bool) -> Self {
        self.silence_detection = silence_detection;
        self
    }
    /// The configuration with [`tx_stall`](Self::tx_stall) replaced.
    #[must_use]
    pub fn with_tx_stall(mut self, tx_stall: Duration) -> Self {
        self.tx_stall = tx_stall;
        self
    }
}

impl HealthConfig {
    /// The defaults for a given node-guarding (or heartbeat) period: silence limit 3 periods,
    /// suspect after, error hold and probation one period.
    #[must_use]
    pub const fn from_guard_period(period: Duration) -> Self {
        HealthConfig {
            silence_limit: period.saturating_mul(3),
            suspect_after: period,
            error_hold: period,
            probation: period,
            reinit_first: Duration::from_millis(100),
            reinit_max: Duration::from_secs(10),
            silence_detection: true,
            tx_stall: Duration::ZERO,
        }
    }
}

impl Default for HealthConfig {
    fn default() -> Self {
        HealthConfig::from_guard_period(Duration::from_millis(100))
    }
}

/// Number of [`ErrorCause`] variants (the length of [`HealthCounters::errors`]).
pub const ERROR_CAUSES: usize = 14;

/// Index of an error cause in [`HealthCounters::errors`].
pub const fn cause_index(c: ErrorCause) -> usize {
    match c {
        ErrorCause::BusOff => 0,
        ErrorCause::ErrorPassive => 1,
        ErrorCause::ErrorWarning => 2,
        ErrorCause::NoAck => 3,
        ErrorCause::Bit => 4,
        ErrorCause::Stuff => 5,
        ErrorCause::Form => 6,
        ErrorCause::Crc => 7,
        ErrorCause::RxOverflow => 8,
        ErrorCause::TxTimeout => 9,
        ErrorCause::Transceiver => 10,
        ErrorCause::InterfaceDown => 11,
        ErrorCause::Restarted => 12,
        ErrorCause::Other => 13,
    }
}

/// Counters of one port.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct HealthCounters {
    /// Frames received.
    pub rx: u64,
    /// Received frames delivered upward (first copies).
    pub delivered: u64,
    /// Received frames dropped as twins.
    pub duplicates: u64,
    /// Received frames dropped without a twin: older than the merger remembers (a reader that
    /// ran further behind than the horizon), or from a port not proven yet at a time the other
    /// port had already passed (a frame a repaired bus carried from before its fault).
    pub stale: u64,
    /// Frames handed to the port.
    pub tx: u64,
    /// Transmissions the driver confirmed.
    pub tx_ok: u64,
    /// Transmissions the driver reported failed.
    pub tx_failed: u64,
    /// Error reports (controller errors and failed transmissions) by cause
    /// (see [`cause_index`]).
    pub errors: [u32; ERROR_CAUSES],
    /// Re-initialisations requested.
    pub reinits: u32,
    /// Last frame received.
    pub last_rx: Option<Instant>,
    /// Last error reported, with its cause.
    pub last_error: Option<(Instant, ErrorCause)>,
}

impl HealthCounters {
    /// Error reports of one cause.
    pub fn errors_of(&self, c: ErrorCause) -> u32 {
        self.errors[cause_index(c)]
    }
}
