//! What the application does with a supervisor: add pairs and slaves, read the parts' state,
//! send NMT commands, switch a pair over, hand the master role over or take it.

use super::{Planned, Supervisor};
use crate::link::dual_bus::LinkCommand;
use crate::link::events::LinkEvent;
use crate::pair::{Member, PairId, PairSpec};
use crate::supervisor::audit::{AuditEntry, AuditTrail, AUDIT_CAPACITY};
use crate::supervisor::events::{AddPairError, SupervisorStats};
use crate::supervisor::flying_master::{FlyingMaster, FlyingMasterError, MasterRole};
use crate::supervisor::pairs::{PairState, PairSupervisor, PairsError};
use duocan_core::frame::storage::Heap;
use duocan_core::master::{
    objects, Assignment, Master, MasterError, MasterNode, MasterSdoClient, SlaveConfig, SlaveView,
    StartPolicy,
};
use duocan_core::nmt::NmtTarget;
use duocan_core::od::{comm, ObjectDictionary};
use duocan_core::profile::IdProfile;
use duocan_core::time_stamp::TimeOfDay;
use duocan_core::{AbortCode, Duration, Instant, NmtCommand, NodeId};

impl<D: ObjectDictionary, P: IdProfile> Supervisor<D, P> {
    /// Adds a slave pair to supervise; both members become slaves of the master with nothing
    /// configured but their heartbeat (and the device type of `spec`, if not 0).
    pub fn add_pair(&mut self, now: Instant, spec: PairSpec) -> Result<PairId, AddPairError> {
        self.add_pair_with(
            now,
            spec,
            SlaveConfig::new(spec.a),
            SlaveConfig::new(spec.b),
        )
    }

    /// Adds a slave pair whose members the master configures as `a` and `b` say (identity,
    /// configuration steps, PDOs, guarding in the assignment). The supervisor overrides what
    /// pair supervision needs: the node-IDs of `spec`, the heartbeat (producer and consumer time
    /// of `spec`), start by the application, no boot of the master's own accord, neither
    /// mandatory nor keep-alive; `spec`'s device type where the identity leaves it unchecked.
    pub fn add_pair_with(
        &mut self,
        now: Instant,
        spec: PairSpec,
        a: SlaveConfig,
        b: SlaveConfig,
    ) -> Result<PairId, AddPairError> {
        self.watch_clock(now);
        self.pairs.check(&spec)?;
        let ms = |d: Duration| d.as_millis().min(u16::MAX as u64) as u16;
        let member = |node: NodeId, mut c: SlaveConfig| {
            c.node = node;
            c.assignment = Assignment(
                (c.assignment.0 | Assignment::SLAVE)
                    & !(Assignment::BOOT | Assignment::MANDATORY | Assignment::KEEP_ALIVE),
            );
            if c.identity.device_type == 0 {
                c.identity.device_type = spec.device_type;
            }
            c.heartbeat(ms(spec.producer_time), ms(spec.consumer_time))
                .start(StartPolicy::Application)
        };
        self.master
            .add_slave(now, member(spec.a, a))
            .map_err(|e| AddPairError::Master(spec.a, e))?;
        if let Err(e) = self.master.add_slave(now, member(spec.b, b)) {
            // Not half a pair: A is no slave of this master again.
            let _ = self.master.node_mut().write(
                now,
                objects::SLAVE_ASSIGNMENT,
                spec.a.raw(),
                &0u32.to_le_bytes(),
            );
            self.pump(now);
            return Err(AddPairError::Master(spec.b, e));
        }
        let id = self.pairs.add_pair(now, spec)?;
        self.measure_timeouts();
        // The layer judges the members' heartbeats against the producer time they get.
        for node in [spec.a, spec.b] {
            self.link.push(LinkCommand::Watch {
                node,
                producer_ms: ms(spec.producer_time),
            });
        }
        self.pump(now);
        Ok(id)
    }

    /// Adds (or replaces) a slave that is no pair member: booted, configured and started by the
    /// master as `cfg` says.
    pub fn add_slave(&mut self, now: Instant, cfg: SlaveConfig) -> Result<(), MasterError> {
        self.watch_clock(now);
        let r = self.master.add_slave(now, cfg);
        self.pump(now);
        r
    }

    // ----- application API -----

