//! What the master does with what its node and SDO client report: boot-ups, states, error
//! control losses, writes to its own 0x1F8x entries, NMT commands of others, and the results of
//! the boot processes' SDO accesses.

use super::boot::{BootPhase, ErrorStatus};
use super::events::{MasterError, MasterEventKind};
use super::network::Network;
use super::objects::{self, request, REQUEST_ALL};
use super::Master;
use crate::cia301::nmt::{NmtCommand, NmtTarget};
use crate::cia301::sdo::{SdoEvent, TransferBuffer};
use crate::frame::cob_id::NodeId;
use crate::frame::instant::Instant;
use crate::machine::Machine;
use crate::node::{NodeEvent, NodeEventKind};
use crate::od::abort::AbortCode;
use crate::od::{comm, ObjectDictionary};
use crate::profile::IdProfile;

impl<D: ObjectDictionary, P: IdProfile> Master<D, P> {
    /// Drains the node's and the client's events, reacting to each, until nothing moves.
    pub(super) fn pump(&mut self, now: Instant) {
        loop {
            let mut moved = false;
            while let Some(e) = self.node.poll_event() {
                moved = true;
                self.on_node_event(e);
            }
            while let Some(e) = self.sdo.poll_event() {
                moved = true;
                self.on_sdo_event(e);
            }
            self.dispatch(now);
            if !moved {
                break;
            }
        }
        self.programs_progress(now);
    }

    pub(super) fn on_node_event(&mut self, e: NodeEvent) {
        let now = e.at;
        self.emit(now, MasterEventKind::Node(e.kind));
        match e.kind {
            NodeEventKind::BootUp { node } => {
                self.on_boot_up(now, node);
                self.standby_guard(now, node);
            }
            NodeEventKind::RemoteState { node, .. } => {
                self.standby_guard(now, node);
                self.refresh(node);
                if self.slot(node).phase == BootPhase::WaitState {
                    self.decide_keep_alive(now, node);
                }
            }
            NodeEventKind::HeartbeatTimeout { node, .. } => {
                self.error_control(now, node, ErrorStatus::E)
            }
            NodeEventKind::GuardingTimeout { node } => {
                self.error_control(now, node, ErrorStatus::F)
            }
            NodeEventKind::HeartbeatResumed { node } | NodeEventKind::GuardingResumed { node } => {
                self.slot_mut(node).missing = false;
                self.refresh(node);
            }
            NodeEventKind::ObjectWritten { index, sub, .. } => match index {
                objects::REQUEST_NMT => self.on_request_nmt(now, sub),
                objects::SLAVE_ASSIGNMENT => {
                    if let Some(n) = NodeId::new(sub) {
                        self.on_assignment(now, n);
                    }
                }
                comm::SYNC_COB_ID | comm::TIME_COB_ID => self.on_producer_written(now, index),
                _ => {}
            },
            NodeEventKind::NmtObserved { cmd, target } => {
                // Another node's command (the active master, seen by a standby; or a third
                // party): what the addressed nodes are now, until they are heard.
                let target = match NodeId::new(target) {
                    Some(n) => NmtTarget::Node(n),
                    None => NmtTarget::All,
                };
                self.note_command(now, cmd, target);
            }
            _ => {}
        }
    }

    pub(super) fn on_sdo_event(&mut self, e: SdoEvent) {
        let now = e.at;
        let n = e.node;
        let s = self.slot_mut(n);
        if s.request != Some(e.request) {
            self.emit(now, MasterEventKind::Sdo(e));
            return;
        }
        s.request = None;
        if s.program.is_some() {
            self.on_program_result(now, n, e);
            return;
        }
        if s.process.is_none() {
            // Of a dropped process: the result means nothing now.
            if core::mem::take(&mut s.restart) {
                self.begin(now, n);
            }
            return;
        }
        if e.result.is_ok() {
            s.missing = false;
            s.missing_reported = false;
        }
        let id = self.expected_identity(n);
        let s = self.slot_mut(n);
        let result = e.result.as_ref().map(|b| b.as_slice()).map_err(|x| *x);
        let Some(p) = s.process.as_mut() else {
            return;
        };
        let out = p.handle(s.run.as_deref().unwrap_or(&s.cfg), &id, result);
        self.apply(now, n, out);
    }

