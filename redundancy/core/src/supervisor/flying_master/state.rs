//! What a flying master knows: the other master-capable devices ([`Peer`]), and its own phase
//! with the data only that phase has (kept in the variants, so that a role change leaves nothing
//! of the old role behind).

use super::events::MasterRole;
use super::frames::Rank;
use duocan_core::Instant;

/// Other master-capable devices a device keeps track of.
pub const MAX_PEERS: usize = 8;

/// Another master-capable device.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Peer {
    /// Its rank.
    pub rank: Rank,
    /// Last heartbeat (or flying-master frame).
    pub last: Option<Instant>,
    /// Heard without a loss since this device became active.
    pub(super) continuous: bool,
    /// Its heartbeat had been lost (a return is a hint of a healed partition).
    pub(super) lost: bool,
}

/// Where the device is, with the data only that phase has. Every transition builds the new
/// variant whole, so nothing of one role (a detection cycle, a suspension, a hand-back) outlives
/// it into the next; the public [`MasterRole`] is read off it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum State {
    /// Not started.
    Off,
    /// Asked for the active master; negotiates at `until` if nobody answered.
    Detecting { until: Instant },
    /// Announces itself at `until` unless another device announced first.
    Negotiating { until: Instant },
    /// Follows `master` (if known) and takes over at `takeover_at`: the master's heartbeat
    /// deadline, or, the master lost, the end of the slots of the live devices ranked better.
    Standby {
        master: Option<Rank>,
        takeover_at: Instant,
        /// After losing a conflict: the master followed must show it is active (answer a
        /// request for the active master) by then, or a negotiation starts. Two active
        /// masters whose claims cross (each one's message reaching the other after it had
        /// stepped down, a port running behind) would otherwise each follow the other, and
        /// nobody be active.
        confirm_by: Option<Instant>,
    },
    /// The active master, with its own timers.
    Active(Active),
}

/// What only an active master keeps.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) struct Active {
    /// Next periodic 0x76 (none with a zero detect cycle).
    pub(super) detect_at: Option<Instant>,
    /// NMT commands suspended until then (another active master suspected).
    pub(super) suspended_until: Option<Instant>,
    /// A revertive hand-back is due then.
    pub(super) handback_at: Option<Instant>,
    /// The hand-back that became due, until the supervisor takes it.
    pub(super) handback: Option<Rank>,
}

impl State {
    pub(super) fn role(&self) -> MasterRole {
        match self {
            State::Off => MasterRole::Off,
            State::Detecting { .. } => MasterRole::Detecting,
            State::Negotiating { .. } => MasterRole::Negotiating,
            State::Standby { master, .. } => MasterRole::Standby(*master),
            State::Active(_) => MasterRole::Active,
        }
    }
}
