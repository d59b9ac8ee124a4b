//! Fastscan on the master side: find every non-configured slave, one after another, and give
//! each a node-ID from an [`LssPlan`].
//!
//! # The rule
//!
//! A reset step (`bit_checked` 0x80) asks every non-configured slave in waiting mode to start
//! over; if none answers, the scan is over. Otherwise the master learns the lowest identity
//! present, part by part (vendor, product, revision, serial) and bit by bit from bit 31 down: it
//! sends the bits known so far with the bit under test 0, and every slave whose part agrees on
//! bits 31 to the bit under test answers. Silence means no slave has a 0 there, so the bit is 1.
//! A confirm step with all 32 bits (`bit_checked` 0) moves the one matching slave to the next
//! part; after the serial number it is in configuration mode, alone. The master gives it the
//! node-ID the plan has for it (configure node-ID, store configuration if the plan says so) and
//! switches it back to waiting, where it is no longer non-configured; then the next reset.
//!
//! # Timing
//!
//! Several slaves may answer one step, so a step that was answered ends only when no further
//! answer came for the *settle* time ([`LssMasterConfig::with_settle`]); an unanswered step ends
//! at the timeout. A slave costs 1 reset + 4 × 32 bit steps + 4 confirms (133 steps), then
//! configure node-ID (and store) and the switch back: unanswered steps are exactly the one bits
//! of its identity, each costing one timeout. [`fastscan_cost`] works the whole cost out for a
//! set of identities.
//!
//! # Answers that are not the step's
//!
//! An answer of another service stops the scan ([`LssError::WrongAnswer`]), except the answer
//! to the scan's own configure or store step arriving while a later step waits, or a scan
//! answer arriving while the configure or store step waits: on a dual bus that is the other
//! bus's copy, delivered past the merge window because its sender wrote the two copies that far
//! apart (a slave's host busy between its two writes). It is counted
//! ([`LssMasterStats::late`]) and dropped.
//!
//! # Starting over
//!
//! A scan answer carries no data, so a late copy that arrives during a *later* bit step cannot
//! be told from an answer to it: the step is taken as answered and the bit as 0. The protocol
//! shows the mistake itself: no slave has the part found, so its confirmation goes unanswered
//! (or, after a false confirmation of the serial number, nobody is in configuration mode to
//! answer the configure node-ID step). The scan then starts over at its reset, switching every
//! slave back to waiting first, and reports [`LssMasterEventKind::ScanRestarted`]: up to
//! [`RESTARTS`] times for one slave, then it stops with [`LssError::ScanLost`] (a slave that
//! keeps leaving, or a bus that keeps lying). A slave that left for good is simply not found
//! by the new reset. What the attempts given up cost is counted
//! ([`LssMasterStats::restarts`], [`LssMasterStats::abandoned`]), so that a scan can still be
//! checked against [`fastscan_cost`]: requests = the cost + `abandoned`.
//!
//! # Memory
//!
//! The plan holds up to `N` identities with their node-IDs and a 128-bit set of free node-IDs
//! for the others: a fixed size, whatever the number of slaves found.
//!
//! [`LssMasterConfig::with_settle`]: super::master::LssMasterConfig::with_settle
//! [`LssMasterStats::late`]: super::master::LssMasterStats::late
//! [`LssMasterStats::restarts`]: super::master::LssMasterStats::restarts
//! [`LssMasterStats::abandoned`]: super::master::LssMasterStats::abandoned
//! [`LssMasterEventKind::ScanRestarted`]: super::master::LssMasterEventKind::ScanRestarted

use super::codec::{Fastscan, LssAddress, LssMode, LssRequest, LssResponse, FASTSCAN_RESET};
use super::error::{LssError, LssService};
use super::master::{LssMasterConfig, LssMasterEventKind, Out};
use crate::frame::cob_id::{NodeId, NodeSet};
use crate::frame::instant::{Duration, Instant};
use heapless::Vec;

/// Which node-ID fastscan gives which slave: by identity first (an exact address, or an
/// expected identity whose zero parts are not checked, as CiA 302-2 reads 0x1F85–0x1F88),
/// otherwise the lowest free node-ID of the plan's pool. Each planned entry is given once: a
/// second board matching the same expected identity gets a node-ID from the pool, if any.
#[derive(Clone, Debug, Default)]
pub struct LssPlan<const N: usize> {
    /// (address or pattern, node-ID, exact).
    by_identity: Vec<(LssAddress, NodeId, bool), N>,
    free: NodeSet,
    store: bool,
}

