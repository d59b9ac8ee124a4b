//! The LSS slave: the CiA 305 services a device offers so that a master can find it by its
//! identity and give it a node-ID and a bit rate.
//!
//! # States
//!
//! The slave is in *waiting* or *configuration* mode. Switch state global moves every slave;
//! switch state selective moves the one whose four identity parts arrive in sequence (vendor,
//! product, revision, serial: a part that does not match restarts the sequence), and it answers
//! the fourth. Fastscan (non-configured slaves in waiting mode only) moves the slave whose
//! identity the master has confirmed bit by bit. Identify remote slave (a sequence of six, with
//! ranges for revision and serial) and identify non-configured remote slave are answered in
//! either mode. Configure node-ID, bit timing, activate bit timing, store and inquire are served
//! in configuration mode only; elsewhere they are ignored, as CiA 305 has it.
//!
//! # Node-IDs
//!
//! The slave has an *active* node-ID (the one its node runs with) and a *pending* one (the one
//! configure node-ID set). 0xFF is "none": a device that boots with it is non-configured and
//! runs LSS only (the composer does not boot its node). The pending node-ID becomes active at
//! the next reset-communication or reset-node the slave sees on the bus (addressed to all, or to
//! its active node-ID), or when the composer calls [`LssSlave::reset_communication`]; a
//! non-configured slave that was given a node-ID and is switched back to waiting does the reset
//! itself ([`LssSlaveEventKind::ResetCommunication`]).
//!
//! # Bit timing
//!
//! Configure bit timing accepts an entry of the CiA 301 table that the device supports
//! ([`LssSlave::with_bit_rates`]). Activate bit timing (no answer) makes the slave fall silent,
//! ask its driver to switch after the delay ([`LssSlaveEventKind::SwitchBitRate`]) and stay
//! silent for the delay again.
//!
//! # Memory
//!
//! Fixed: four answers and eight events queued (overflow counted by the queues), the sequence
//! positions as small counters. Bad frames are ignored and counted.

use super::codec::{
    BitTiming, Inquiry, LssAddress, LssMode, LssRequest, LssResponse, FASTSCAN_RESET,
    MASTER_TO_SLAVE, UNCONFIGURED,
};
use super::store::{LssStoreError, NoMedium, StoredLss, IMAGE_LEN};
use crate::cia301::nmt::{parse_command, NmtCommand};
use crate::frame::cob_id::NodeId;
use crate::frame::instant::{earliest, shift_back, Duration, Instant, TimeWatch};
use crate::frame::queue::Bounded;
use crate::frame::{Frame, Id};
use crate::machine::Machine;
use crate::od::parameters::ParameterStorage;
use core::convert::Infallible;

/// What an LSS slave tells its composer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LssSlaveEvent {
    /// When it happened.
    pub at: Instant,
    /// What happened.
    pub kind: LssSlaveEventKind,
}

/// The kinds of [`LssSlaveEvent`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum LssSlaveEventKind {
    /// The LSS mode changed.
    Mode(LssMode),
    /// Configure node-ID set the pending node-ID (0xFF: none).
    NodeIdConfigured(u8),
    /// Configure bit timing set the pending bit timing.
    BitTimingConfigured(BitTiming),
    /// Switch the controller to this bit timing now (activate bit timing's first delay ended).
    SwitchBitRate(BitTiming),
    /// The pending node-ID became active at a reset the bus commanded (`None`: no node-ID).
    NodeIdActivated(Option<NodeId>),
    /// The non-configured slave was given a node-ID and switched back to waiting: it enters
    /// reset-communication by itself; the composer boots its node with this node-ID.
    ResetCommunication(NodeId),
    /// Store configuration wrote the pending configuration to the medium.
    Stored,
    /// Store configuration failed.
    StoreFailed(LssStoreError),
}

/// Counters of what the slave ignored.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LssSlaveStats {
    /// Frames on 0x7E5 that are not LSS requests (wrong length, unknown command, bad value).
    pub malformed: u32,
    /// Requests ignored because the slave was silent (activate bit timing).
    pub silenced: u32,
}

