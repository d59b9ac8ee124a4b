//! The master's own state, as its private helpers read and write it: its role (acting or
//! not), its own entries (0x1F80 start-up, 0x1F81 slave assignment, the SYNC and TIME production
//! bits), the per-slave slots and its bounded event queue.

use super::*;

impl<D: ObjectDictionary, P: IdProfile> Master<D, P> {
    /// True if the master manages the network now: booted, active, and 0x1F80 bit 0 set.
    pub(super) fn acting(&self) -> bool {
        self.booted && self.active && self.startup().has(NmtStartup::MASTER)
    }

    pub(super) fn startup(&self) -> NmtStartup {
        NmtStartup(self.node.od().get_u32(objects::NMT_STARTUP, 0).unwrap_or(0))
    }

    pub(super) fn assignment(&self, n: NodeId) -> Assignment {
        Assignment(
            self.node
                .od()
                .get_u32(objects::SLAVE_ASSIGNMENT, n.raw())
                .unwrap_or(0),
        )
    }

    pub(super) fn assigned(&self) -> impl Iterator<Item = NodeId> + '_ {
        (1..=127u8)
            .filter_map(NodeId::new)
            .filter(|n| self.assignment(*n).is_slave())
    }

    /// `n`'s slot, or a blank one if it has none (`slot_table.rs`).
    pub(super) fn slot(&self, n: NodeId) -> &super::slaves::Slot {
        self.slots.read(n)
    }

    /// `n`'s slot: given now to a slave that has none (assigned in the dictionary behind the
    /// master's back) while the table has room; else a scratch slot whose writes go nowhere.
    pub(super) fn slot_mut(&mut self, n: NodeId) -> &mut super::slaves::Slot {
        if self.slots.get(n).is_none() && self.assignment(n).is_slave() {
            let _ = self.slots.give(n);
        }
        self.slots.write(n)
    }

    pub(super) fn emit(&mut self, at: Instant, kind: MasterEventKind) {
        if self.events.len() >= self.event_capacity {
            self.stats.events_dropped = self.stats.events_dropped.saturating_add(1);
        } else {
            self.events.push_back(MasterEvent { at, kind });
        }
    }

    /// The node's state: heard after the last command, else as commanded, else as last heard.
    pub(super) fn view_state(&self, n: NodeId) -> Option<NmtState> {
        let heard = self.node.remote(n);
        let state = match (heard, self.slot(n).commanded) {
            (Some(v), Some((_, at))) if v.seen > at => Some(v.state),
            (_, Some((state, _))) => state,
            (h, None) => h.map(|v| v.state),
        };
        // A node that sent its boot-up is pre-operational.
        state.map(|s| match s {
            NmtState::Initialising => NmtState::PreOperational,
            s => s,
        })
    }

    /// Runs the master's own node into operational unless 0x1F80 bit 2 forbids it.
    pub(super) fn self_start(&mut self, now: Instant) {
        if !self.startup().has(NmtStartup::NO_SELF_START)
            && self.node.nmt_state() != NmtState::Operational
        {
            self.node.set_nmt_state(now, NmtState::Operational);
        }
    }

    /// Sets or clears bit 30 of 0x1005 and 0x1012 (SYNC and TIME production) as wanted.
    pub(super) fn set_producers(&mut self, now: Instant, on: bool) {
        for (index, wanted) in [
            (comm::SYNC_COB_ID, self.produce_sync),
            (comm::TIME_COB_ID, self.produce_time),
        ] {
            let Some(v) = self.node.od().get_u32(index, 0) else {
                continue;
            };
            let bit = crate::frame::cob_id::CobId::BIT30;
            let new = if on && wanted { v | bit } else { v & !bit };
            if new != v {
                let data = new.to_le_bytes();
                if self.booted {
                    let _ = self.node.write(now, index, 0, &data);
                } else {
                    let _ = self.node.od_mut().write_local(index, 0, &data);
                }
            }
        }
    }

    /// Writes one of the master's own entries (with the node's reactions once booted).
    pub(super) fn write_own(
        &mut self,
        now: Instant,
        index: u16,
        sub: u8,
        v: u32,
    ) -> Result<(), MasterError> {
        let data = v.to_le_bytes();
        let r = if self.booted {
            self.node.write(now, index, sub, &data)
        } else {
            self.node.od_mut().write_local(index, sub, &data)
        };
        r.map_err(|code| MasterError::Refused { index, sub, code })
    }
}

/// What can be checked of a slave's configuration before it is used.
pub(super) fn check_slave(cfg: &SlaveConfig, master: NodeId) -> Result<(), MasterError> {
    if cfg.node == master {
        return Err(MasterError::OwnNode(cfg.node));
    }
    for step in &cfg.steps {
        if let ConfigStep::Pdo { pdo, .. } = step {
            if !(1..=crate::cia301::pdo::params::MAX_PDOS).contains(pdo) {
                return Err(MasterError::NoSuchPdo {
                    node: cfg.node,
                    pdo: *pdo,
                });
            }
        }
    }
    Ok(())
}