impl<const N: usize> LssPlan<N> {
    /// An empty plan: every slave found is refused ([`LssError::NoNodeId`]).
    #[must_use]
    pub fn new() -> Self {
        LssPlan {
            by_identity: Vec::new(),
            free: NodeSet(0),
            store: false,
        }
    }
    /// The slave with identity `address` gets `node`. Returns the plan unchanged when it is
    /// full (`N` entries) or the identity or node-ID is planned already (check with
    /// [`len`](Self::len)).
    #[must_use]
    pub fn with_identity(self, address: LssAddress, node: NodeId) -> Self {
        self.with_entry(address, node, true)
    }
    /// The first slave whose identity agrees with `expected` on every part that is not 0 gets
    /// `node` (a replacement board: its serial number is not known beforehand).
    #[must_use]
    pub fn with_expected(self, expected: LssAddress, node: NodeId) -> Self {
        self.with_entry(expected, node, false)
    }
    fn with_entry(mut self, address: LssAddress, node: NodeId, exact: bool) -> Self {
        let taken = self
            .by_identity
            .iter()
            .any(|(a, n, e)| (*a == address && *e == exact) || *n == node);
        if !taken && self.by_identity.push((address, node, exact)).is_ok() {
            self.free.0 &= !(1u128 << node.raw());
        }
        self
    }
    /// Slaves the plan does not name get the lowest free node-ID in `nodes` (node-IDs planned by
    /// identity are never handed out to others).
    #[must_use]
    pub fn with_free(mut self, nodes: impl IntoIterator<Item = NodeId>) -> Self {
        for n in nodes {
            if !self.by_identity.iter().any(|(_, m, _)| *m == n) {
                self.free.insert(n);
            }
        }
        self
    }
    /// Each slave also stores its configuration (store configuration after configure node-ID).
    #[must_use]
    pub fn with_store(mut self, store: bool) -> Self {
        self.store = store;
        self
    }
    /// Identities planned (and not given yet).
    pub fn len(&self) -> usize {
        self.by_identity.len()
    }
    /// True when no identity is planned.
    pub fn is_empty(&self) -> bool {
        self.by_identity.is_empty()
    }
    /// The node-ID planned for `address`: its exact entry, else the first expected identity it
    /// agrees with.
    pub fn node_of(&self, address: &LssAddress) -> Option<NodeId> {
        self.entry(address).map(|i| self.by_identity[i].1)
    }
    fn entry(&self, address: &LssAddress) -> Option<usize> {
        let agrees = |p: &LssAddress| {
            let (a, p) = (address.parts(), p.parts());
            (0..4).all(|i| p[i] == 0 || p[i] == a[i])
        };
        let list = &self.by_identity;
        list.iter()
            .position(|(a, _, exact)| *exact && a == address)
            .or_else(|| list.iter().position(|(p, _, exact)| !*exact && agrees(p)))
    }
    /// The node-ID for a slave found: its planned one, else the lowest free one. Nothing is
    /// used up: [`take`](Self::take) does that once the slave took it.
    fn choose(&self, address: &LssAddress) -> Option<NodeId> {
        match self.entry(address) {
            Some(i) => Some(self.by_identity[i].1),
            None => self.free.iter().next(),
        }
    }
    /// Uses up what [`choose`](Self::choose) gives for `address`.
    fn take(&mut self, address: &LssAddress) {
        if let Some(i) = self.entry(address) {
            self.by_identity.swap_remove(i);
            return;
        }
        let first = self.free.iter().next();
        if let Some(n) = first {
            self.free.0 &= !(1u128 << n.raw());
        }
    }
}

#[derive(Clone, Copy, Debug)]
enum Step {
    Reset,
    Bit { sub: u8, bit: u8 },
    Confirm { sub: u8 },
    NodeId { address: LssAddress, node: NodeId },
    Store { address: LssAddress, node: NodeId },
}

/// Times a fastscan starts over for one slave before it stops with [`LssError::ScanLost`]
/// (see [Starting over](self#starting-over)).
pub const RESTARTS: u8 = 3;

/// A fastscan in progress.
#[derive(Debug)]
pub(super) struct Scan<const N: usize> {
    plan: LssPlan<N>,
    step: Step,
    id: [u32; 4],
    pub(super) deadline: Instant,
    heard: bool,
    assigned: u8,
    /// Restarts for the slave being scanned.
    restarts: u8,
    /// The master's request count when this attempt's reset was sent.
    attempt_from: u32,
}

/// What a scan step came to.
pub(super) enum Progress {
    Running,
    Finished,
}

impl<const N: usize> Scan<N> {
    pub(super) fn start(
        now: Instant,
        plan: LssPlan<N>,
        cfg: &LssMasterConfig,
        out: &mut Out,
    ) -> Self {
        let mut s = Scan {
            plan,
            step: Step::Reset,
            id: [0; 4],
            deadline: now,
            heard: false,
            assigned: 0,
            restarts: 0,
            attempt_from: out.stats.requests,
        };
        s.send_step(now, cfg, out);
        s
    }