/// An LSS slave (CiA 305) for a device with identity `address`, on medium `S` for store
/// configuration ([`NoMedium`]: store answers "not supported").
#[derive(Debug)]
pub struct LssSlave<S: ParameterStorage = NoMedium> {
    address: LssAddress,
    mode: LssMode,
    active: u8,
    pending: u8,
    timing: Option<BitTiming>,
    pending_timing: Option<BitTiming>,
    rates: u16,
    /// Parts of switch state selective matched in sequence (0–3).
    selective: u8,
    /// Parts of identify remote slave matched in sequence (0–5), and the low ends seen.
    identify: u8,
    /// Fastscan position: the identity part this slave compares next.
    scan_pos: u8,
    switch_at: Option<(Instant, BitTiming)>,
    silent_until: Option<Instant>,
    delay: Duration,
    storage: Option<S>,
    clock: TimeWatch,
    tx: Bounded<Frame, 4>,
    events: Bounded<LssSlaveEvent, 8>,
    stats: LssSlaveStats,
}

impl LssSlave<NoMedium> {
    /// A slave with identity `address` booting with `node_id` (0xFF: non-configured), in waiting
    /// mode, supporting every bit rate of the CiA 301 table, storing nothing.
    #[must_use]
    pub fn new(address: LssAddress, node_id: u8) -> Self {
        let node_id = if NodeId::new(node_id).is_some() {
            node_id
        } else {
            UNCONFIGURED
        };
        LssSlave {
            address,
            mode: LssMode::Waiting,
            active: node_id,
            pending: node_id,
            timing: None,
            pending_timing: None,
            rates: 0x01DF,
            selective: 0,
            identify: 0,
            scan_pos: 0,
            switch_at: None,
            silent_until: None,
            delay: Duration::ZERO,
            storage: None,
            clock: TimeWatch::new(),
            tx: Bounded::new(),
            events: Bounded::new(),
            stats: LssSlaveStats::default(),
        }
    }
}

impl<S: ParameterStorage> LssSlave<S> {
    /// The slave with `storage` behind store configuration. Nothing is read:
    /// [`load_stored`](Self::load_stored) does that at power-on.
    pub fn with_storage<T: ParameterStorage>(self, storage: T) -> LssSlave<T> {
        LssSlave {
            address: self.address,
            mode: self.mode,
            active: self.active,
            pending: self.pending,
            timing: self.timing,
            pending_timing: self.pending_timing,
            rates: self.rates,
            selective: self.selective,
            identify: self.identify,
            scan_pos: self.scan_pos,
            switch_at: self.switch_at,
            silent_until: self.silent_until,
            delay: self.delay,
            storage: Some(storage),
            clock: self.clock,
            tx: self.tx,
            events: self.events,
            stats: self.stats,
        }
    }

    /// The CiA 301 table entries this device can run at: bit `i` set for index `i` (default
    /// every rate, 0x01DF). Configure bit timing refuses the others.
    #[must_use]
    pub fn with_bit_rates(mut self, mask: u16) -> Self {
        self.rates = mask;
        self
    }

    /// Reads the stored configuration (at power-on) and makes it active and pending: `Ok(None)`
    /// when nothing is stored. An unreadable image changes nothing.
    pub fn load_stored(&mut self) -> Result<Option<StoredLss>, LssStoreError> {
        let storage = self.storage.as_mut().ok_or(LssStoreError::Unsupported)?;
        let mut buf = [0u8; IMAGE_LEN];
        let n = match storage.load(&mut buf) {
            Ok(Some(n)) => n,
            Ok(None) => return Ok(None),
            Err(_) => return Err(LssStoreError::Medium),
        };
        let stored = StoredLss::parse(buf.get(..n).ok_or(LssStoreError::Corrupt)?)?;
        (self.active, self.pending) = (stored.node_id, stored.node_id);
        (self.timing, self.pending_timing) = (stored.bit_timing, stored.bit_timing);
        Ok(Some(stored))
    }

    /// The medium, if any.
    pub fn storage(&self) -> Option<&S> {
        self.storage.as_ref()
    }
    /// The identity this slave answers for.
    pub fn address(&self) -> LssAddress {
        self.address
    }
    /// The LSS mode.
    pub fn mode(&self) -> LssMode {
        self.mode
    }
    /// The active node-ID (`None`: non-configured, LSS only).
    pub fn node_id(&self) -> Option<NodeId> {
        NodeId::new(self.active)
    }
    /// The pending node-ID, 0xFF for none.
    pub fn pending_node_id(&self) -> u8 {
        self.pending
    }
    /// The active bit timing, once one was activated or loaded.
    pub fn bit_timing(&self) -> Option<BitTiming> {
        self.timing
    }
    /// What was ignored.
    pub fn stats(&self) -> LssSlaveStats {
        self.stats
    }
    /// True while the slave takes part in fastscan and identify non-configured.
    pub fn is_non_configured(&self) -> bool {
        self.active == UNCONFIGURED && self.pending == UNCONFIGURED
    }

