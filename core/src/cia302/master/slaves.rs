//! The slaves, one by one: what the master keeps per node-ID ([`Slot`]), its timers (probes,
//! keep-alive waits, the K watchdog) and how they follow the clock, and the slave's entries in
//! the master's dictionary (0x1F82 state, 0x1F84–0x1F88 expected identity). What moves a slot
//! is in `inputs.rs` (node events, SDO results), `boot_run.rs` (its boot process) and
//! `error_control.rs` (losses, guarding, heartbeat consumer).

use super::boot::{BootPhase, ErrorStatus, Process};
use super::config::{ExpectedIdentity, SlaveConfig};
use super::events::MasterEventKind;
use super::network::Network;
use super::objects;
use super::Master;
use crate::cia301::nmt::NmtState;
use crate::cia301::sdo::RequestId;
use crate::frame::cob_id::{NodeId, NodeSet};
use crate::frame::instant::{earliest, earliest_of, shift_back, Duration, Instant};
use crate::od::ObjectDictionary;
use crate::profile::IdProfile;

/// Everything the master keeps per node-ID.
pub(super) struct Slot {
    pub(super) cfg: SlaveConfig,
    /// The configuration the running boot process applies when it is not `cfg`: `cfg` with
    /// the node's concise DCF (0x1F22 sub n) read when the process began.
    pub(super) run: Option<alloc::boxed::Box<SlaveConfig>>,
    /// A program download under way.
    pub(super) program: Option<alloc::boxed::Box<super::program_run::ProgramRun>>,
    pub(super) phase: BootPhase,
    pub(super) process: Option<Process>,
    /// The SDO request in flight to the node (of the running process, or of one dropped).
    pub(super) request: Option<RequestId>,
    /// Begin the process once the request in flight ends.
    pub(super) restart: bool,
    pub(super) queued: bool,
    pub(super) probe_at: Option<Instant>,
    pub(super) wait_until: Option<Instant>,
    /// K watchdog: (configured at, first heartbeat due by).
    pub(super) hb_check: Option<(Instant, Instant)>,
    /// Last NMT command that addressed the node: the state it leads to (`None`: a reset), when.
    pub(super) commanded: Option<(Option<NmtState>, Instant)>,
    pub(super) missing: bool,
    pub(super) missing_reported: bool,
    /// This master's node guards it (0x1F81 guard time), active or standby.
    pub(super) guarded: bool,
    pub(super) last_error: Option<ErrorStatus>,
    pub(super) boot_ups: u32,
}

impl Slot {
    pub(super) const fn new(n: NodeId) -> Slot {
        Slot {
            cfg: SlaveConfig::new(n),
            run: None,
            program: None,
            phase: BootPhase::Unassigned,
            process: None,
            request: None,
            restart: false,
            queued: false,
            probe_at: None,
            wait_until: None,
            hb_check: None,
            commanded: None,
            missing: false,
            missing_reported: false,
            guarded: false,
            last_error: None,
            boot_ups: 0,
        }
    }

    pub(super) fn deadline(&self) -> Option<Instant> {
        earliest_of([
            self.probe_at,
            self.wait_until,
            self.hb_check.map(|(_, d)| d),
        ])
    }

    /// The caller's clock stepped back `by` (the clock contract, [`crate::frame::instant`]).
    fn step_back(&mut self, by: Duration) {
        shift_back(&mut self.probe_at, by);
        shift_back(&mut self.wait_until, by);
        if let Some((armed, due)) = self.hb_check.as_mut() {
            *armed = *armed - by;
            *due = *due - by;
        }
        if let Some((_, at)) = self.commanded.as_mut() {
            *at = *at - by;
        }
    }
}

impl<D: ObjectDictionary, P: IdProfile> Master<D, P> {
    pub(super) fn deadline(&self) -> Option<Instant> {
        let net = match self.network {
            Network::Booting {
                deadline,
                reported: false,
            } => deadline,
            _ => None,
        };
        debug_assert!(
            self.slot_deadline()
                .is_none_or(|t| self.slot_timer.is_some_and(|b| b <= t)),
            "a slot timer was armed without Master::arm"
        );
        earliest(net, self.slot_timer)
    }

    /// The earliest timer of any slot, computed (up to 127 slots: not on every poll).
    fn slot_deadline(&self) -> Option<Instant> {
        earliest_of(self.slots.iter().map(|s| s.deadline()))
    }

    /// A slot timer was set to `t`: the cached lower bound of every slot's timers follows.
    /// Clearing a timer needs nothing (a bound reached early only costs a look at the slots).
    pub(super) fn arm(&mut self, t: Option<Instant>) {
        self.slot_timer = earliest(self.slot_timer, t);
    }