    fn scan_request(&self) -> LssRequest {
        let (id_number, bit_checked, sub, next) = match self.step {
            Step::Bit { sub, bit } => (self.id[sub as usize], bit, sub, sub),
            Step::Confirm { sub } => (self.id[sub as usize], 0, sub, (sub + 1) & 3),
            _ => (0, FASTSCAN_RESET, 0, 0),
        };
        LssRequest::Fastscan(Fastscan {
            id_number,
            bit_checked,
            sub,
            next,
        })
    }

    fn send_step(&mut self, now: Instant, cfg: &LssMasterConfig, out: &mut Out) {
        let req = match self.step {
            Step::NodeId { node, .. } => LssRequest::ConfigureNodeId(node.raw()),
            Step::Store { .. } => LssRequest::Store,
            _ => self.scan_request(),
        };
        out.send(req);
        self.heard = false;
        self.deadline = now.saturating_add(cfg.timeout);
    }

    /// An answer arrived. `Err` ends the scan.
    pub(super) fn answer(
        &mut self,
        now: Instant,
        r: LssResponse,
        cfg: &LssMasterConfig,
        out: &mut Out,
    ) -> Result<Progress, LssError> {
        let wrong = |service| LssError::WrongAnswer {
            service,
            cs: r.cs(),
        };
        match (self.step, r) {
            (Step::Reset | Step::Bit { .. } | Step::Confirm { .. }, LssResponse::IdentifySlave) => {
                // Wait for the others answering the same step: the step ends after the quiet
                // settle time.
                self.heard = true;
                self.deadline = now.saturating_add(cfg.settle);
                Ok(Progress::Running)
            }
            // The answer to this scan's own configure or store step, come late: a second copy
            // the other bus delivered past the merge window. Counted and dropped; any other
            // answer is not the scan's.
            (
                Step::Reset | Step::Bit { .. } | Step::Confirm { .. },
                LssResponse::NodeIdConfigured { .. } | LssResponse::Stored { .. },
            )
            | (Step::NodeId { .. } | Step::Store { .. }, LssResponse::IdentifySlave) => {
                out.late();
                Ok(Progress::Running)
            }
            (Step::Reset | Step::Bit { .. } | Step::Confirm { .. }, _) => {
                Err(wrong(LssService::Fastscan))
            }
            (Step::NodeId { address, node }, LssResponse::NodeIdConfigured { error, spec })
            | (Step::Store { address, node }, LssResponse::Stored { error, spec }) => {
                let storing = matches!(self.step, Step::Store { .. });
                if error != 0 {
                    let service = if storing {
                        LssService::Store
                    } else {
                        LssService::ConfigureNodeId
                    };
                    return Err(LssError::Refused {
                        service,
                        error,
                        spec,
                    });
                }
                if self.plan.store && !storing {
                    self.step = Step::Store { address, node };
                    self.send_step(now, cfg, out);
                    return Ok(Progress::Running);
                }
                Ok(self.assigned(now, address, node, cfg, out))
            }
            (Step::NodeId { .. }, _) => Err(wrong(LssService::ConfigureNodeId)),
            (Step::Store { .. }, _) => Err(wrong(LssService::Store)),
        }
    }

    fn assigned(
        &mut self,
        now: Instant,
        address: LssAddress,
        node: NodeId,
        cfg: &LssMasterConfig,
        out: &mut Out,
    ) -> Progress {
        self.plan.take(&address);
        out.send(LssRequest::SwitchGlobal(LssMode::Waiting));
        out.event(now, LssMasterEventKind::Assigned { address, node });
        self.assigned = self.assigned.saturating_add(1);
        self.restarts = 0;
        self.step = Step::Reset;
        self.attempt_from = out.stats.requests;
        self.send_step(now, cfg, out);
        Progress::Running
    }

    /// This attempt went wrong at part `sub`: starts over at the reset, or gives up.
    fn restart(
        &mut self,
        now: Instant,
        sub: u8,
        cfg: &LssMasterConfig,
        out: &mut Out,
    ) -> Result<Progress, LssError> {
        if self.restarts >= RESTARTS {
            return Err(LssError::ScanLost { sub });
        }
        self.restarts += 1;
        // A slave a false confirmation left in a later part, or in configuration mode, takes
        // part in the reset again only from waiting.
        out.send(LssRequest::SwitchGlobal(LssMode::Waiting));
        out.restarted(out.stats.requests.wrapping_sub(self.attempt_from));
        out.event(now, LssMasterEventKind::ScanRestarted { sub });
        self.attempt_from = out.stats.requests;
        self.step = Step::Reset;
        self.send_step(now, cfg, out);
        Ok(Progress::Running)
    }

