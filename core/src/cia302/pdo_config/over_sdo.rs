//! A [`PdoConfigurator`] carried by the master's [`SdoClient`].

use super::{AccessError, Configured, PdoConfigError, PdoConfigurator, SdoAccess};
use crate::cia301::sdo::{
    RequestId, SdoClient, SdoErrorKind, SdoEvent, SdoOptions, TransferBuffer,
};
use crate::frame::instant::Instant;
use crate::frame::storage::Storage;

/// Runs a [`PdoConfigurator`] over an [`SdoClient`]: one access at a time.
///
/// Call [`SdoPdoJob::poll`] once to start, hand every [`SdoEvent`] of the client to
/// [`SdoPdoJob::handle_event`] (it takes the job's own) and call `poll` again after each; the
/// job is over when [`SdoPdoJob::result`] is `Some`. While another transfer to the same node is
/// running (the client serves one per server), `poll` waits and tries again on its next call.
#[derive(Clone, Debug)]
pub struct SdoPdoJob {
    job: PdoConfigurator,
    pending: Option<RequestId>,
    opts: SdoOptions,
}

impl SdoPdoJob {
    /// Carries `job` with the client's default options (expedited transfers, 1 s timeout).
    #[must_use]
    pub fn new(job: PdoConfigurator) -> SdoPdoJob {
        SdoPdoJob {
            job,
            pending: None,
            opts: SdoOptions::default(),
        }
    }

    /// Uses `opts` for every access (timeout, custom channel).
    #[must_use]
    pub fn with_options(mut self, opts: SdoOptions) -> SdoPdoJob {
        self.opts = opts;
        self
    }

    /// The configurator inside.
    pub fn job(&self) -> &PdoConfigurator {
        &self.job
    }

    /// The outcome, once finished.
    pub fn result(&self) -> Option<Result<Configured, PdoConfigError>> {
        self.job.result()
    }

    /// Starts the next access unless one is running or the job is over.
    pub fn poll<B: TransferBuffer, const SESSIONS: usize, S: Storage>(
        &mut self,
        now: Instant,
        client: &mut SdoClient<B, SESSIONS, S>,
    ) {
        while self.pending.is_none() {
            let Some(a) = self.job.next() else { return };
            let node = self.job.node();
            let started = match a {
                SdoAccess::Read { index, sub } => client.upload(now, node, index, sub, self.opts),
                SdoAccess::Write { index, sub, .. } => {
                    client.download(now, node, index, sub, a.data(), self.opts)
                }
            };
            match started {
                Ok(id) => self.pending = Some(id),
                // Another transfer holds the node or every session: try again later.
                Err(e) if matches!(e.kind, SdoErrorKind::Busy | SdoErrorKind::NoSession { .. }) => {
                    return
                }
                Err(e) => self.job.handle(Err(AccessError::NoAnswer(e.code()))),
            }
        }
    }

    /// Takes the result of this job's running access; false if `ev` is not this job's.
    pub fn handle_event<B: TransferBuffer>(&mut self, ev: &SdoEvent<B>) -> bool {
        if self.pending != Some(ev.request) {
            return false;
        }
        self.pending = None;
        let r = match &ev.result {
            Ok(b) => Ok(b.as_slice()),
            Err(e) => Err(match e.kind {
                SdoErrorKind::Server(code) => AccessError::Aborted(code),
                _ => AccessError::NoAnswer(e.code()),
            }),
        };
        self.job.handle(r);
        true
    }
}
