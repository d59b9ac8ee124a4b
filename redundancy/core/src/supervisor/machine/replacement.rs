//! Board replacement by LSS (CiA 305): a pair member that comes up without a node-ID is given
//! its slot's node-ID, then joins like any member.
//!
//! # The rule
//!
//! With [`SupervisorConfig::with_lss`](crate::supervisor::SupervisorConfig::with_lss), the
//! *active* supervisor looks every period, while some pair slot is *vacant* (its member waiting,
//! not rejected for a wrong identity), whether a non-configured board is on the bus (identify
//! non-configured remote slave: one request, one timeout). If one answers, a fastscan gives each
//! board found the node-ID of the vacant slot whose expected identity (0x1F85–0x1F88 of the
//! member, zero parts not checked) it has; a slot without an expected vendor and product is
//! never given to an unknown board. The board then enters reset-communication by itself (CiA
//! 305), sends its boot-up and joins through the normal boot: identity check, configuration,
//! standby while its partner is active.
//!
//! Each board addressed is a [`SupervisorEvent::Addressed`] and an audit record
//! ([`AuditEntry::Addressed`]); every LSS result is a [`SupervisorEvent::Lss`]. A standby
//! supervisor sends no LSS frame: one LSS master on the bus at a time, the active one.
//!
//! # Memory
//!
//! The LSS master's fixed queues and a plan of at most [`LSS_SLOTS`] vacant slots per scan.

use super::Supervisor;
use crate::pair::Member;
use crate::supervisor::audit::{AuditEntry, BoardAddressed};
use crate::supervisor::events::SupervisorEvent;
use crate::supervisor::pairs::Phase;
use duocan_core::cia305::{LssAddress, LssMasterEventKind, LssOutcome, LssPlan, LssService};
use duocan_core::machine::Machine;
use duocan_core::master::objects;
use duocan_core::od::ObjectDictionary;
use duocan_core::profile::IdProfile;
use duocan_core::{Instant, NodeId};

/// Vacant slots one fastscan can place.
pub const LSS_SLOTS: usize = 16;

impl<D: ObjectDictionary, P: IdProfile> Supervisor<D, P> {
    /// The vacant pair slots with the identity the master expects there (vendor and product
    /// known).
    fn vacant_slots(&self) -> impl Iterator<Item = (NodeId, LssAddress)> + '_ {
        let od = self.master.node().od();
        self.pairs
            .pairs()
            .flat_map(|(_, p)| [*p.member(Member::A), *p.member(Member::B)])
            .filter(|m| m.phase() == Phase::Waiting && !m.is_rejected())
            .filter_map(move |m| {
                let get = |index| od.get_u32(index, m.node.raw()).unwrap_or(0);
                let expected = LssAddress {
                    vendor: get(objects::VENDOR_ID),
                    product: get(objects::PRODUCT_CODE),
                    revision: get(objects::REVISION_NUMBER),
                    serial: get(objects::SERIAL_NUMBER),
                };
                (expected.vendor != 0 && expected.product != 0).then_some((m.node, expected))
            })
    }

    /// True while the replacement's LSS master runs no request: another LSS master on the
    /// network (a front door's) may then make one without the slaves' answers mixing.
    pub fn lss_idle(&self) -> bool {
        self.lss.is_idle()
    }

    /// Another LSS master made a request at `now` (one heard on the bus, or this station's
    /// front door's own): the replacement starts nothing for a period after it, so that the
    /// two masters' requests, and the slaves' answers to them, do not mix. (The front door,
    /// for its part, waits for [`Self::lss_idle`].)
    pub fn lss_heard(&mut self, now: Instant) {
        if let Some(period) = self.cfg.lss_period {
            self.lss_due = Some(self.lss_due.map_or(now + period, |d| d.max(now + period)));
        }
    }

    /// At each period: asks whether a board without node-ID is there, if a slot is vacant.
    pub(super) fn lss_tick(&mut self, now: Instant) {
        let Some(period) = self.cfg.lss_period else {
            return;
        };
        if self.lss_due.is_some_and(|d| d > now) {
            return;
        }
        self.lss_due = Some(now + period);
        if self.is_active() && self.lss.is_idle() && self.vacant_slots().next().is_some() {
            let _ = self.lss.identify_non_configured(now);
        }
    }

    /// Acts on what the LSS master reports and passes it on.
    pub(super) fn lss_pump(&mut self, now: Instant) {
        while let Some(e) = self.lss.poll_event() {
            match e.kind {
                LssMasterEventKind::Done(LssOutcome::Identified(
                    LssService::IdentifyNonConfigured,
                    true,
                )) if self.is_active() => {
                    let plan = self
                        .vacant_slots()
                        .fold(LssPlan::<LSS_SLOTS>::new(), |p, (node, expected)| {
                            p.with_expected(expected, node)
                        });
                    if !plan.is_empty() {
                        let _ = self.lss.fastscan(now, plan);
                    }
                }
                LssMasterEventKind::Assigned { address, node } => {
                    if let Some((pair, member)) = self.pairs.locate(node) {
                        let b = BoardAddressed {
                            at: e.at,
                            pair,
                            member,
                            node,
                            address,
                        };
                        self.audit.record(e.at, AuditEntry::Addressed(b));
                        self.emit(SupervisorEvent::Addressed(b));
                    }
                }
                _ => {}
            }
            self.emit(SupervisorEvent::Lss(e));
        }
    }
}
