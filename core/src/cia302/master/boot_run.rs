//! The boot processes run by the master, one per slave: begun, cancelled, each SDO access issued
//! on a session of the client (or queued for one, first come first served), each outcome
//! applied (configured, started or left to the application, adopted, missing, failed). The
//! process itself, a pure state machine, is in `boot/`.

use super::boot::{BootError, BootPhase, ErrorStatus, Outcome, Process};
use super::concise::{ConciseDcf, ConciseError};
use super::config::SlaveConfig;
use super::config::{NmtStartup, StartPolicy};
use super::events::{MasterError, MasterEventKind};
use super::objects::CONCISE_DCF;
use super::Master;
use crate::cia301::nmt::{NmtCommand, NmtState};
use crate::cia301::sdo::{SdoErrorKind, SdoOptions};
use crate::frame::cob_id::NodeId;
use crate::frame::instant::{Duration, Instant};
use crate::od::ObjectDictionary;
use crate::profile::IdProfile;
use alloc::boxed::Box;

impl<D: ObjectDictionary, P: IdProfile> Master<D, P> {
    /// (Re)starts the boot process of `n` from the identity check.
    ///
    /// A request still in flight to `n` is waited for, not aborted: SDO frames carry no
    /// transaction number, so a server that got the old request (after its reset, say) would
    /// answer it into the new transfer. Its result is dropped and the process begins then.
    pub(super) fn begin(&mut self, now: Instant, n: NodeId) {
        self.cancel(n);
        let stamp = self.expected_stamp(n);
        let s = self.slot_mut(n);
        if s.program.is_some() {
            // Its program is being replaced: booted when that ends.
            s.restart = true;
            return;
        }
        s.phase = BootPhase::Identifying;
        if s.request.is_some() {
            s.restart = true;
            return;
        }
        let run = match self.concise_config(n) {
            Ok(run) => run,
            Err(e) => {
                // Refused before anything is written: no half configuration.
                let reason = BootError::ConciseDcf(e);
                let status = ErrorStatus::J;
                return self.apply(now, n, Outcome::Failed { status, reason });
            }
        };
        let s = self.slot_mut(n);
        s.run = run;
        s.process = Some(Process::new(s.run.as_deref().unwrap_or(&s.cfg), stamp));
        self.stats.boots_started += 1;
        self.issue(now, n);
    }

    /// Drops whatever runs for `n`: its process, its place in the session queue, its timers.
    /// A transfer in flight ends by itself (its result is dropped).
    pub(super) fn cancel(&mut self, n: NodeId) {
        let s = self.slot_mut(n);
        s.process = None;
        s.restart = false;
        s.probe_at = None;
        s.wait_until = None;
        s.hb_check = None;
        if core::mem::take(&mut s.queued) {
            self.waiting.retain(|x| *x != n);
        }
    }

    /// Starts the current access of `n`'s process, or queues `n` for a session.
    pub(super) fn issue(&mut self, now: Instant, n: NodeId) {
        if self.slot(n).program.is_some() {
            return self.issue_program(now, n);
        }
        let opts = SdoOptions {
            timeout: self.sdo_timeout,
            ..SdoOptions::default()
        };
        let Some(s) = self.slots.get_mut(n) else {
            return;
        };
        let Some(p) = s.process.as_ref() else {
            return;
        };
        let Some(access) = p.access(s.run.as_deref().unwrap_or(&s.cfg)) else {
            return;
        };
        self.sdo_idle = false;
        let started = match access {
            super::boot::Access::Read { index, sub } => self.sdo.upload(now, n, index, sub, opts),
            super::boot::Access::Write { index, sub, data } => {
                self.sdo.download(now, n, index, sub, data, opts)
            }
        };
        match started {
            Ok(r) => {
                s.request = Some(r);
                s.phase = if p.configuring() {
                    BootPhase::Configuring
                } else {
                    BootPhase::Identifying
                };
            }
            Err(e) if matches!(e.kind, SdoErrorKind::Busy | SdoErrorKind::NoSession { .. }) => {
                if !s.queued {
                    s.queued = true;
                    self.waiting.push_back(n);
                    self.stats.jobs_queued += 1;
                    self.stats.max_waiting = self.stats.max_waiting.max(self.waiting.len() as u32);
                }
            }
            Err(e) => {
                let id = self.expected_identity(n);
                let s = self.slot_mut(n);
                if let Some(p) = s.process.as_mut() {
                    let out = p.handle(s.run.as_deref().unwrap_or(&s.cfg), &id, Err(e));
                    self.apply(now, n, out);
                }
            }
        }
    }

    /// Gives waiting slaves the sessions that became free, in arrival order.
    pub(super) fn dispatch(&mut self, now: Instant) {
        let mut tries = self.waiting.len();
        while tries > 0 && self.sdo.in_flight() < self.sdo.sessions() {
            tries -= 1;
            let Some(n) = self.waiting.pop_front() else {
                break;
            };
            self.slot_mut(n).queued = false;
            let counted = self.stats.jobs_queued;
            self.issue(now, n);
            // Still waiting (its node busy with the application's transfer): the same wait.
            if self.slot(n).queued {
                self.stats.jobs_queued = counted;
            }
        }
    }