    /// The composer's node enters reset-communication (or reset-node): the pending node-ID
    /// becomes active.
    pub fn reset_communication(&mut self, now: Instant) {
        let _ = self.clock.step_back(now);
        self.activate(now);
    }

    fn activate(&mut self, now: Instant) {
        if self.active != self.pending {
            self.active = self.pending;
            self.event(
                now,
                LssSlaveEventKind::NodeIdActivated(NodeId::new(self.active)),
            );
        }
    }

    fn event(&mut self, at: Instant, kind: LssSlaveEventKind) {
        self.events.push(LssSlaveEvent { at, kind });
    }

    fn answer(&mut self, r: LssResponse) {
        self.tx.push(r.encode());
    }

    fn set_mode(&mut self, now: Instant, mode: LssMode) {
        if self.mode != mode {
            self.mode = mode;
            self.event(now, LssSlaveEventKind::Mode(mode));
        }
    }

    fn request(&mut self, now: Instant, req: LssRequest) {
        let conf = self.mode == LssMode::Configuration;
        match req {
            LssRequest::SwitchGlobal(LssMode::Waiting) => {
                let was_new = conf && self.active == UNCONFIGURED && self.pending != UNCONFIGURED;
                self.set_mode(now, LssMode::Waiting);
                self.selective = 0;
                if let (true, Some(n)) = (was_new, NodeId::new(self.pending)) {
                    self.active = self.pending;
                    self.event(now, LssSlaveEventKind::ResetCommunication(n));
                }
            }
            LssRequest::SwitchGlobal(LssMode::Configuration) => {
                self.set_mode(now, LssMode::Configuration)
            }
            LssRequest::SwitchSelective { part, value } if !conf => {
                let matches = self.address.parts()[part as usize & 3] == value;
                // A vendor part always starts a new sequence.
                let next = matches && (part == self.selective || part == 0);
                self.selective = if next { part + 1 } else { 0 };
                if self.selective == 4 {
                    self.selective = 0;
                    self.set_mode(now, LssMode::Configuration);
                    self.answer(LssResponse::SelectiveSwitched);
                }
            }
            LssRequest::IdentifyRemote { part, value } => {
                let a = self.address;
                let ok = match part {
                    0 => a.vendor == value,
                    1 => a.product == value,
                    2 => a.revision >= value,
                    3 => a.revision <= value,
                    4 => a.serial >= value,
                    _ => a.serial <= value,
                };
                let next = ok && (part == self.identify || part == 0);
                self.identify = if next { part + 1 } else { 0 };
                if self.identify == 6 {
                    self.identify = 0;
                    self.answer(LssResponse::IdentifySlave);
                }
            }
            LssRequest::IdentifyNonConfigured if self.is_non_configured() => {
                self.answer(LssResponse::NonConfigured)
            }
            LssRequest::Fastscan(s) if !conf && self.is_non_configured() => {
                if s.bit_checked == FASTSCAN_RESET {
                    self.scan_pos = 0;
                    self.answer(LssResponse::IdentifySlave);
                } else if s.sub == self.scan_pos {
                    let mask = u32::MAX << s.bit_checked;
                    if self.address.parts()[s.sub as usize] & mask == s.id_number & mask {
                        self.scan_pos = s.next;
                        self.answer(LssResponse::IdentifySlave);
                        if s.bit_checked == 0 && s.next < s.sub {
                            self.set_mode(now, LssMode::Configuration);
                        }
                    }
                }
            }
            LssRequest::ConfigureNodeId(n) if conf => {
                let error = if n == UNCONFIGURED || NodeId::new(n).is_some() {
                    self.pending = n;
                    self.event(now, LssSlaveEventKind::NodeIdConfigured(n));
                    0
                } else {
                    1
                };
                self.answer(LssResponse::NodeIdConfigured { error, spec: 0 });
            }
            LssRequest::ConfigureBitTiming(t) if conf => {
                let ok = t.kbit().is_some() && t.index < 16 && self.rates & (1 << t.index) != 0;
                if ok {
                    self.pending_timing = Some(t);
                    self.event(now, LssSlaveEventKind::BitTimingConfigured(t));
                }
                let error = u8::from(!ok);
                self.answer(LssResponse::BitTimingConfigured { error, spec: 0 });
            }
            LssRequest::ActivateBitTiming { delay_ms } if conf => {
                if let Some(t) = self.pending_timing {
                    self.delay = Duration::from_millis(u64::from(delay_ms));
                    let at = now.saturating_add(self.delay);
                    self.switch_at = Some((at, t));
                    self.silent_until = Some(at.saturating_add(self.delay));
                }
            }
            LssRequest::Store if conf => self.store(now),
            LssRequest::Inquire(q) if conf => {
                let a = self.address;
                let v = match q {
                    Inquiry::Vendor => a.vendor,
                    Inquiry::Product => a.product,
                    Inquiry::Revision => a.revision,
                    Inquiry::Serial => a.serial,
                    Inquiry::NodeId => u32::from(self.active),
                };
                self.answer(LssResponse::Inquired(q, v));
            }
            // Not served in this mode (or to a configured slave): CiA 305 ignores it.
            _ => {}
        }
    }

