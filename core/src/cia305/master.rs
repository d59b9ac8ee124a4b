//! The LSS master: each CiA 305 service as a request with a timeout and a typed result, and
//! fastscan with an assignment plan ([`super::fastscan`]).
//!
//! # The rule
//!
//! LSS has no addressing beyond the slaves' modes, so the master runs one request at a time; a
//! second one while the first runs is refused ([`LssError::Busy`]). A request writes its frames
//! (switch selective four, identify remote slave six) and, for a service with an answer, waits
//! until the timeout ([`LssMasterConfig::with_timeout`]):
//!
//! - services one slave answers (switch selective, configure, store, inquire) end at the first
//!   answer: the expected one is the result, an error code is [`LssError::Refused`], the answer
//!   of another service [`LssError::WrongAnswer`], a frame that is not LSS
//!   [`LssError::Malformed`], silence [`LssError::Timeout`];
//! - services any number of slaves answer (identify remote slave, identify non-configured)
//!   always wait the whole timeout and report whether anyone answered;
//! - services without an answer (switch global, activate bit timing) are done when written.
//!
//! Every result is one [`LssMasterEvent`]. Answers while nothing waits are counted
//! ([`LssMasterStats::unsolicited`]) and dropped.
//!
//! # Memory
//!
//! Fixed: eight frames and sixteen events queued, one request's state, and during fastscan the
//! plan (`PLAN` identities).

use super::codec::{
    BitTiming, IdentifyRange, Inquiry, LssAddress, LssMode, LssRequest, LssResponse,
    SLAVE_TO_MASTER, UNCONFIGURED,
};
use super::error::{LssError, LssService};
use super::fastscan::{LssPlan, Progress, Scan};
use crate::frame::cob_id::NodeId;
use crate::frame::instant::{Duration, Instant, TimeWatch};
use crate::frame::queue::Bounded;
use crate::frame::Frame;
use crate::machine::Machine;
use core::convert::Infallible;

/// How long the master waits.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub struct LssMasterConfig {
    /// How long a request waits for its answer (default 50 ms).
    pub timeout: Duration,
    /// How long a fastscan step that was answered waits for further answers of other slaves
    /// after the last one (default 2 ms: a few frame times at 125 kbit/s).
    pub settle: Duration,
}

impl Default for LssMasterConfig {
    fn default() -> Self {
        LssMasterConfig {
            timeout: Duration::from_millis(50),
            settle: Duration::from_millis(2),
        }
    }
}

impl LssMasterConfig {
    /// The answer timeout.
    #[must_use]
    pub fn with_timeout(mut self, timeout: Duration) -> Self {
        self.timeout = timeout;
        self
    }
    /// The quiet time that ends an answered fastscan step.
    #[must_use]
    pub fn with_settle(mut self, settle: Duration) -> Self {
        self.settle = settle;
        self
    }
}

/// The result of a request that succeeded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum LssOutcome {
    /// A service without an answer was written (switch global, activate bit timing).
    Sent(LssService),
    /// The selected slave answered: it is in configuration mode.
    Selected,
    /// Configure node-ID was accepted.
    NodeIdConfigured,
    /// Configure bit timing was accepted.
    BitTimingConfigured,
    /// Store configuration succeeded.
    Stored,
    /// The inquired value (the node-ID in the low byte; 0xFF: none).
    Inquired(Inquiry, u32),
    /// Identify remote slave or identify non-configured: whether any slave answered.
    Identified(LssService, bool),
}

/// What the master tells its application.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LssMasterEvent {
    /// When it happened (a timeout: exactly the deadline).
    pub at: Instant,
    /// What happened.
    pub kind: LssMasterEventKind,
}

