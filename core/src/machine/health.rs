//! A port's health as a link over several ports keeps it (the dual-bus layer's port health):
//! its state and why it changed. Declared here, below every link, so that what reports it —
//! the layer's events, the front door's — names one type.

use super::ErrorCause;
use crate::Duration;
use core::fmt;

/// The health of a port.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PortState {
    /// Working.
    Ok,
    /// Errors reported, silent for a while, or lagging beyond the maximum skew window; still
    /// used (a lagging one only to match twins while the other port delivers).
    Suspect,
    /// Not used for transmission; waiting for re-initialisation.
    Failed,
    /// Re-initialised or receiving again; used for transmission, not yet trusted for delivery.
    Recovering,
}

impl PortState {
    /// Ok or suspect: frames from it are delivered.
    pub const fn is_trusted(self) -> bool {
        matches!(self, PortState::Ok | PortState::Suspect)
    }
    /// Its name: `"ok"`, `"suspect"`, `"failed"` or `"recovering"` (what `Display` prints).
    pub const fn as_str(self) -> &'static str {
        match self {
            PortState::Ok => "ok",
            PortState::Suspect => "suspect",
            PortState::Failed => "failed",
            PortState::Recovering => "recovering",
        }
    }
}

impl fmt::Display for PortState {
    // `pad`, not `write_str`: the status table lines its columns up with `{:<11}`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.pad(self.as_str())
    }
}

/// Why a port changed state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum PortReason {
    /// Nothing received for `silent` while the other port kept receiving first copies.
    Silence {
        /// How long it has been silent.
        silent: Duration,
    },
    /// The controller reported an error.
    Controller(ErrorCause),
    /// A transmission failed.
    TxFailed(ErrorCause),
    /// A frame handed to the port got no transmit outcome for `waited`: the port cannot send
    /// (a babbling node holds the bus, the controller is stuck); its queue was flushed.
    TxStalled {
        /// How long the oldest frame waited.
        waited: Duration,
    },
    /// The driver reported the port down.
    Down(ErrorCause),
    /// The driver reported the port up again.
    Up,
    /// The layer asked the driver to re-initialise the port (attempt number, from 1).
    Reinit {
        /// Attempt since the port last was ok.
        attempt: u32,
    },
    /// Frames are received again.
    Traffic,
    /// Its frames arrive `lag` after their twins on the other bus, beyond the maximum skew
    /// window: they are used only while the other bus is silent.
    Lag {
        /// The measured lag.
        lag: Duration,
    },
    /// Its lag is within the maximum skew window again (`lag`, zero when gone): trusted again.
    LagWithin {
        /// The measured lag.
        lag: Duration,
    },
}

impl fmt::Display for PortReason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PortReason::Silence { silent } => write!(f, "nothing received for {silent}"),
            PortReason::Controller(c) => write!(f, "controller reported {c}"),
            PortReason::TxFailed(c) => write!(f, "transmission failed: {c}"),
            PortReason::TxStalled { waited } => {
                write!(f, "transmission stalled for {waited}: queue flushed")
            }
            PortReason::Down(c) => write!(f, "port down: {c}"),
            PortReason::Up => f.write_str("port up again"),
            PortReason::Reinit { attempt } => write!(f, "re-initialised (attempt {attempt})"),
            PortReason::Traffic => f.write_str("frames received again"),
            PortReason::Lag { lag } => write!(
                f,
                "lags {lag} behind the other bus, beyond the maximum window: used only while the other bus is silent"
            ),
            PortReason::LagWithin { lag } => {
                write!(f, "lag {lag}, within the maximum window again")
            }
        }
    }
}
