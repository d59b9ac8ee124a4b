//! The master runs program downloads ([`ProgramDownload`]): one per slave at a time, on the
//! same client sessions and queue as the boot processes, reporting progress and the outcome as
//! [`MasterEventKind::ProgramProgress`] and [`MasterEventKind::ProgramDownloaded`]. A slave's
//! boot process does not run while its program is replaced: one asked for meanwhile (its
//! boot-up, say) runs when the download ends. A master that becomes standby sends nothing
//! more: the download ends where it is ([`ProgramDownload::abandon`]).

use super::events::{MasterError, MasterEventKind};
use super::objects::EXPECTED_SOFTWARE;
use super::program::{ProgramAccess, ProgramDownload};
use super::Master;
use crate::cia301::sdo::{SdoErrorKind, SdoEvent, SdoOptions, TransferBuffer, TransferMode};
use crate::frame::cob_id::NodeId;
use crate::frame::instant::Instant;
use crate::od::ObjectDictionary;
use crate::profile::IdProfile;
use alloc::boxed::Box;
use alloc::vec::Vec;

/// A download the master runs for one slave.
pub(super) struct ProgramRun {
    pub(super) job: ProgramDownload,
    /// Bytes last reported done.
    reported: usize,
}

impl<D: ObjectDictionary, P: IdProfile> Master<D, P> {
    /// Replaces `node`'s program with `image` (CiA 302-3 program download, the steps in
    /// [`ProgramDownload`]): stop, clear, the image by SDO block transfer, start, then the
    /// slave's 0x1F56 compared with the master's 0x1F55 sub n (0: not checked). Progress and
    /// the outcome arrive as events. Refused while standby, while the slave is being booted or
    /// updated already ([`MasterError::Busy`]), and for an image above the client's transfer
    /// limit ([`MasterError::ImageTooLarge`]).
    pub fn download_program(
        &mut self,
        now: Instant,
        node: NodeId,
        image: Vec<u8>,
    ) -> Result<(), MasterError> {
        if !self.acting() {
            return Err(MasterError::Standby);
        }
        if node == self.node.id() {
            return Err(MasterError::OwnNode(node));
        }
        let limit = self.sdo.limit();
        if image.len() > limit {
            return Err(MasterError::ImageTooLarge {
                len: image.len(),
                limit,
            });
        }
        let s = self.slot(node);
        if s.program.is_some() || s.process.is_some() || s.request.is_some() {
            return Err(MasterError::Busy(node));
        }
        // The download lives in the node's slot, slave or not.
        self.slots.claim(node)?;
        let expected = self
            .node
            .od()
            .get_u32(EXPECTED_SOFTWARE, node.raw())
            .unwrap_or(0);
        let total = image.len();
        self.slot_mut(node).program = Some(Box::new(ProgramRun {
            job: ProgramDownload::new(node, image, expected),
            reported: 0,
        }));
        self.programs += 1;
        self.emit(
            now,
            MasterEventKind::ProgramProgress {
                node,
                done: 0,
                total,
            },
        );
        self.issue(now, node);
        self.pump(now);
        Ok(())
    }

    /// Starts the access `n`'s download asks for now, or queues `n` for a session.
    pub(super) fn issue_program(&mut self, now: Instant, n: NodeId) {
        if !self.acting() {
            // Standby now: nothing more goes out; the download ends where it is.
            if let Some(run) = self.slot_mut(n).program.as_mut() {
                run.job.abandon();
            }
            return self.program_moved(now, n);
        }
        let timeout = self.sdo_timeout;
        let Some(s) = self.slots.get_mut(n) else {
            return;
        };
        let Some(run) = s.program.as_ref() else {
            return;
        };
        let Some(access) = run.job.access() else {
            return;
        };
        self.sdo_idle = false;
        let opts = SdoOptions::default().with_timeout(timeout);
        let started = match access {
            ProgramAccess::Read { index, sub } => self.sdo.upload(now, n, index, sub, opts),
            ProgramAccess::Write {
                index,
                sub,
                data,
                block,
            } => {
                let opts = if block {
                    opts.with_mode(TransferMode::Block)
                } else {
                    opts
                };
                self.sdo.download(now, n, index, sub, data, opts)
            }
        };
        match started {
            Ok(r) => s.request = Some(r),
            Err(e) if matches!(e.kind, SdoErrorKind::Busy | SdoErrorKind::NoSession { .. }) => {
                if !s.queued {
                    s.queued = true;
                    self.waiting.push_back(n);
                }
            }
            Err(e) => {
                if let Some(run) = s.program.as_mut() {
                    run.job.handle(Err(e));
                }
                self.program_moved(now, n);
            }
        }
    }

    /// The result of `n`'s download access.
    pub(super) fn on_program_result(&mut self, now: Instant, n: NodeId, e: SdoEvent) {
        let result = e.result.as_ref().map(|b| b.as_slice()).map_err(|x| *x);
        if let Some(run) = self.slot_mut(n).program.as_mut() {
            run.job.handle(result);
        }
        self.program_moved(now, n);
    }

    /// After a result: the next access, or the outcome.
    fn program_moved(&mut self, now: Instant, n: NodeId) {
        self.report_progress(now, n);
        let Some(run) = self.slot(n).program.as_ref() else {
            return;
        };
        let Some(result) = run.job.result() else {
            self.issue(now, n);
            return;
        };
        let s = self.slot_mut(n);
        s.program = None;
        let boot = core::mem::take(&mut s.restart);
        self.programs -= 1;
        self.emit(now, MasterEventKind::ProgramDownloaded { node: n, result });
        if boot {
            self.begin(now, n);
        }
    }

    /// Reports how far `n`'s image is, when it moved since the last report.
    fn report_progress(&mut self, now: Instant, n: NodeId) {
        let request = self.slot(n).request;
        let Some(run) = self.slot(n).program.as_deref() else {
            return;
        };
        use super::ProgramStep as S;
        let total = run.job.len();
        let done = match (run.job.step(), request) {
            (Some(S::Download), Some(r)) => self
                .sdo
                .progress(r)
                .map_or(run.reported, |(done, _)| done.max(run.reported)),
            // Past the download: all of it confirmed.
            (Some(S::Start | S::Verify), _) => total,
            _ if run.job.result().is_some_and(|r| r.is_ok()) => total,
            // Before it, or after a failure: what was confirmed stays.
            _ => run.reported,
        };
        if done != run.reported {
            if let Some(run) = self.slot_mut(n).program.as_deref_mut() {
                run.reported = done;
            }
            self.emit(
                now,
                MasterEventKind::ProgramProgress {
                    node: n,
                    done,
                    total,
                },
            );
        }
    }

    /// Progress of every download under way (after each frame and timeout).
    pub(super) fn programs_progress(&mut self, now: Instant) {
        if self.programs == 0 {
            return;
        }
        for n in (1..=127u8).filter_map(NodeId::new) {
            if self.slot(n).program.is_some() {
                self.report_progress(now, n);
            }
        }
    }
}