/// The kinds of [`LssMasterEvent`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum LssMasterEventKind {
    /// A request succeeded.
    Done(LssOutcome),
    /// A request (or the fastscan) failed; the master is idle again.
    Failed(LssError),
    /// Fastscan found a slave; it is in configuration mode.
    Found(LssAddress),
    /// Fastscan gave the slave its node-ID (and stored it if the plan says so) and switched it
    /// back to waiting.
    Assigned {
        /// The slave.
        address: LssAddress,
        /// Its node-ID.
        node: NodeId,
    },
    /// Fastscan starts over at its reset: the confirmation of identity part `sub` (0 vendor …
    /// 3 serial) went unanswered, or nobody took the node-ID after the serial number was
    /// confirmed. A late or stray answer misled a bit, or the slave left (see
    /// [the fastscan](super::fastscan#starting-over)).
    ScanRestarted {
        /// The identity part whose confirmation went wrong.
        sub: u8,
    },
    /// Fastscan found no further non-configured slave.
    ScanFinished {
        /// Slaves configured by this scan.
        assigned: u8,
    },
}

/// One line: `LSS: configure node-ID accepted`, `LSS fastscan: vendor 0x… given node 0x10`.
impl core::fmt::Display for LssMasterEventKind {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            LssMasterEventKind::Done(o) => match o {
                LssOutcome::Sent(s) => write!(f, "LSS: {s} sent"),
                LssOutcome::Selected => f.write_str("LSS: slave selected, in configuration mode"),
                LssOutcome::NodeIdConfigured => f.write_str("LSS: configure node-ID accepted"),
                LssOutcome::BitTimingConfigured => {
                    f.write_str("LSS: configure bit timing accepted")
                }
                LssOutcome::Stored => f.write_str("LSS: configuration stored"),
                LssOutcome::Inquired(i, v) => {
                    write!(f, "LSS: {} answered {v:#010x}", LssService::Inquire(i))
                }
                LssOutcome::Identified(s, any) => {
                    write!(
                        f,
                        "LSS: {s}, {}",
                        if any { "answered" } else { "no answer" }
                    )
                }
            },
            LssMasterEventKind::Failed(e) => write!(f, "LSS: {e}"),
            LssMasterEventKind::Found(a) => write!(f, "LSS fastscan: found {a}"),
            LssMasterEventKind::Assigned { address, node } => {
                write!(f, "LSS fastscan: {address} given {node}")
            }
            LssMasterEventKind::ScanRestarted { sub } => write!(
                f,
                "LSS fastscan: starting over, identity part {sub} not confirmed"
            ),
            LssMasterEventKind::ScanFinished { assigned } => write!(
                f,
                "LSS fastscan: finished, {assigned} slave(s) given a node-ID"
            ),
        }
    }
}

impl core::fmt::Display for LssMasterEvent {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        core::fmt::Display::fmt(&self.kind, f)
    }
}

/// Counters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LssMasterStats {
    /// Request frames written.
    pub requests: u32,
    /// Answers received while a request waited.
    pub answers: u32,
    /// Frames on 0x7E4 while no request waited.
    pub unsolicited: u32,
    /// Answers to a configure or store step of a fastscan that came while a later step waited
    /// (on a dual bus: the other bus's copy, delivered past the merge window), or scan answers
    /// that came while the configure or store step waited: dropped.
    pub late: u32,
    /// Times a fastscan started over ([`LssMasterEventKind::ScanRestarted`]).
    pub restarts: u32,
    /// Requests of the fastscan attempts given up (the switch back to waiting of each restart
    /// included): a scan's requests are what [`fastscan_cost`](super::fastscan_cost) predicts
    /// plus these.
    pub abandoned: u32,
}

/// The master's output queues, shared with the fastscan.
#[derive(Debug, Default)]
pub(super) struct Out {
    tx: Bounded<Frame, 8>,
    events: Bounded<LssMasterEvent, 16>,
    pub(super) stats: LssMasterStats,
}

impl Out {
    pub(super) fn send(&mut self, r: LssRequest) {
        self.stats.requests = self.stats.requests.saturating_add(1);
        self.tx.push(r.encode());
    }
    pub(super) fn event(&mut self, at: Instant, kind: LssMasterEventKind) {
        self.events.push(LssMasterEvent { at, kind });
    }
    /// Counts an answer a fastscan dropped as late ([`LssMasterStats::late`]).
    pub(super) fn late(&mut self) {
        self.stats.late = self.stats.late.saturating_add(1);
    }
    /// Counts a fastscan restart and the requests of the attempt given up.
    pub(super) fn restarted(&mut self, requests: u32) {
        self.stats.restarts = self.stats.restarts.saturating_add(1);
        self.stats.abandoned = self.stats.abandoned.saturating_add(requests);
    }
}

