//! The network as a whole: its boot (resets, the wait for mandatory slaves, the start), the
//! takeover and the demotion of a master, and NMT commands with what they mean for the slaves'
//! boot processes.

use super::boot::BootPhase;
use super::config::{NmtStartup, StartPolicy};
use super::events::{MasterError, MasterEventKind};
use super::{objects, Master};
use crate::cia301::nmt::{self, NmtCommand, NmtState, NmtTarget};
use crate::frame::cob_id::NodeId;
use crate::frame::instant::{Duration, Instant};
use crate::od::abort::AbortCode;
use crate::od::ObjectDictionary;
use crate::profile::IdProfile;

/// The network's boot state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Network {
    /// Not managed (not booted, standby).
    Idle,
    /// Waiting for the mandatory slaves.
    Booting {
        deadline: Option<Instant>,
        reported: bool,
    },
    /// Started.
    Started,
}

impl<D: ObjectDictionary, P: IdProfile> Master<D, P> {
    // ----- the network -----

    pub(super) fn boot_network(&mut self, now: Instant) {
        let slaves: heapless::Vec<NodeId, 127> = self.assigned().collect();
        let keep_alive = slaves.iter().any(|n| self.assignment(*n).is_keep_alive());
        if keep_alive {
            for n in &slaves {
                if !self.assignment(*n).is_keep_alive() {
                    let _ = self.send_nmt(now, NmtCommand::ResetCommunication, (*n).into());
                }
            }
        } else if !slaves.is_empty() {
            let _ = self.send_nmt(now, NmtCommand::ResetCommunication, NmtTarget::All);
        }
        for n in slaves {
            let wait = Duration::from_millis(self.consumer_ms(n) as u64);
            let probe = self.probe_after(now);
            let keep_alive = self.assignment(n).is_keep_alive();
            let s = self.slot_mut(n);
            if keep_alive {
                s.phase = BootPhase::WaitState;
                s.wait_until = Some(now + wait);
                self.arm(Some(now + wait));
            } else {
                s.phase = BootPhase::WaitBootUp;
                s.probe_at = probe;
                self.arm(probe);
            }
        }
        let ms = self.node.od().get_u32(objects::BOOT_TIME, 0).unwrap_or(0);
        self.network = Network::Booting {
            deadline: (ms > 0).then(|| now + Duration::from_millis(ms as u64)),
            reported: false,
        };
        self.check_network_start(now);
    }

    pub(super) fn take_over(&mut self, now: Instant) {
        if !self.acting() {
            return;
        }
        let slaves: heapless::Vec<NodeId, 127> = self.assigned().collect();
        for n in slaves {
            match self.view_state(n) {
                Some(state @ (NmtState::Operational | NmtState::Stopped)) => {
                    self.adopt(now, n, state)
                }
                // Its boot is the application's (0x1F81 bit 2 clear; a slave-pair supervisor
                // knows which members the previous master configured): left as it is, without
                // a burst of SDO traffic at the moment SYNC must continue on its grid.
                Some(state) if !self.assignment(n).reboots() => self.adopt(now, n, state),
                Some(_) => self.begin(now, n),
                None => {
                    let s = self.slot_mut(n);
                    s.phase = BootPhase::WaitBootUp;
                    s.probe_at = Some(now);
                    self.arm(Some(now));
                }
            }
        }
        let mandatory_booted = self
            .assigned()
            .filter(|n| self.assignment(*n).is_mandatory())
            .all(|n| self.slot(n).phase.is_booted());
        if mandatory_booted {
            self.network = Network::Started;
            self.self_start(now);
            self.emit(
                now,
                MasterEventKind::NetworkStarted {
                    broadcast: false,
                    takeover: true,
                },
            );
        } else {
            let ms = self.node.od().get_u32(objects::BOOT_TIME, 0).unwrap_or(0);
            self.network = Network::Booting {
                deadline: (ms > 0).then(|| now + Duration::from_millis(ms as u64)),
                reported: false,
            };
        }
    }

    pub(super) fn stand_by(&mut self, now: Instant) {
        self.network = Network::Idle;
        self.waiting.clear();
        let assigned: heapless::Vec<NodeId, 127> = self.assigned().collect();
        for s in self.slots.iter_mut() {
            // Transfers under way are aborted now, the last frames this master sends for them:
            // left to run, their timeouts would send the aborts later, from a standby. Their
            // results are dropped.
            if let Some(r) = s.request {
                self.sdo.abort(now, r, AbortCode::GENERAL);
                self.sdo_idle = false;
            }
            s.process = None;
            s.restart = false;
            s.queued = false;
            s.probe_at = None;
            s.wait_until = None;
            s.hb_check = None;
        }
        for n in assigned {
            self.slot_mut(n).phase = BootPhase::Observed;
        }
    }

