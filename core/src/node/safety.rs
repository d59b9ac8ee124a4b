//! The node's CiA 304 side: its SRDOs and the global fail-safe command, for the application.
//!
//! The SRDOs run by themselves once the node is operational ([`crate::cia304::srdo`]); the
//! application sets its consumers' safe values, acknowledges a safe state, asks a producer for
//! an early pair and sends the GFC.

use super::{Node, NodeEvent, NodeEventKind};
use crate::cia301::nmt::NmtState;
use crate::cia304::gfc;
use crate::cia304::srdo::config::{self, SrdoConfig, SrdoConfigError};
use crate::cia304::srdo::{SrdoEvent, SrdoOutput, SrdoSet, SrdoStatus, NODE_SRDOS};
use crate::frame::instant::Instant;
use crate::frame::storage::Storage;
use crate::frame::Frame;
use crate::od::abort::AbortCode;
use crate::od::ObjectDictionary;
use crate::profile::IdProfile;

impl<
        D: ObjectDictionary,
        P: IdProfile,
        const GUARDED: usize,
        const TPDOS: usize,
        const RPDOS: usize,
        S: Storage,
    > Node<D, P, GUARDED, TPDOS, RPDOS, S>
{
    /// Checks the SRDO configuration now, as entering operational will: `Ok` when the node may
    /// (no SRDO in use, or all valid with matching checksums).
    pub fn srdo_check(&self) -> Result<(), SrdoConfigError> {
        let mut probe: SrdoSet<NODE_SRDOS> = SrdoSet::new();
        probe.load(&self.core.od)
    }
    /// Gives SRDO `n` the configuration `cfg` through the node's own write path (checks
    /// included, outside operational only), its checksum included: what a configuration tool
    /// writes over SDO ([`config::writes`]). Then [`Node::srdo_mark_valid`].
    pub fn configure_srdo(
        &mut self,
        now: Instant,
        n: u16,
        cfg: &SrdoConfig,
    ) -> Result<(), AbortCode> {
        for w in config::writes(n, cfg) {
            self.write(now, w.index, w.sub, w.data())?;
        }
        Ok(())
    }
    /// Marks the SRDO configuration valid (0x13FE = 0xA5), after checking it as entering
    /// operational will: the refusal says what is wrong, and nothing is written.
    pub fn srdo_mark_valid(&mut self, now: Instant) -> Result<(), SrdoMarkError> {
        let mut probe: SrdoSet<NODE_SRDOS> = SrdoSet::new();
        let w = config::mark_valid();
        // The check of 0x13FE itself is the one thing this write changes.
        match probe.load(&self.core.od) {
            Err(e) if e.index != config::CONFIG_VALID => return Err(SrdoMarkError::Config(e)),
            _ => {}
        }
        self.write(now, w.index, w.sub, w.data())
            .map_err(SrdoMarkError::Write)
    }
    /// What SRDO `n` (1-based) is doing; `None` beyond [`NODE_SRDOS`].
    pub fn srdo_status(&self, n: u16) -> Option<SrdoStatus> {
        self.core.srdo.status(n)
    }
    /// The safe values of consumer SRDO `n`: its normal data in frame layout (zeros unless set),
    /// written into its entries, with their inverse into the inverted entries, when it enters
    /// its safe state. False beyond [`NODE_SRDOS`] or for more than 8 bytes.
    pub fn set_srdo_safe_values(&mut self, n: u16, data: &[u8]) -> bool {
        self.core.srdo.set_safe_values(n, data)
    }
    /// The application acknowledges consumer `n`'s safe state: it checks again from `now`
    /// ([`crate::cia304::srdo::consumer`]). False when it is not in its safe state.
    pub fn srdo_acknowledge(&mut self, now: Instant, n: u16) -> bool {
        self.watch_clock(now);
        let core = &mut self.core;
        let mut out = Events(&mut core.events);
        core.srdo.acknowledge(now, n, &mut out)
    }
    /// Producer `n` sends its next pair at once (after writing a value that must not wait for
    /// the refresh time). False when it is not a running producer.
    pub fn srdo_request(&mut self, now: Instant, n: u16) -> bool {
        self.watch_clock(now);
        self.core.srdo.request(now, n)
    }
    /// Sends the global fail-safe command (0x001, no data). False when 0x1300 is not 1 or the
    /// node is not operational. The sender's own consumers are not affected: it knows.
    pub fn gfc_send(&mut self, now: Instant) -> bool {
        self.watch_clock(now);
        if self.core.state != NmtState::Operational || !self.core.gfc_valid() {
            return false;
        }
        self.core.send(gfc::gfc_frame()).is_ok()
    }
}

/// The node's event queue as the SRDOs' output outside a timed run (nothing is sent there).
struct Events<'a>(&'a mut crate::frame::queue::Bounded<NodeEvent, { super::EVENT_QUEUE }>);

impl SrdoOutput for Events<'_> {
    fn transmit(&mut self, _frame: Frame) {}
    fn srdo_event(&mut self, at: Instant, e: SrdoEvent) {
        self.0.push(NodeEvent {
            at,
            kind: NodeEventKind::Srdo(e),
        });
    }
}

/// Why [`Node::srdo_mark_valid`] did not mark the configuration valid.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SrdoMarkError {
    /// The configuration does not pass its checks.
    Config(SrdoConfigError),
    /// The dictionary refused the write of 0x13FE (no such object, or operational).
    Write(AbortCode),
}

impl core::fmt::Display for SrdoMarkError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            SrdoMarkError::Config(e) => write!(f, "not marked valid: {e}"),
            SrdoMarkError::Write(code) => write!(f, "0x13FE not written: {code}"),
        }
    }
}

impl core::error::Error for SrdoMarkError {}