    pub(super) fn on_boot_up(&mut self, now: Instant, n: NodeId) {
        let s = self.slot_mut(n);
        s.boot_ups = s.boot_ups.saturating_add(1);
        s.missing = false;
        s.missing_reported = false;
        self.refresh(n);
        let a = self.assignment(n);
        if !a.is_slave() {
            return;
        }
        self.emit(now, MasterEventKind::SlaveBootUp { node: n });
        let s = self.slot(n);
        if s.program.is_none() {
            // A transfer with it (this master's boot process's, begun while it was silent or
            // before a reset, or the application's) went with the server's state at the boot:
            // it could only time out, and would hold up the node's boot process (one channel
            // per server) until it did. Ended now, as the device state ended it; the server is
            // told, so that a request of it still on its way is not answered into the next.
            match s.request {
                Some(r) => {
                    self.sdo.abort(now, r, AbortCode::DEVICE_STATE);
                }
                None => {
                    self.sdo.abort_node(now, n, AbortCode::DEVICE_STATE);
                }
            }
        }
        if !self.acting() {
            self.slot_mut(n).phase = BootPhase::Observed;
            return;
        }
        let booting = matches!(self.network, Network::Booting { .. });
        if a.reboots() || booting || self.slot(n).phase == BootPhase::WaitBootUp {
            self.begin(now, n);
        } else {
            // 0x1F81 bit 2 clear: reported only; the application decides (boot_slave).
            self.cancel(n);
            self.slot_mut(n).phase = BootPhase::WaitBootUp;
        }
    }

    pub(super) fn on_request_nmt(&mut self, now: Instant, sub: u8) {
        let value = self
            .node
            .od()
            .get_u32(objects::REQUEST_NMT, sub)
            .unwrap_or(0) as u8;
        let cmd = match value {
            request::STOP => NmtCommand::Stop,
            request::START => NmtCommand::Start,
            request::RESET_NODE => NmtCommand::ResetNode,
            request::RESET_COMMUNICATION => NmtCommand::ResetCommunication,
            request::PRE_OPERATIONAL => NmtCommand::EnterPreOperational,
            // A read-back value written by the master itself: nothing was asked.
            _ => return,
        };
        let target = match NodeId::new(sub) {
            Some(n) => NmtTarget::Node(n),
            None if sub == REQUEST_ALL => NmtTarget::All,
            None => return,
        };
        let sent = if target == NmtTarget::Node(self.node.id()) {
            // A request about the master itself: states yes, resets not over the bus.
            match cmd {
                NmtCommand::ResetNode | NmtCommand::ResetCommunication => false,
                c => {
                    self.node.set_nmt_state(now, c.resulting_state());
                    true
                }
            }
        } else {
            self.acting() && self.command(now, cmd, target).is_ok()
        };
        self.emit(now, MasterEventKind::NmtRequest { target, cmd, sent });
        match target {
            NmtTarget::Node(n) => self.refresh(n),
            NmtTarget::All => {
                let _ = self.node.od_mut().store(
                    objects::REQUEST_NMT,
                    REQUEST_ALL,
                    &[request::UNKNOWN],
                );
            }
        }
    }

    pub(super) fn on_assignment(&mut self, now: Instant, n: NodeId) {
        let mut a = self.assignment(n);
        if a.is_slave() && self.slots.give(n).is_none() {
            // No slot left for it: the entry goes back to "not a slave", so that the
            // dictionary says what the master does, and the writer is told by the event.
            let _ =
                self.node
                    .od_mut()
                    .store(objects::SLAVE_ASSIGNMENT, n.raw(), &0u32.to_le_bytes());
            let capacity = self.slots.capacity();
            self.emit(now, MasterEventKind::TooManySlaves { node: n, capacity });
            a = self.assignment(n);
        }
        if let Err(MasterError::Refused { code, .. }) = self.set_consumer(now, n, a.is_slave()) {
            self.emit(
                now,
                MasterEventKind::ConsumerNotConfigured { node: n, code },
            );
        }
        if !a.is_slave() {
            self.cancel(n);
            self.slot_mut(n).phase = BootPhase::Unassigned;
            if core::mem::take(&mut self.slot_mut(n).guarded) {
                self.node.unguard_node(n);
            }
            return;
        }
        if self.slot(n).phase == BootPhase::Unassigned {
            if self.acting() {
                let s = self.slot_mut(n);
                s.phase = BootPhase::WaitBootUp;
                s.probe_at = Some(now);
                self.arm(Some(now));
            } else {
                self.slot_mut(n).phase = BootPhase::Observed;
            }
        }
    }

    /// A write to 0x1005/0x1012 while standby must not make the master a producer: the wish is
    /// kept for when it becomes active.
    pub(super) fn on_producer_written(&mut self, now: Instant, index: u16) {
        let Some(v) = self.node.od().get_u32(index, 0) else {
            return;
        };
        let on = v & crate::frame::cob_id::CobId::BIT30 != 0;
        if !self.active && on {
            match index {
                comm::SYNC_COB_ID => self.produce_sync = true,
                _ => self.produce_time = true,
            }
            self.set_producers(now, false);
        } else if self.active {
            match index {
                comm::SYNC_COB_ID => self.produce_sync = on,
                _ => self.produce_time = on,
            }
        }
    }
}