#[derive(Debug)]
enum Job<const PLAN: usize> {
    Idle,
    /// One slave answers: the first answer ends it.
    Answer(LssService, Instant),
    /// Any number answer: the timeout ends it.
    Collect(LssService, Instant, bool),
    Scan(Scan<PLAN>),
}

/// An LSS master (CiA 305) whose fastscan plans hold up to `PLAN` identities.
#[derive(Debug)]
pub struct LssMaster<const PLAN: usize = 16> {
    cfg: LssMasterConfig,
    job: Job<PLAN>,
    clock: TimeWatch,
    out: Out,
}

impl<const PLAN: usize> Default for LssMaster<PLAN> {
    fn default() -> Self {
        Self::new(LssMasterConfig::default())
    }
}

impl<const PLAN: usize> LssMaster<PLAN> {
    /// An idle master.
    #[must_use]
    pub fn new(cfg: LssMasterConfig) -> Self {
        LssMaster {
            cfg,
            job: Job::Idle,
            clock: TimeWatch::new(),
            out: Out::default(),
        }
    }
    /// True when no request runs.
    pub fn is_idle(&self) -> bool {
        matches!(self.job, Job::Idle)
    }
    /// The counters.
    pub fn stats(&self) -> LssMasterStats {
        self.out.stats
    }
    /// The configuration.
    pub fn config(&self) -> &LssMasterConfig {
        &self.cfg
    }

    fn begin(&mut self, now: Instant) -> Result<(), LssError> {
        if let Some(by) = self.clock.step_back(now) {
            self.shift(by);
        }
        if self.is_idle() {
            Ok(())
        } else {
            Err(LssError::Busy)
        }
    }

    fn sent(&mut self, now: Instant, req: LssRequest, service: LssService) -> Result<(), LssError> {
        self.begin(now)?;
        self.out.send(req);
        self.out
            .event(now, LssMasterEventKind::Done(LssOutcome::Sent(service)));
        Ok(())
    }

    fn ask(&mut self, now: Instant, reqs: &[LssRequest], job: Job<PLAN>) -> Result<(), LssError> {
        self.begin(now)?;
        reqs.iter().for_each(|r| self.out.send(*r));
        self.job = job;
        Ok(())
    }

    fn deadline(&self, now: Instant) -> Instant {
        now.saturating_add(self.cfg.timeout)
    }

    /// Switch state global: every slave to `mode`; done when written.
    pub fn switch_global(&mut self, now: Instant, mode: LssMode) -> Result<(), LssError> {
        self.sent(
            now,
            LssRequest::SwitchGlobal(mode),
            LssService::SwitchGlobal,
        )
    }

    /// Switch state selective: the slave with `address` to configuration mode.
    pub fn switch_selective(&mut self, now: Instant, address: LssAddress) -> Result<(), LssError> {
        let p = address.parts();
        let reqs: [LssRequest; 4] = core::array::from_fn(|i| LssRequest::SwitchSelective {
            part: i as u8,
            value: p[i],
        });
        let job = Job::Answer(LssService::SwitchSelective, self.deadline(now));
        self.ask(now, &reqs, job)
    }

    /// Configure node-ID of the slave(s) in configuration mode: 1–127, or 0xFF for none.
    pub fn configure_node_id(&mut self, now: Instant, node: u8) -> Result<(), LssError> {
        if node != UNCONFIGURED && NodeId::new(node).is_none() {
            return Err(LssError::InvalidNodeId(node));
        }
        let job = Job::Answer(LssService::ConfigureNodeId, self.deadline(now));
        self.ask(now, &[LssRequest::ConfigureNodeId(node)], job)
    }

    /// Configure bit timing.
    pub fn configure_bit_timing(&mut self, now: Instant, t: BitTiming) -> Result<(), LssError> {
        let job = Job::Answer(LssService::ConfigureBitTiming, self.deadline(now));
        self.ask(now, &[LssRequest::ConfigureBitTiming(t)], job)
    }