    /// The step's deadline passed. `Err` ends the scan.
    pub(super) fn deadline(
        &mut self,
        now: Instant,
        cfg: &LssMasterConfig,
        out: &mut Out,
    ) -> Result<Progress, LssError> {
        let heard = self.heard;
        self.step = match self.step {
            Step::Reset if !heard => {
                let assigned = self.assigned;
                out.event(now, LssMasterEventKind::ScanFinished { assigned });
                return Ok(Progress::Finished);
            }
            Step::Reset => {
                self.id = [0; 4];
                Step::Bit { sub: 0, bit: 31 }
            }
            Step::Bit { sub, bit } => {
                if !heard {
                    self.id[sub as usize] |= 1 << bit;
                }
                match bit {
                    0 => Step::Confirm { sub },
                    _ => Step::Bit { sub, bit: bit - 1 },
                }
            }
            Step::Confirm { sub } if !heard => return self.restart(now, sub, cfg, out),
            Step::Confirm { sub } if sub < 3 => Step::Bit {
                sub: sub + 1,
                bit: 31,
            },
            Step::Confirm { .. } => {
                let address = LssAddress::from_parts(self.id);
                out.event(now, LssMasterEventKind::Found(address));
                let node = self
                    .plan
                    .choose(&address)
                    .ok_or(LssError::NoNodeId(address))?;
                Step::NodeId { address, node }
            }
            // Nobody in configuration mode: the serial number was confirmed falsely.
            Step::NodeId { .. } => return self.restart(now, 3, cfg, out),
            Step::Store { .. } => return Err(LssError::Timeout(LssService::Store)),
        };
        self.send_step(now, cfg, out);
        Ok(Progress::Running)
    }

    /// Shifts the deadline back with a clock that stepped back.
    pub(super) fn shift(&mut self, by: Duration) {
        self.deadline = self.deadline - by;
    }
}

/// What a fastscan costs: see [`fastscan_cost`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FastscanCost {
    /// Request frames of the master.
    pub requests: u32,
    /// Answer frames of the slaves (each slave's answer counted once: over the dual-bus layer,
    /// once per bus on the wire and once after the merge).
    pub answers: u32,
    /// Steps nobody answered, each ending at the timeout.
    pub unanswered: u32,
    /// Steps answered, each ending after the settle time.
    pub answered: u32,
    /// The time spent waiting: `unanswered` timeouts plus `answered` settle times. Frame times
    /// on the wire come on top.
    pub waiting: Duration,
}

/// What a fastscan that configures the non-configured slaves `ids` costs, worked out from the
/// protocol alone (for planning a commissioning and for checking a scan against it): the
/// lowest identity present is found first; a bit step is answered by each slave still in the
/// running (its earlier parts confirmed) whose part agrees on the bits checked; the reset by
/// every slave left; the confirmations by the slaves whose part equals the one found. `ids`
/// must be distinct (two boards with one identity cannot be told apart by any LSS master); it
/// is sorted in place, nothing is allocated.
pub fn fastscan_cost(ids: &mut [LssAddress], cfg: &LssMasterConfig, store: bool) -> FastscanCost {
    ids.sort_unstable();
    let mut c = FastscanCost::default();
    let step = |answers: usize, c: &mut FastscanCost| {
        c.requests += 1;
        c.answers += answers as u32;
        if answers == 0 {
            c.unanswered += 1;
        } else {
            c.answered += 1;
        }
    };
    for i in 0..ids.len() {
        let left = &ids[i..];
        step(left.len(), &mut c);
        let target = left[0].parts();
        for sub in 0..4 {
            let running = || {
                left.iter()
                    .map(LssAddress::parts)
                    .filter(move |p| p[..sub] == target[..sub])
            };
            for bit in (0..32).rev() {
                let mask = u32::MAX << bit;
                // The bits above `bit` as found, `bit` itself 0.
                let probe = target[sub] & (mask << 1);
                step(running().filter(|p| p[sub] & mask == probe).count(), &mut c);
            }
            step(running().filter(|p| p[sub] == target[sub]).count(), &mut c);
        }
        // Configure node-ID (and store), each answered; the switch back to waiting, unanswered
        // by design (no wait).
        c.requests += 2 + u32::from(store);
        c.answers += 1 + u32::from(store);
    }
    // The last reset finds nobody.
    step(0, &mut c);
    c.waiting = cfg.timeout.saturating_mul(u64::from(c.unanswered))
        + cfg.settle.saturating_mul(u64::from(c.answered));
    c
}
