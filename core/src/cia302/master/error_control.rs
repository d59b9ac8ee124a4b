//! Error control of the slaves as the master runs it: a slave lost (E, F, K) and what follows
//! per 0x1F80, node guarding per 0x1F81 (active and standby), the master's heartbeat consumer
//! entries (0x1016), and the probing of missing slaves.

use super::boot::{BootPhase, ErrorStatus};
use super::config::NmtStartup;
use super::events::{MasterError, MasterEventKind};
use super::Master;
use crate::cia301::nmt::{NmtCommand, NmtTarget};
use crate::frame::cob_id::NodeId;
use crate::frame::instant::{Duration, Instant};
use crate::od::abort::AbortCode;
use crate::od::{comm, ObjectDictionary};
use crate::profile::IdProfile;

impl<D: ObjectDictionary, P: IdProfile> Master<D, P> {
    /// Error control lost `n` (E, F, K).
    pub(super) fn error_control(&mut self, now: Instant, n: NodeId, status: ErrorStatus) {
        let a = self.assignment(n);
        let phase = self.slot(n).phase;
        // Only a slave whose error control was started counts (a standby cannot tell, so it
        // reports what it sees). Before that its boot-up alone started the consumer: a slave
        // being booted again, failed, or not yet heard is not "lost".
        if !a.is_slave() || !(phase.is_booted() || phase == BootPhase::Observed) {
            return;
        }
        let s = self.slot_mut(n);
        s.missing = true;
        s.last_error = Some(status);
        self.refresh(n);
        self.emit(now, MasterEventKind::SlaveLost { node: n, status });
        if !self.acting() {
            return;
        }
        let startup = self.startup();
        if a.is_mandatory() && startup.has(NmtStartup::RESET_ALL) {
            let _ = self.command(now, NmtCommand::ResetCommunication, NmtTarget::All);
        } else if a.is_mandatory() && startup.has(NmtStartup::STOP_ALL) {
            let _ = self.command(now, NmtCommand::Stop, NmtTarget::All);
        } else if a.reboots() {
            let probe = self.probe_after(now);
            let s = self.slot_mut(n);
            s.phase = BootPhase::WaitBootUp;
            s.probe_at = probe;
            self.arm(probe);
        } else {
            self.slot_mut(n).phase = BootPhase::Failed(status);
        }
    }

    /// Starts (or re-times) node guarding of `n` if its 0x1F81 entry gives a guard time.
    pub(super) fn guard(&mut self, now: Instant, n: NodeId) {
        let a = self.assignment(n);
        if !a.is_slave() || a.guard_time_ms() == 0 {
            return;
        }
        let t = Duration::from_millis(a.guard_time_ms() as u64);
        let guarded = self.node.guard_node(now, n, t, a.retry_factor().max(1));
        self.slot_mut(n).guarded = guarded;
    }

    /// A standby guards the slaves it hears (redundancy: both masters guard, so that each
    /// slave's life guarding sees both, and the standby knows who is alive before it takes
    /// over). An active master starts guarding at the end of the boot process instead.
    pub(super) fn standby_guard(&mut self, now: Instant, n: NodeId) {
        if self.booted && !self.acting() && !self.slot(n).guarded {
            self.guard(now, n);
        }
    }

    pub(super) fn consumer_ms(&self, n: NodeId) -> u16 {
        match self.slot(n).cfg.heartbeat_consumer_ms {
            0 => self.default_consumer_ms,
            ms => ms,
        }
    }

    pub(super) fn probe_after(&self, now: Instant) -> Option<Instant> {
        (!self.probe_interval.is_zero()).then(|| now + self.probe_interval)
    }

    /// Adds (`on`) or clears the master's 0x1016 entry for `n`: the entry already naming `n`,
    /// else sub n if free, else the first free one.
    pub(super) fn set_consumer(
        &mut self,
        now: Instant,
        n: NodeId,
        on: bool,
    ) -> Result<(), MasterError> {
        let ms = if on { self.consumer_ms(n) } else { 0 };
        let od = self.node.od();
        let count = od
            .get_u32(comm::HEARTBEAT_CONSUMER, 0)
            .unwrap_or(0)
            .min(127) as u8;
        let value = |sub: u8| od.get_u32(comm::HEARTBEAT_CONSUMER, sub);
        let names = |sub: u8| value(sub).is_some_and(|v| (v >> 16) as u8 == n.raw());
        let free = |sub: u8| value(sub).is_some_and(|v| v & 0xFFFF == 0 || (v >> 16) as u8 == 0);
        let existing = (1..=count).find(|s| names(*s));
        let sub = match (existing, ms) {
            (Some(s), _) => s,
            (None, 0) => return Ok(()),
            (None, _) => {
                let own = (n.raw() <= count && free(n.raw())).then_some(n.raw());
                match own.or_else(|| (1..=count).find(|s| free(*s))) {
                    Some(s) => s,
                    None => {
                        return Err(MasterError::Refused {
                            index: comm::HEARTBEAT_CONSUMER,
                            sub: 0,
                            code: AbortCode::NO_RESOURCE,
                        })
                    }
                }
            }
        };
        let v = if ms == 0 {
            0
        } else {
            ((n.raw() as u32) << 16) | ms as u32
        };
        self.write_own(now, comm::HEARTBEAT_CONSUMER, sub, v)
    }
}