    pub(super) fn check_network_start(&mut self, now: Instant) {
        if !matches!(self.network, Network::Booting { .. }) || !self.acting() {
            return;
        }
        let ready = self
            .assigned()
            .filter(|n| self.assignment(*n).is_mandatory())
            .all(|n| self.slot(n).phase.is_booted());
        if ready {
            self.start_network_now(now);
        }
    }

    pub(super) fn start_network_now(&mut self, now: Instant) {
        self.network = Network::Started;
        self.self_start(now);
        let startup = self.startup();
        let waiting: heapless::Vec<NodeId, 127> = self
            .assigned()
            .filter(|n| self.slot(*n).phase == BootPhase::WaitStart)
            .collect();
        // One broadcast only when it cannot start a slave that is not configured (being
        // configured, failed, or left to the application).
        let broadcast = !startup.has(NmtStartup::NO_SLAVE_START)
            && startup.has(NmtStartup::START_ALL)
            && !waiting.is_empty()
            && self.assigned().all(|n| {
                let s = self.slot(n);
                s.cfg.start == StartPolicy::Auto
                    && matches!(
                        s.phase,
                        BootPhase::WaitStart
                            | BootPhase::Started
                            | BootPhase::Adopted
                            | BootPhase::WaitBootUp
                    )
            });
        self.emit(
            now,
            MasterEventKind::NetworkStarted {
                broadcast,
                takeover: false,
            },
        );
        if startup.has(NmtStartup::NO_SLAVE_START) {
            for n in waiting {
                self.slot_mut(n).phase = BootPhase::Ready;
            }
        } else if broadcast {
            if self
                .send_nmt(now, NmtCommand::Start, NmtTarget::All)
                .is_ok()
            {
                for n in waiting {
                    self.slot_mut(n).phase = BootPhase::Started;
                    self.emit(
                        now,
                        MasterEventKind::SlaveStarted {
                            node: n,
                            broadcast: true,
                        },
                    );
                }
            }
        } else {
            for n in waiting {
                self.start_one(now, n);
            }
        }
    }

    // ----- NMT -----

    /// Sends a command and makes the boot processes follow it.
    pub(super) fn command(
        &mut self,
        now: Instant,
        cmd: NmtCommand,
        target: NmtTarget,
    ) -> Result<(), MasterError> {
        self.send_nmt(now, cmd, target)?;
        let nodes: heapless::Vec<NodeId, 127> =
            self.assigned().filter(|n| target.includes(*n)).collect();
        for n in nodes {
            match cmd {
                NmtCommand::Start => {
                    if matches!(self.slot(n).phase, BootPhase::WaitStart | BootPhase::Ready) {
                        self.slot_mut(n).phase = BootPhase::Started;
                        self.emit(
                            now,
                            MasterEventKind::SlaveStarted {
                                node: n,
                                broadcast: target == NmtTarget::All,
                            },
                        );
                    }
                }
                NmtCommand::ResetNode | NmtCommand::ResetCommunication => {
                    self.cancel(n);
                    let probe = self.probe_after(now);
                    let s = self.slot_mut(n);
                    s.phase = BootPhase::WaitBootUp;
                    s.probe_at = probe;
                    self.arm(probe);
                }
                NmtCommand::Stop | NmtCommand::EnterPreOperational => {}
            }
        }
        Ok(())
    }

    /// Queues the frame and records what the addressed nodes are expected to be.
    pub(super) fn send_nmt(
        &mut self,
        now: Instant,
        cmd: NmtCommand,
        target: NmtTarget,
    ) -> Result<(), MasterError> {
        if self.nmt_out.len() >= self.nmt_capacity {
            self.stats.nmt_dropped += 1;
            return Err(MasterError::QueueFull);
        }
        let frame = nmt::command_frame(self.node.profile().nmt(), cmd, target);
        self.nmt_out.push_back(frame);
        self.stats.nmt_sent += 1;
        self.note_command(now, cmd, target);
        Ok(())
    }

    pub(super) fn note_command(&mut self, now: Instant, cmd: NmtCommand, target: NmtTarget) {
        let state = match cmd {
            NmtCommand::ResetNode | NmtCommand::ResetCommunication => None,
            c => Some(c.resulting_state()),
        };
        for i in 1..=127u8 {
            let Some(n) = NodeId::new(i) else { continue };
            if target.includes(n) && n != self.node.id() {
                self.slot_mut(n).commanded = Some((state, now));
                self.refresh(n);
            }
        }
    }
}