    /// Activate bit timing: the slaves in configuration mode switch after `delay_ms` and speak
    /// again after twice that; done when written.
    pub fn activate_bit_timing(&mut self, now: Instant, delay_ms: u16) -> Result<(), LssError> {
        let req = LssRequest::ActivateBitTiming { delay_ms };
        self.sent(now, req, LssService::ActivateBitTiming)
    }

    /// Store configuration.
    pub fn store(&mut self, now: Instant) -> Result<(), LssError> {
        let job = Job::Answer(LssService::Store, self.deadline(now));
        self.ask(now, &[LssRequest::Store], job)
    }

    /// Inquire an identity part or the node-ID of the slave in configuration mode.
    pub fn inquire(&mut self, now: Instant, q: Inquiry) -> Result<(), LssError> {
        let job = Job::Answer(LssService::Inquire(q), self.deadline(now));
        self.ask(now, &[LssRequest::Inquire(q)], job)
    }

    /// Identify remote slave: is any slave in `range`?
    pub fn identify_remote(&mut self, now: Instant, range: IdentifyRange) -> Result<(), LssError> {
        let v = range.values();
        let reqs: [LssRequest; 6] = core::array::from_fn(|i| LssRequest::IdentifyRemote {
            part: i as u8,
            value: v[i],
        });
        let job = Job::Collect(LssService::IdentifyRemote, self.deadline(now), false);
        self.ask(now, &reqs, job)
    }

    /// Identify non-configured remote slave: is any slave without a node-ID there?
    pub fn identify_non_configured(&mut self, now: Instant) -> Result<(), LssError> {
        let job = Job::Collect(LssService::IdentifyNonConfigured, self.deadline(now), false);
        self.ask(now, &[LssRequest::IdentifyNonConfigured], job)
    }

    /// Fastscan: find every non-configured slave and give it its node-ID from `plan` (see
    /// [`super::fastscan`]). Reports [`LssMasterEventKind::Found`] and
    /// [`LssMasterEventKind::Assigned`] per slave, then [`LssMasterEventKind::ScanFinished`], or
    /// [`LssMasterEventKind::Failed`] where it stopped.
    pub fn fastscan(&mut self, now: Instant, plan: LssPlan<PLAN>) -> Result<(), LssError> {
        self.begin(now)?;
        self.job = Job::Scan(Scan::start(now, plan, &self.cfg, &mut self.out));
        Ok(())
    }

    fn finish(&mut self, at: Instant, r: Result<LssOutcome, LssError>) {
        if matches!(self.job, Job::Scan(_)) && r.is_err() {
            // Leave no slave in configuration mode behind.
            self.out.send(LssRequest::SwitchGlobal(LssMode::Waiting));
        }
        self.job = Job::Idle;
        let kind = match r {
            Ok(o) => LssMasterEventKind::Done(o),
            Err(e) => LssMasterEventKind::Failed(e),
        };
        self.out.event(at, kind);
    }

    fn scan_result(&mut self, at: Instant, r: Result<Progress, LssError>) {
        match r {
            Ok(Progress::Running) => {}
            Ok(Progress::Finished) => self.job = Job::Idle,
            Err(e) => self.finish(at, Err(e)),
        }
    }

