//! The flying master's configuration: the CiA 302-2 timing of 0x1F90 (with its defaults, and
//! read from a dictionary whose 0x1F80 makes the device flying-master capable), and what this
//! implementation adds (the master-heartbeat timeout, revertive hand-back).

use super::frames::Rank;
use crate::link::config::{read, ConfigError};
use duocan_core::od::{Access, ObjectDef, ObjectDictionary, ObjectType};
use duocan_core::{Duration, NodeId};

/// 0x1F90 and this implementation's additions.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub struct FlyingMasterConfig {
    /// This device's rank (node-ID, 0x1F90 sub 3 priority).
    pub rank: Rank,
    /// Sub 1: active-master detection timeout (100 ms).
    pub detection_timeout: Duration,
    /// Sub 2: negotiation delay (500 ms).
    pub negotiation_delay: Duration,
    /// Sub 4: priority time slot (1500 ms).
    pub priority_slot: Duration,
    /// Sub 5: device time slot (10 ms).
    pub device_slot: Duration,
    /// Sub 6: multiple-master detect cycle (4000 ms; zero: no periodic detection).
    pub detect_cycle: Duration,
    /// Heartbeat consumer time for the other masters: the takeover deadline.
    pub master_timeout: Duration,
    /// Take the role back from a worse active master (default false: non-revertive).
    pub revertive: bool,
    /// How long a better master must be heard as standby before it is given the role back.
    pub handback_delay: Duration,
}

// Builders: the struct is `#[non_exhaustive]` (it may gain fields), so code outside the crate
// starts from a constructor or `Default` and sets what it needs.
impl FlyingMasterConfig {
    /// The configuration with [`rank`](Self::rank) replaced.
    #[must_use]
    pub fn with_rank(mut self, rank: Rank) -> Self {
        self.rank = rank;
        self
    }
    /// The configuration with [`detection_timeout`](Self::detection_timeout) replaced.
    #[must_use]
    pub fn with_detection_timeout(mut self, detection_timeout: Duration) -> Self {
        self.detection_timeout = detection_timeout;
        self
    }
    /// The configuration with [`negotiation_delay`](Self::negotiation_delay) replaced.
    #[must_use]
    pub fn with_negotiation_delay(mut self, negotiation_delay: Duration) -> Self {
        self.negotiation_delay = negotiation_delay;
        self
    }
    /// The configuration with [`priority_slot`](Self::priority_slot) replaced.
    #[must_use]
    pub fn with_priority_slot(mut self, priority_slot: Duration) -> Self {
        self.priority_slot = priority_slot;
        self
    }
    /// The configuration with [`device_slot`](Self::device_slot) replaced.
    #[must_use]
    pub fn with_device_slot(mut self, device_slot: Duration) -> Self {
        self.device_slot = device_slot;
        self
    }
    /// The configuration with [`detect_cycle`](Self::detect_cycle) replaced.
    #[must_use]
    pub fn with_detect_cycle(mut self, detect_cycle: Duration) -> Self {
        self.detect_cycle = detect_cycle;
        self
    }
    /// The configuration with [`master_timeout`](Self::master_timeout) replaced.
    #[must_use]
    pub fn with_master_timeout(mut self, master_timeout: Duration) -> Self {
        self.master_timeout = master_timeout;
        self
    }
    /// The configuration with [`revertive`](Self::revertive) replaced.
    #[must_use]
    pub fn with_revertive(mut self, revertive: bool) -> Self {
        self.revertive = revertive;
        self
    }
    /// The configuration with [`handback_delay`](Self::handback_delay) replaced.
    #[must_use]
    pub fn with_handback_delay(mut self, handback_delay: Duration) -> Self {
        self.handback_delay = handback_delay;
        self
    }
}

impl FlyingMasterConfig {
    /// The 0x1F90 defaults for a device of `priority` and `node`, with a master-heartbeat timeout.
    #[must_use]
    pub const fn new(priority: u8, node: NodeId, master_timeout: Duration) -> Self {
        FlyingMasterConfig {
            rank: Rank::new(priority, node),
            detection_timeout: Duration::from_millis(100),
            negotiation_delay: Duration::from_millis(500),
            priority_slot: Duration::from_millis(1500),
            device_slot: Duration::from_millis(10),
            detect_cycle: Duration::from_millis(4000),
            master_timeout,
            revertive: false,
            handback_delay: Duration::from_millis(1000),
        }
    }
    /// Wait of a negotiation, from its start.
    pub fn negotiation_wait(&self) -> Duration {
        self.negotiation_delay
            + self.priority_slot.saturating_mul(self.rank.priority as u64)
            + self.device_slot.saturating_mul(self.rank.node.raw() as u64)
    }
}