    fn store(&mut self, now: Instant) {
        let image = StoredLss {
            node_id: self.pending,
            bit_timing: self.pending_timing,
        }
        .image();
        let result = match self.storage.as_mut() {
            None => Err(LssStoreError::Unsupported),
            Some(s) => s.store(&image).map_err(|_| LssStoreError::Medium),
        };
        let (error, kind) = match result {
            Ok(()) => (0, LssSlaveEventKind::Stored),
            Err(e @ LssStoreError::Unsupported) => (1, LssSlaveEventKind::StoreFailed(e)),
            Err(e) => (2, LssSlaveEventKind::StoreFailed(e)),
        };
        self.event(now, kind);
        self.answer(LssResponse::Stored { error, spec: 0 });
    }

    fn nmt(&mut self, now: Instant, frame: &Frame) {
        if let Ok((NmtCommand::ResetCommunication | NmtCommand::ResetNode, target)) =
            parse_command(frame)
        {
            if target == 0 || (target == self.active && self.active != UNCONFIGURED) {
                self.activate(now);
            }
        }
    }

    fn watch(&mut self, now: Instant) {
        if let Some(by) = self.clock.step_back(now) {
            if let Some((at, _)) = &mut self.switch_at {
                *at = *at - by;
            }
            shift_back(&mut self.silent_until, by);
        }
    }
}

impl<S: ParameterStorage> Machine for LssSlave<S> {
    type Event = LssSlaveEvent;
    type LinkCommand = Infallible;

    fn handle_frame(&mut self, now: Instant, frame: &Frame) {
        self.watch(now);
        self.handle_timeout(now);
        if frame.id() == Id::Standard(0) {
            return self.nmt(now, frame);
        }
        if frame.id() != MASTER_TO_SLAVE {
            return;
        }
        if self.silent_until.is_some() {
            self.stats.silenced = self.stats.silenced.saturating_add(1);
            return;
        }
        match LssRequest::decode(frame) {
            Ok(req) => self.request(now, req),
            Err(_) => self.stats.malformed = self.stats.malformed.saturating_add(1),
        }
    }

    fn handle_timeout(&mut self, now: Instant) {
        self.watch(now);
        if let Some((at, t)) = self.switch_at.filter(|(at, _)| *at <= now) {
            self.switch_at = None;
            self.timing = Some(t);
            self.event(at, LssSlaveEventKind::SwitchBitRate(t));
        }
        if self.silent_until.is_some_and(|t| t <= now) {
            self.silent_until = None;
        }
    }

    fn poll_transmit(&mut self) -> Option<Frame> {
        self.tx.pop()
    }

    fn poll_timeout(&self) -> Option<Instant> {
        earliest(self.switch_at.map(|(at, _)| at), self.silent_until)
    }

    fn poll_event(&mut self) -> Option<LssSlaveEvent> {
        self.events.pop()
    }
}