    fn answer(&mut self, now: Instant, frame: &Frame) {
        let service = match &self.job {
            Job::Idle => {
                self.out.stats.unsolicited = self.out.stats.unsolicited.saturating_add(1);
                return;
            }
            Job::Answer(s, _) | Job::Collect(s, _, _) => *s,
            Job::Scan(_) => LssService::Fastscan,
        };
        self.out.stats.answers = self.out.stats.answers.saturating_add(1);
        let r = match LssResponse::decode(frame) {
            Ok(r) => r,
            Err(error) => return self.finish(now, Err(LssError::Malformed { service, error })),
        };
        if let Job::Scan(scan) = &mut self.job {
            let p = scan.answer(now, r, &self.cfg, &mut self.out);
            return self.scan_result(now, p);
        }
        if let Job::Collect(s, _, heard) = &mut self.job {
            let ok = matches!(
                (*s, r),
                (LssService::IdentifyRemote, LssResponse::IdentifySlave)
                    | (
                        LssService::IdentifyNonConfigured,
                        LssResponse::NonConfigured
                    )
            );
            if ok {
                *heard = true;
                return;
            }
        }
        let refused = |error, spec| {
            Err(LssError::Refused {
                service,
                error,
                spec,
            })
        };
        let result = match (service, r) {
            (LssService::SwitchSelective, LssResponse::SelectiveSwitched) => {
                Ok(LssOutcome::Selected)
            }
            (LssService::ConfigureNodeId, LssResponse::NodeIdConfigured { error: 0, .. }) => {
                Ok(LssOutcome::NodeIdConfigured)
            }
            (LssService::ConfigureBitTiming, LssResponse::BitTimingConfigured { error: 0, .. }) => {
                Ok(LssOutcome::BitTimingConfigured)
            }
            (LssService::Store, LssResponse::Stored { error: 0, .. }) => Ok(LssOutcome::Stored),
            (LssService::ConfigureNodeId, LssResponse::NodeIdConfigured { error, spec })
            | (LssService::ConfigureBitTiming, LssResponse::BitTimingConfigured { error, spec })
            | (LssService::Store, LssResponse::Stored { error, spec }) => refused(error, spec),
            (LssService::Inquire(q), LssResponse::Inquired(a, v)) if q == a => {
                Ok(LssOutcome::Inquired(q, v))
            }
            (service, r) => Err(LssError::WrongAnswer {
                service,
                cs: r.cs(),
            }),
        };
        self.finish(now, result);
    }

    fn shift(&mut self, by: Duration) {
        match &mut self.job {
            Job::Idle => {}
            Job::Answer(_, d) | Job::Collect(_, d, _) => *d = *d - by,
            Job::Scan(s) => s.shift(by),
        }
    }
}

impl<const PLAN: usize> Machine for LssMaster<PLAN> {
    type Event = LssMasterEvent;
    type LinkCommand = Infallible;

    fn handle_frame(&mut self, now: Instant, frame: &Frame) {
        if let Some(by) = self.clock.step_back(now) {
            self.shift(by);
        }
        if frame.id() == SLAVE_TO_MASTER {
            // A deadline that passed before this answer arrived decides first.
            self.handle_timeout(now);
            self.answer(now, frame);
        }
    }

    fn handle_timeout(&mut self, now: Instant) {
        if let Some(by) = self.clock.step_back(now) {
            self.shift(by);
        }
        let Some(due) = self.poll_timeout().filter(|d| *d <= now) else {
            return;
        };
        match &mut self.job {
            Job::Idle => {}
            Job::Answer(s, _) => {
                let e = LssError::Timeout(*s);
                self.finish(due, Err(e));
            }
            Job::Collect(s, _, heard) => {
                let o = LssOutcome::Identified(*s, *heard);
                self.finish(due, Ok(o));
            }
            Job::Scan(scan) => {
                // The next step starts now, not at the deadline: after a late call (a jump of
                // the clock) its slaves still get the whole timeout to answer.
                let p = scan.deadline(now, &self.cfg, &mut self.out);
                self.scan_result(now, p);
            }
        }
    }

    fn poll_transmit(&mut self) -> Option<Frame> {
        self.out.tx.pop()
    }

    fn poll_timeout(&self) -> Option<Instant> {
        match &self.job {
            Job::Idle => None,
            Job::Answer(_, d) | Job::Collect(_, d, _) => Some(*d),
            Job::Scan(s) => Some(s.deadline),
        }
    }

    fn poll_event(&mut self) -> Option<LssMasterEvent> {
        self.out.events.pop()
    }
}

#[cfg(test)]
mod display_tests {
    use super::*;

    #[test]
    fn lss_master_events_print_one_line_each() {
        assert_eq!(
            LssMasterEventKind::Done(LssOutcome::NodeIdConfigured).to_string(),
            "LSS: configure node-ID accepted"
        );
        assert_eq!(
            LssMasterEventKind::Done(LssOutcome::Inquired(Inquiry::Serial, 7)).to_string(),
            "LSS: inquire serial number answered 0x00000007"
        );
        assert_eq!(
            LssMasterEventKind::ScanFinished { assigned: 2 }.to_string(),
            "LSS fastscan: finished, 2 slave(s) given a node-ID"
        );
    }
}