    /// The clock contract ([`crate::frame::instant`]): on every input that carries a time, a step
    /// back of the caller's clock moves every timer of the master back with it (its node and SDO
    /// client watch the clock themselves, on their inputs).
    #[inline]
    pub(super) fn watch_own_clock(&mut self, now: Instant) {
        if let Some(by) = self.clock.step_back(now) {
            self.step_back(by);
        }
    }

    /// Shows the master `now` without anything else happening (no timer runs, nothing is sent):
    /// the master, its node and its SDO client each notice a step back of the caller's clock
    /// and move their times back with it (the clock contract, [`crate::frame::instant`]). For an
    /// owner that watches the clock itself and does not pass every input on to the master, so
    /// that the master measures the same step from the same latest time, once.
    pub fn watch_clock(&mut self, now: Instant) {
        self.watch_own_clock(now);
        self.node.watch_clock(now);
        self.sdo.watch_clock(now);
    }

    #[cold]
    fn step_back(&mut self, by: Duration) {
        for s in self.slots.iter_mut() {
            s.step_back(by);
        }
        // The cached bound moves with the timers (as early as it was: the master wakes when it
        // would have on a clock that never stepped), and takes in a timer that saturated at the
        // end of time: "never" in the bound before, a real deadline once moved back.
        let moved = self.slot_timer.map(|t| t - by);
        self.slot_timer = earliest(moved, self.slot_deadline());
        if let Network::Booting { deadline, .. } = &mut self.network {
            shift_back(deadline, by);
        }
    }

    pub(super) fn on_timers(&mut self, now: Instant) {
        if let Network::Booting {
            deadline: Some(d),
            reported: false,
        } = self.network
        {
            if d <= now {
                self.network = Network::Booting {
                    deadline: Some(d),
                    reported: true,
                };
                let mut nodes = NodeSet::EMPTY;
                for n in self.assigned() {
                    if self.assignment(n).is_mandatory() && !self.slot(n).phase.is_booted() {
                        nodes.insert(n);
                    }
                }
                if !nodes.is_empty() {
                    self.emit(d, MasterEventKind::MandatoryMissing { nodes });
                }
            }
        }
        if self.slot_timer.is_none_or(|t| t > now) {
            return;
        }
        for i in 0..self.slots.len() {
            let (n, s) = self.slots.at_mut(i);
            if s.wait_until.is_some_and(|t| t <= now) {
                s.wait_until = None;
                self.decide_keep_alive(now, n);
            }
            let (_, s) = self.slots.at_mut(i);
            if s.probe_at.is_some_and(|t| t <= now) {
                s.probe_at = None;
                if s.phase == BootPhase::WaitBootUp && self.acting() {
                    self.stats.probes += 1;
                    self.begin(now, n);
                }
            }
            let (_, s) = self.slots.at_mut(i);
            if let Some((armed, due)) = s.hb_check {
                if due <= now {
                    s.hb_check = None;
                    let heard = self.node.remote(n).is_some_and(|v| v.seen > armed);
                    if !heard {
                        self.error_control(due, n, ErrorStatus::K);
                    }
                }
            }
        }
        self.slot_timer = self.slot_deadline();
    }

    /// Stores `n`'s state as 0x1F82 sub n reads it.
    pub(super) fn refresh(&mut self, n: NodeId) {
        let code = self.slave(n).request_nmt_code();
        let _ = self
            .node
            .od_mut()
            .store(objects::REQUEST_NMT, n.raw(), &[code]);
    }

    /// Node `n`'s 0x1F26/0x1F27 entries (zero where the dictionary has none).
    pub(super) fn expected_stamp(&self, n: NodeId) -> super::config::ConfigurationStamp {
        let od = self.node.od();
        let get = |index| od.get_u32(index, n.raw()).unwrap_or(0);
        super::config::ConfigurationStamp {
            date: get(objects::EXPECTED_CONFIG_DATE),
            time: get(objects::EXPECTED_CONFIG_TIME),
        }
    }

    pub(super) fn expected_identity(&self, n: NodeId) -> ExpectedIdentity {
        let od = self.node.od();
        let get = |index| od.get_u32(index, n.raw()).unwrap_or(0);
        ExpectedIdentity {
            device_type: get(objects::DEVICE_TYPE_ID),
            vendor: get(objects::VENDOR_ID),
            product: get(objects::PRODUCT_CODE),
            revision: get(objects::REVISION_NUMBER),
            serial: get(objects::SERIAL_NUMBER),
        }
    }
}
