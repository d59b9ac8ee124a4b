//! How the supervisor reacts to what its parts report: the flying master's role changes make the
//! CiA 302-2 master active or standby and set the pair table's authority, the pair table's
//! commands go through the master (only while this master may command), the master's events
//! move the pair table (a member configured, or refused and why).

use super::Supervisor;
use crate::link::dual_bus::LinkCommand;
use crate::supervisor::audit::AuditEntry;
use crate::supervisor::events::{JoinRefusal, NotJoined, SupervisorEvent};
use crate::supervisor::flying_master::{FlyingEvent, MasterRole};
use crate::supervisor::pairs::{Authority, PairCommand};
use duocan_core::master::{MasterEvent, MasterEventKind};
use duocan_core::nmt::NmtTarget;
use duocan_core::node::{NodeEventKind, Writer};
use duocan_core::od::ObjectDictionary;
use duocan_core::profile::IdProfile;
use duocan_core::{Instant, NodeEvent, NodeId};

impl<D: ObjectDictionary, P: IdProfile> Supervisor<D, P> {
    /// Pair supervision commands only while this master may command, follows while another
    /// master is known to be active (or may be), and only records while nobody is.
    pub(super) fn sync_authority(&mut self, now: Instant) {
        let want = if self.fm.may_command(now) {
            Authority::Command
        } else if matches!(
            self.fm.role(),
            MasterRole::Active | MasterRole::Standby(Some(_))
        ) {
            Authority::Shadow
        } else {
            Authority::Idle
        };
        if self.pairs.authority() != want {
            self.pairs.set_authority(now, want);
        }
    }

    pub(super) fn flying_event(&mut self, now: Instant, e: FlyingEvent) {
        match e {
            FlyingEvent::Role(r) => {
                self.audit.record(r.at, AuditEntry::Master(r));
                if r.to.is_active() && !r.from.is_active() {
                    // The master adopts what runs, re-checks what does not, produces SYNC on
                    // the grid it consumed and TIME from the base it consumed. Taking over
                    // from an active master whose SYNC it never heard (it booted after the
                    // last one), it has no grid: SYNC at once, the consumers waited already.
                    self.master.set_active(now, true);
                    if matches!(r.from, MasterRole::Standby(Some(_))) {
                        self.master.node_mut().sync_at_once(now);
                    }
                    if !self.cfg.time_period.is_zero() {
                        let node = self.master.node_mut();
                        node.set_time_period(now, self.cfg.time_period);
                        node.send_time(now);
                    }
                } else if r.from.is_active() && !r.to.is_active() {
                    self.master.set_active(now, false);
                    self.planned = None;
                }
            }
            FlyingEvent::Suspended { at, until } => {
                self.audit.record(at, AuditEntry::Suspended { until });
            }
        }
        self.emit(SupervisorEvent::FlyingMaster(e));
    }

    pub(super) fn pair_command(&mut self, now: Instant, c: PairCommand) {
        match c {
            PairCommand::Nmt { cmd, node } => {
                let sent = self.fm.may_command(now)
                    && self.master.nmt(now, cmd, NmtTarget::Node(node)).is_ok();
                if sent {
                    self.stats.nmt_sent += 1;
                } else {
                    self.stats.nmt_withheld += 1;
                }
            }
            PairCommand::Configure { node, .. } => {
                // A boot process already running for it (begun at its boot-up after a reset
                // by this master, or at the takeover) is the one asked for.
                if !self.fm.may_command(now) || self.master.slave(node).phase.is_running() {
                    return;
                }
                match self.master.boot_slave(now, node) {
                    Ok(()) => self.stats.configs += 1,
                    Err(e) => self.refused(now, node, JoinRefusal::Master(e)),
                }
            }
            PairCommand::SetActive { pair, member } => {
                self.link.push(LinkCommand::SetActive(pair, member));
            }
            PairCommand::Forget { pair, member } => {
                self.link.push(LinkCommand::Forget(pair, member));
            }
        }
    }

    /// A pair member's boot process failed: the table is told, the application too.
    fn refused(&mut self, at: Instant, node: NodeId, why: JoinRefusal) {
        let Some((pair, member)) = self.pairs.locate(node) else {
            return;
        };
        let configuring = self.pairs.is_configuring(node);
        let changed = if why.is_transient() {
            // Not answering: reset, it boots and is configured again.
            self.pairs.configured(at, node, false);
            configuring
        } else {
            // Another device, or one that refuses its configuration: out, whatever its phase,
            // until it boots again.
            let joined = self
                .pairs
                .pair(pair)
                .is_some_and(|p| p.member(member).joined());
            self.pairs.rejected(at, node);
            configuring || joined
        };
        if changed {
            self.emit(SupervisorEvent::NotJoined(NotJoined {
                at,
                pair,
                member,
                node,
                why,
            }));
        }
    }

    pub(super) fn manager_event(&mut self, now: Instant, e: MasterEvent) {
        let at = e.at;
        match e.kind {
            MasterEventKind::Node(kind) => return self.node_event(now, NodeEvent { at, kind }),
            MasterEventKind::Sdo(s) => return self.emit(SupervisorEvent::Sdo(s)),
            MasterEventKind::SlaveConfigured { node, .. } => {
                self.pairs.configured(at, node, true);
            }
            MasterEventKind::IdentityMismatch { node, mismatch } => {
                self.refused(at, node, JoinRefusal::Identity(mismatch))
            }
            MasterEventKind::ConfigFailed {
                node,
                status,
                reason,
            } => self.refused(at, node, JoinRefusal::Config { status, reason }),
            _ => {}
        }
        self.emit(SupervisorEvent::Master(e));
    }

    fn node_event(&mut self, now: Instant, e: NodeEvent) {
        match e.kind {
            NodeEventKind::Sync { produced, .. } => {
                self.last_sync = Some(e.at);
                if produced {
                    self.stats.sync_produced += 1;
                } else {
                    self.stats.sync_received += 1;
                    self.fm.foreign_activity(now);
                }
                return;
            }
            NodeEventKind::NmtObserved { cmd, target } => {
                self.fm.foreign_activity(now);
                self.pairs.nmt_observed(e.at, cmd, target);
            }
            NodeEventKind::ObjectWritten {
                by: Writer::Local, ..
            } => return,
            _ => {}
        }
        self.emit(SupervisorEvent::Node(e));
    }
}