    /// This master's role.
    pub fn role(&self) -> MasterRole {
        self.fm.role()
    }
    /// True when active.
    pub fn is_active(&self) -> bool {
        self.fm.is_active()
    }
    /// True when this master may send NMT commands now (active, not suspended by a suspected
    /// second active master).
    pub fn may_command(&self, now: Instant) -> bool {
        self.fm.may_command(now)
    }
    /// The flying master (rank, peers, active master).
    pub fn flying_master(&self) -> &FlyingMaster {
        &self.fm
    }
    /// The pair table.
    pub fn pairs(&self) -> impl Iterator<Item = (PairId, &PairState)> + '_ {
        self.pairs.pairs()
    }
    /// The pair supervision.
    pub fn pair_supervisor(&self) -> &PairSupervisor<Heap> {
        &self.pairs
    }
    /// The CiA 302-2 master (its view of every slave, its node, its SDO client).
    pub fn master(&self) -> &Master<D, P> {
        &self.master
    }
    /// Every slave of the master, pair members included: state, boot phase, errors.
    pub fn slaves(&self) -> impl Iterator<Item = SlaveView> + '_ {
        self.master.slaves()
    }
    /// The master's node (states of every node heard: [`Node::remotes`](duocan_core::Node::remotes)).
    pub fn node(&self) -> &MasterNode<D, P> {
        self.master.node()
    }
    /// The master's node, for the application's own use (its dictionary, EMCY, TPDOs). NMT
    /// commands belong in [`Supervisor::nmt`].
    pub fn node_mut(&mut self) -> &mut MasterNode<D, P> {
        self.master.node_mut()
    }
    /// The master's SDO client, for the application's transfers; their results arrive as
    /// [`SupervisorEvent::Sdo`](crate::supervisor::SupervisorEvent::Sdo). A transfer to a slave
    /// the master is booting waits for the boot's (the client refuses it as busy).
    pub fn sdo_mut(&mut self) -> &mut MasterSdoClient {
        self.master.sdo_mut()
    }
    /// Sends an NMT command through the master, if this master may command now. Pair members
    /// are better switched with [`Supervisor::switch_over`]: the pair table does not follow its
    /// own master's commands.
    pub fn nmt(
        &mut self,
        now: Instant,
        cmd: NmtCommand,
        target: NmtTarget,
    ) -> Result<(), MasterError> {
        self.watch_clock(now);
        if !self.fm.may_command(now) {
            return Err(MasterError::Standby);
        }
        let r = self.master.nmt(now, cmd, target);
        if r.is_ok() {
            self.pairs.application_nmt(cmd, target.code());
        }
        self.pump(now);
        r
    }
    /// The audit trail.
    pub fn audit(&self) -> &AuditTrail<AUDIT_CAPACITY, Heap> {
        &self.audit
    }
    /// Counters.
    pub fn stats(&self) -> SupervisorStats {
        SupervisorStats {
            tx_dropped: self.tx.dropped(),
            events_dropped: self.events_dropped,
            ..self.stats
        }
    }
    /// Sets the network time (the active master then produces TIME from it).
    pub fn set_time(&mut self, now: Instant, tod: TimeOfDay) {
        self.watch_clock(now);
        self.master.node_mut().set_time(now, tod);
    }
    /// Changes the SYNC period (0x1006) to `period`, or to none (`None`, or zero): SYNC
    /// stops. Only the period changes: production stays the flying master's, so an active
    /// master produces at the new period at once and a standby one produces nothing until it
    /// takes over, then at this period (planned switches align to it too). The producer is
    /// switched off while the period changes, as CiA 301 wants, and on again if it ran. A
    /// period beyond 0x1006's 32 bits of µs (some 71 minutes) is held at that; an entry the
    /// master's dictionary refuses is the abort code.
    pub fn set_sync_period(
        &mut self,
        now: Instant,
        period: Option<Duration>,
    ) -> Result<(), AbortCode> {
        self.watch_clock(now);
        let period = period.unwrap_or(Duration::ZERO);
        let us = period.as_micros().min(u64::from(u32::MAX)) as u32;
        self.master.set_production(now, false, true);
        let r = self.master.node_mut().set(now, comm::SYNC_PERIOD, 0, us);
        if r.is_ok() {
            self.cfg.sync_period = Duration::from_micros(u64::from(us));
        }
        self.master
            .set_production(now, !self.cfg.sync_period.is_zero(), true);
        self.pump(now);
        r
    }
    /// Makes `to` the active member of `pair` by hand (active master only).
    pub fn switch_over(
        &mut self,
        now: Instant,
        pair: PairId,
        to: Member,
    ) -> Result<(), PairsError> {
        self.watch_clock(now);
        self.pairs.switch_over(now, pair, to)?;
        self.pump(now);
        Ok(())
    }
    /// Puts this (active) master in standby by hand: the role is handed to the best live
    /// master between two SYNCs.
    pub fn set_standby(&mut self, now: Instant) -> Result<(), FlyingMasterError> {
        self.watch_clock(now);
        if !self.fm.is_active() {
            return Err(FlyingMasterError::WrongRole(self.fm.role()));
        }
        if !self.fm.peers().iter().any(|p| {
            p.last
                .is_some_and(|l| l + self.cfg.flying.master_timeout > now)
        }) {
            return Err(FlyingMasterError::NoSuccessor);
        }
        self.plan(now, Planned::HandOver(None));
        Ok(())
    }
    /// Makes this (standby) master active by hand, between two SYNCs.
    pub fn set_active(&mut self, now: Instant) -> Result<(), FlyingMasterError> {
        self.watch_clock(now);
        if self.fm.is_active() {
            return Err(FlyingMasterError::WrongRole(self.fm.role()));
        }
        self.plan(now, Planned::TakeOver);
        Ok(())
    }
    /// Records a dual-bus event in the audit trail if it is a switch, toggle or port change.
    pub fn audit_link(&mut self, e: &LinkEvent) {
        if AuditEntry::link_worth_recording(e) {
            self.audit.record(e.at, AuditEntry::Link(*e));
        }
    }
}