/// NMT start-up (0x1F80); bit 5 makes a device flying-master capable.
pub const NMT_STARTUP: u16 = 0x1F80;
/// Flying-master timing (0x1F90).
pub const FLYING_MASTER_TIMING: u16 = 0x1F90;
/// 0x1F80 bit 5: NMT flying master.
pub const STARTUP_FLYING_MASTER: u32 = 1 << 5;

/// The seven entries of 0x1F90 with the CiA 302-2 defaults (times in ms).
pub const fn timing_objects() -> [ObjectDef; 7] {
    const fn rec(d: ObjectDef) -> ObjectDef {
        d.object_type(ObjectType::Record)
    }
    const I: u16 = FLYING_MASTER_TIMING;
    [
        rec(ObjectDef::u8(I, 0, Access::Const, 6)).named("NMT flying master timing parameters"),
        rec(ObjectDef::u16(I, 1, Access::Rw, 100)).named("Active master detection timeout"),
        rec(ObjectDef::u16(I, 2, Access::Rw, 500)).named("Negotiation delay"),
        rec(ObjectDef::u16(I, 3, Access::Rw, 0)).named("NMT master priority"),
        rec(ObjectDef::u16(I, 4, Access::Rw, 1500)).named("Priority time slot"),
        rec(ObjectDef::u16(I, 5, Access::Rw, 10)).named("CANopen device time slot"),
        rec(ObjectDef::u16(I, 6, Access::Rw, 4000)).named("Multiple master detect cycle time"),
    ]
}

impl FlyingMasterConfig {
    /// Reads 0x1F80 and 0x1F90 of `node`'s dictionary: `None` if 0x1F80 bit 5 is clear (not a
    /// flying master). The master-heartbeat timeout is not a 302-2 entry and is given.
    pub fn from_od<D: ObjectDictionary>(
        od: &D,
        node: NodeId,
        master_timeout: Duration,
    ) -> Result<Option<Self>, ConfigError> {
        if read(od, NMT_STARTUP, 0)? & STARTUP_FLYING_MASTER == 0 {
            return Ok(None);
        }
        let ms = |sub| read(od, FLYING_MASTER_TIMING, sub).map(|v| Duration::from_millis(v as u64));
        let priority = read(od, FLYING_MASTER_TIMING, 3)?;
        let priority = u8::try_from(priority).map_err(|_| ConfigError::Invalid {
            index: FLYING_MASTER_TIMING,
            sub: 3,
            what: "priority above 255",
        })?;
        Ok(Some(FlyingMasterConfig {
            detection_timeout: ms(1)?,
            negotiation_delay: ms(2)?,
            priority_slot: ms(4)?,
            device_slot: ms(5)?,
            detect_cycle: ms(6)?,
            ..FlyingMasterConfig::new(priority, node, master_timeout)
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use duocan_core::od::{comm, StaticDictionary};

    static COMM: [ObjectDef; comm::COMM_LEN] = comm::communication();
    static STARTUP: [ObjectDef; 1] = [ObjectDef::u32(NMT_STARTUP, 0, Access::Rw, 0)];
    static TIMING: [ObjectDef; 7] = timing_objects();

    #[test]
    fn configuration_from_the_dictionary() {
        let mut od = StaticDictionary::<64, 512>::new();
        od.load(1, &[&COMM, &STARTUP, &TIMING]).unwrap();
        let node = NodeId::must(1);
        let t = Duration::from_millis(50);
        assert_eq!(FlyingMasterConfig::from_od(&od, node, t), Ok(None));
        od.set_value::<u32>(NMT_STARTUP, 0, 0x21).unwrap();
        od.set_value::<u16>(FLYING_MASTER_TIMING, 3, 2).unwrap();
        od.set_value::<u16>(FLYING_MASTER_TIMING, 6, 1000).unwrap();
        let c = FlyingMasterConfig::from_od(&od, node, t).unwrap().unwrap();
        assert_eq!(c.rank, Rank::new(2, node));
        assert_eq!(c.detect_cycle, Duration::from_millis(1000));
        assert_eq!(c.detection_timeout, Duration::from_millis(100));
        assert_eq!(
            c.negotiation_wait(),
            Duration::from_millis(500 + 2 * 1500 + 10)
        );
        od.set_value::<u16>(FLYING_MASTER_TIMING, 3, 300).unwrap();
        assert!(FlyingMasterConfig::from_od(&od, node, t).is_err());
    }
}