    pub(super) fn apply(&mut self, now: Instant, n: NodeId, out: Outcome) {
        let refused = self
            .slot_mut(n)
            .process
            .as_mut()
            .and_then(|p| p.take_abort());
        if let Some((index, sub, code)) = refused {
            self.emit(
                now,
                MasterEventKind::ConfigWriteAborted {
                    node: n,
                    index,
                    sub,
                    code,
                },
            );
        }
        match out {
            Outcome::Continue => self.issue(now, n),
            Outcome::Done => {
                self.slot_mut(n).process = None;
                self.configured(now, n);
            }
            Outcome::Mismatch(mismatch) => {
                self.fail(n, mismatch.status);
                self.emit(now, MasterEventKind::IdentityMismatch { node: n, mismatch });
            }
            Outcome::Failed {
                status: ErrorStatus::B,
                reason,
            } => {
                // Not answering: missing. Reported once per absence; probed until it answers.
                let probe = self.probe_after(now);
                let s = self.slot_mut(n);
                s.process = None;
                s.phase = BootPhase::WaitBootUp;
                s.probe_at = probe;
                s.missing = true;
                s.last_error = Some(ErrorStatus::B);
                let report = !core::mem::replace(&mut s.missing_reported, true);
                self.arm(probe);
                self.refresh(n);
                if report {
                    self.emit(
                        now,
                        MasterEventKind::ConfigFailed {
                            node: n,
                            status: ErrorStatus::B,
                            reason,
                        },
                    );
                }
            }
            Outcome::Failed { status, reason } => {
                self.fail(n, status);
                self.emit(
                    now,
                    MasterEventKind::ConfigFailed {
                        node: n,
                        status,
                        reason,
                    },
                );
            }
        }
    }

    /// `n`'s configuration with its concise DCF (0x1F22 sub n) when the master has one for
    /// it; `None`: its configuration as given.
    fn concise_config(&self, n: NodeId) -> Result<Option<Box<SlaveConfig>>, ConciseError> {
        let bytes = match self.node.od().get(CONCISE_DCF, n.raw()) {
            Ok(e) if !e.data.is_empty() => e.data,
            _ => return Ok(None),
        };
        let dcf = ConciseDcf::parse(bytes)?;
        Ok(Some(Box::new(self.slot(n).cfg.clone().with_concise(&dcf))))
    }

    pub(super) fn fail(&mut self, n: NodeId, status: ErrorStatus) {
        let s = self.slot_mut(n);
        s.process = None;
        s.phase = BootPhase::Failed(status);
        s.last_error = Some(status);
    }

    pub(super) fn configured(&mut self, now: Instant, n: NodeId) {
        self.guard(now, n);
        let consumer = self.consumer_ms(n);
        let startup = self.startup();
        let s = self.slot(n);
        let beats = s
            .run
            .as_deref()
            .unwrap_or(&s.cfg)
            .heartbeat_producer_ms
            .is_some_and(|p| p > 0);
        if beats && consumer > 0 {
            // Error control starts now: the consumer entry is re-armed to wait for the first
            // heartbeat of the configured producer (its boot-up had started it, and a long
            // configuration must not count as silence); the K watchdog covers a slave that
            // never beats.
            if let Err(MasterError::Refused { code, .. }) = self.set_consumer(now, n, true) {
                self.emit(
                    now,
                    MasterEventKind::ConsumerNotConfigured { node: n, code },
                );
            }
            let due = now + Duration::from_millis(consumer as u64);
            self.slot_mut(n).hb_check = Some((now, due));
            self.arm(Some(due));
        }
        let s = self.slot_mut(n);
        s.last_error = None;
        let policy = if startup.has(NmtStartup::NO_SLAVE_START) {
            StartPolicy::Application
        } else {
            s.cfg.start
        };
        self.emit(
            now,
            MasterEventKind::SlaveConfigured {
                node: n,
                start: policy,
            },
        );
        match policy {
            StartPolicy::Application => self.slot_mut(n).phase = BootPhase::Ready,
            StartPolicy::Auto if self.network_started() => self.start_one(now, n),
            StartPolicy::Auto => self.slot_mut(n).phase = BootPhase::WaitStart,
        }
        self.check_network_start(now);
    }

    pub(super) fn start_one(&mut self, now: Instant, n: NodeId) {
        if self.send_nmt(now, NmtCommand::Start, n.into()).is_ok() {
            self.slot_mut(n).phase = BootPhase::Started;
            self.emit(
                now,
                MasterEventKind::SlaveStarted {
                    node: n,
                    broadcast: false,
                },
            );
        }
    }

    pub(super) fn adopt(&mut self, now: Instant, n: NodeId, state: NmtState) {
        self.cancel(n);
        self.slot_mut(n).phase = BootPhase::Adopted;
        self.emit(now, MasterEventKind::SlaveAdopted { node: n, state });
    }

    pub(super) fn decide_keep_alive(&mut self, now: Instant, n: NodeId) {
        self.slot_mut(n).wait_until = None;
        if !self.acting() {
            return;
        }
        match self.view_state(n) {
            Some(NmtState::Operational) => self.adopt(now, n, NmtState::Operational),
            _ => self.begin(now, n),
        }
        self.check_network_start(now);
    }
}
