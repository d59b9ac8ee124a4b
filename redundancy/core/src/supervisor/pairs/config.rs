//! The policy of the whole pair table ([`PairsConfig`]): revertive or not, adoption of members
//! heard without a boot-up and its hold-off, the boot timeout, how a shadow table learns that a
//! member was configured, what a jump of the clock is.

use duocan_core::Duration;

/// Policy of the whole table.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub struct PairsConfig {
    /// Give the role back to A when A rejoins (default: false, non-revertive).
    pub revertive: bool,
    /// Adopt members heard without a boot-up (default: true).
    pub adopt: bool,
    /// How long a member heard without boot-up is watched before it is adopted.
    pub holdoff: Duration,
    /// A configured member not heard for this long after the table started (or after it was
    /// reset) is reported missing.
    pub boot_timeout: Duration,
    /// A shadow table takes a member's first heartbeat after its boot-up as the sign that the
    /// active master configured it (its heartbeat producer time is written last). Right for a
    /// table that sees nothing else; wrong for boards that beat by default. The supervisor sees
    /// the active master's SDO confirmations and clears this
    /// ([`configuration_observed`](super::PairSupervisor::configuration_observed)).
    pub shadow_join_on_heartbeat: bool,
    /// An input this long or more after the latest one the supervisor was given is a jump of
    /// the clock ahead (or a driver that stalled), not time the table watched: the members are
    /// observed again before they are judged ([`PairSupervisor::jumped`](super::PairSupervisor::jumped);
    /// the supervisor takes at least twice its heartbeat period). Default 1 s. A shorter jump
    /// is caught too when the input comes later than the supervisor's earliest deadline by the
    /// smallest slack of its timeouts (see [the clock contract](crate::supervisor)); zero
    /// turns both off.
    pub clock_jump: Duration,
}

// Builders: the struct is `#[non_exhaustive]` (it may gain fields), so code outside the crate
// starts from a constructor or `Default` and sets what it needs.
impl PairsConfig {
    /// The configuration with [`revertive`](Self::revertive) replaced.
    #[must_use]
    pub fn with_revertive(mut self, revertive: bool) -> Self {
        self.revertive = revertive;
        self
    }
    /// The configuration with [`adopt`](Self::adopt) replaced.
    #[must_use]
    pub fn with_adopt(mut self, adopt: bool) -> Self {
        self.adopt = adopt;
        self
    }
    /// The configuration with [`holdoff`](Self::holdoff) replaced.
    #[must_use]
    pub fn with_holdoff(mut self, holdoff: Duration) -> Self {
        self.holdoff = holdoff;
        self
    }
    /// The configuration with [`boot_timeout`](Self::boot_timeout) replaced.
    #[must_use]
    pub fn with_boot_timeout(mut self, boot_timeout: Duration) -> Self {
        self.boot_timeout = boot_timeout;
        self
    }
    /// The configuration with [`clock_jump`](Self::clock_jump) replaced.
    #[must_use]
    pub fn with_clock_jump(mut self, clock_jump: Duration) -> Self {
        self.clock_jump = clock_jump;
        self
    }
    /// The configuration with [`shadow_join_on_heartbeat`](Self::shadow_join_on_heartbeat) replaced.
    #[must_use]
    pub fn with_shadow_join_on_heartbeat(mut self, shadow_join_on_heartbeat: bool) -> Self {
        self.shadow_join_on_heartbeat = shadow_join_on_heartbeat;
        self
    }
}

impl Default for PairsConfig {
    fn default() -> Self {
        PairsConfig {
            revertive: false,
            adopt: true,
            holdoff: Duration::from_millis(200),
            boot_timeout: Duration::from_secs(5),
            shadow_join_on_heartbeat: true,
            clock_jump: Duration::from_secs(1),
        }
    }
}
