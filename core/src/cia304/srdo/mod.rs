//! Safety-relevant data objects (SRDO, CiA 304): the set of SRDOs a node runs, bound to its
//! dictionary.
//!
//! **The rule.** [`SrdoSet::load`] reads SRDO 1 up to the set's capacity from the dictionary
//! ([`config`]) and refuses a configuration that is not marked valid (0x13FE) or whose checksum
//! (0x13FF) does not match: the node then stays out of operational and says why. Entering
//! operational starts every producer and consumer; leaving it stops them. A producer packs its
//! normal entries and its inverted entries from the dictionary and sends the pair
//! ([`producer`]); a consumer checks each pair ([`consumer`]) and writes only a complete,
//! checked one into the dictionary: the normal data into the normal entries, the inverted data
//! into the inverted ones. When a consumer enters its safe state, its entries are set to its
//! safe values (zeros unless [`SrdoSet::set_safe_values`] says otherwise) and their inverse, and
//! an [`SrdoEvent`] says why and after how long.
//!
//! **Memory.** `N` slots, each a producer or a consumer with its safe values (72 bytes; the
//! mapping is read from the dictionary per pair): no allocation, nothing grows.

pub mod config;
pub mod consumer;
pub mod objects;
pub mod producer;

use crate::cia301::pdo::mapping::Mapping;
use crate::cia301::pdo::MapEntry;
use crate::frame::cob_id::NodeId;
use crate::frame::instant::{earliest, Duration, Instant};
use crate::frame::Frame;
use crate::od::ObjectDictionary;
use config::{SrdoConfig, SrdoConfigError, SrdoDirection};
use consumer::{ConsumerStep, SrdoCause, SrdoConsumer, SrdoFault};
use producer::SrdoProducer;

/// SRDOs a node runs: SRDO 1–4 (the dictionary may hold more; they stay inert).
pub const NODE_SRDOS: usize = 4;

/// What the SRDOs report (inside the node's events: `NodeEventKind::Srdo`, whose time is the
/// instant it happened: for a timeout, exactly the deadline). SRDOs are numbered from 1.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum SrdoEvent {
    /// A consumer entered its safe state; its entries hold their safe values.
    SafeState {
        /// The SRDO.
        srdo: u16,
        /// Why.
        cause: SrdoCause,
        /// The time measured ([`SrdoFault::measured`]).
        measured: Duration,
    },
    /// The application acknowledged a safe state: the consumer checks again.
    Acknowledged {
        /// The SRDO.
        srdo: u16,
    },
    /// A producer withheld its pair: the inverted entries do not hold the inverse of the normal
    /// ones (reported once until a pair goes out again).
    NotInverted {
        /// The SRDO.
        srdo: u16,
    },
    /// A global fail-safe command was received: the application's safe-state hook.
    Gfc,
}

/// One line: `SRDO 1 in its safe state: no complete pair within SCT (measured 30 ms)`.
impl core::fmt::Display for SrdoEvent {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            SrdoEvent::SafeState {
                srdo,
                cause,
                measured,
            } => write!(
                f,
                "SRDO {srdo} in its safe state: {} (measured {measured})",
                match cause {
                    SrdoCause::Validation => "no other half within SRVT",
                    SrdoCause::CycleTime => "no complete pair within SCT",
                    SrdoCause::NotInverted => "the halves are not each other's inverse",
                    SrdoCause::Length => "a frame shorter than its data",
                    SrdoCause::Sequence => "a half out of sequence",
                    SrdoCause::Gfc => "global fail-safe command",
                }
            ),
            SrdoEvent::Acknowledged { srdo } => {
                write!(f, "SRDO {srdo}: safe state acknowledged, checking again")
            }
            SrdoEvent::NotInverted { srdo } => write!(
                f,
                "SRDO {srdo} withheld: its inverted entries are not the inverse of the normal ones"
            ),
            SrdoEvent::Gfc => f.write_str("global fail-safe command (GFC) received"),
        }
    }
}

/// What an SRDO is doing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum SrdoStatus {
    /// Not configured (direction 0, or beyond the dictionary).
    Unused,
    /// A producer; `running` while operational.
    Producer {
        /// Producing.
        running: bool,
        /// Pairs sent.
        sent: u32,
    },
    /// A consumer checking pairs (or stopped, outside operational).
    Consumer {
        /// Checking.
        running: bool,
    },
    /// A consumer in its safe state.
    Safe(SrdoFault),
}

/// Where the SRDOs put what they produce.
pub trait SrdoOutput {
    /// A frame to send.
    fn transmit(&mut self, frame: Frame);
    /// Something that happened at `at`.
    fn srdo_event(&mut self, at: Instant, e: SrdoEvent);
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Role {
    Off,
    Producer(SrdoProducer),
    Consumer(SrdoConsumer),
}

/// One SRDO. Its mapping stays in the dictionary (it cannot change while operational): read
/// per pair rather than held, which keeps a slot under 80 bytes.
#[derive(Clone, Copy, Debug)]
struct Slot {
    role: Role,
    safe: [u8; 8],
    withheld: bool,
}

const OFF: Slot = Slot {
    role: Role::Off,
    safe: [0; 8],
    withheld: false,
};

/// The two halves of SRDO `n`'s mapping as the dictionary holds them (checked at load).
fn halves<D: ObjectDictionary + ?Sized>(od: &D, n: u16) -> (Mapping, Mapping) {
    let map = config::MAPPING + n - 1;
    let count = od
        .get_u32(map, 0)
        .unwrap_or(0)
        .min(config::MAX_MAPPED as u32) as u8;
    let mut e = [[MapEntry::new(0, 0, 0); 8]; 2];
    for s in 1..=count {
        let k = s as usize - 1;
        e[k % 2][k / 2] = MapEntry::from_raw(od.get_u32(map, s).unwrap_or(0));
    }
    let half = count as usize / 2;
    (Mapping::with(&e[0][..half]), Mapping::with(&e[1][..half]))
}

/// The SRDOs of one node, bound to its dictionary.
#[derive(Clone, Debug)]
pub struct SrdoSet<const N: usize = NODE_SRDOS> {
    slots: [Slot; N],
}

impl<const N: usize> Default for SrdoSet<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> SrdoSet<N> {
    /// No SRDO configured.
    #[must_use]
    pub const fn new() -> Self {
        SrdoSet { slots: [OFF; N] }
    }

    /// Reads and checks SRDO 1–`N` from `od`. On a refusal every SRDO is off. Safe values set
    /// before are kept.
    pub fn load<D: ObjectDictionary + ?Sized>(&mut self, od: &D) -> Result<(), SrdoConfigError> {
        let r = self.try_load(od);
        if r.is_err() {
            for s in &mut self.slots {
                s.role = Role::Off;
            }
        }
        r
    }

    fn try_load<D: ObjectDictionary + ?Sized>(&mut self, od: &D) -> Result<(), SrdoConfigError> {
        let mut used = false;
        for (k, slot) in self.slots.iter_mut().enumerate() {
            let n = k as u16 + 1;
            slot.role = Role::Off;
            if n > config::MAX_SRDOS {
                break;
            }
            let Some(cfg) = config::load(od, n)? else {
                continue;
            };
            used = true;
            *slot = Slot::of(&cfg, slot.safe);
        }
        if used {
            config::check_valid(od)?;
        }
        Ok(())
    }

    /// Entering operational at `now`: producers start after node-ID × 0.5 ms, consumers
    /// start checking.
    pub fn start(&mut self, now: Instant, node: NodeId) {
        let delay = Duration::from_micros(500 * node.raw() as u64);
        for s in &mut self.slots {
            s.withheld = false;
            match &mut s.role {
                Role::Producer(p) => p.start(now, delay),
                Role::Consumer(c) => c.start(now),
                Role::Off => {}
            }
        }
    }

    /// Leaving operational.
    pub fn stop(&mut self) {
        for s in &mut self.slots {
            match &mut s.role {
                Role::Producer(p) => p.stop(),
                Role::Consumer(c) => c.stop(),
                Role::Off => {}
            }
        }
    }

    /// The next deadline of any SRDO.
    #[must_use]
    pub fn poll_timeout(&self) -> Option<Instant> {
        self.slots.iter().fold(None, |t, s| {
            earliest(
                t,
                match &s.role {
                    Role::Producer(p) => p.poll_timeout(),
                    Role::Consumer(c) => c.poll_timeout(),
                    Role::Off => None,
                },
            )
        })
    }

    /// Sends the pairs due and trips the consumers whose deadlines passed.
    pub fn handle_timeout<D: ObjectDictionary + ?Sized>(
        &mut self,
        now: Instant,
        od: &mut D,
        out: &mut impl SrdoOutput,
    ) {
        for (k, s) in self.slots.iter_mut().enumerate() {
            let srdo = k as u16 + 1;
            match &mut s.role {
                Role::Producer(p) if p.is_due(now) => {
                    let (mut a, mut b) = ([0u8; 8], [0u8; 8]);
                    let (normal, inverted) = halves(od, srdo);
                    normal.pack(od, 0, &mut a);
                    inverted.pack(od, 0, &mut b);
                    let pair = p.frames(&a, &b);
                    p.sent_at(now, pair.is_some());
                    match pair {
                        Some((x, y)) => {
                            out.transmit(x);
                            out.transmit(y);
                            s.withheld = false;
                        }
                        None if !s.withheld => {
                            s.withheld = true;
                            out.srdo_event(now, SrdoEvent::NotInverted { srdo });
                        }
                        None => {}
                    }
                }
                Role::Consumer(c) => {
                    if let Some(step) = c.handle_timeout(now) {
                        s.apply(srdo, step, od, out);
                    }
                }
                _ => {}
            }
        }
    }

    /// A frame: `true` if it was an SRDO's (checked, delivered or tripped on).
    pub fn handle_frame<D: ObjectDictionary + ?Sized>(
        &mut self,
        now: Instant,
        frame: &Frame,
        od: &mut D,
        out: &mut impl SrdoOutput,
    ) -> bool {
        let mut taken = false;
        for (k, s) in self.slots.iter_mut().enumerate() {
            if let Role::Consumer(c) = &mut s.role {
                if !c.accepts(frame.id()) {
                    continue;
                }
                taken = true;
                if let Some(step) = c.handle_frame(now, frame) {
                    s.apply(k as u16 + 1, step, od, out);
                }
            }
        }
        taken
    }

    /// A global fail-safe command at `now`: every checking consumer enters its safe state,
    /// then [`SrdoEvent::Gfc`] is reported.
    pub fn gfc<D: ObjectDictionary + ?Sized>(
        &mut self,
        now: Instant,
        od: &mut D,
        out: &mut impl SrdoOutput,
    ) {
        for (k, s) in self.slots.iter_mut().enumerate() {
            if let Role::Consumer(c) = &mut s.role {
                if c.is_running() {
                    let step = c.trip(now, SrdoCause::Gfc, Duration::ZERO);
                    s.apply(k as u16 + 1, step, od, out);
                }
            }
        }
        out.srdo_event(now, SrdoEvent::Gfc);
    }

    /// The application acknowledges SRDO `n`'s safe state: it checks again from `now`, its
    /// entries keep their safe values until a new intact pair arrives. False when SRDO `n` is
    /// not a consumer in its safe state.
    pub fn acknowledge(&mut self, now: Instant, n: u16, out: &mut impl SrdoOutput) -> bool {
        let Some(Slot {
            role: Role::Consumer(c),
            ..
        }) = self.slot_mut(n)
        else {
            return false;
        };
        let done = c.acknowledge(now);
        if done {
            out.srdo_event(now, SrdoEvent::Acknowledged { srdo: n });
        }
        done
    }

    /// Producer `n` sends its next pair at once. False when SRDO `n` is not a running producer.
    pub fn request(&mut self, now: Instant, n: u16) -> bool {
        match self.slot_mut(n) {
            Some(Slot {
                role: Role::Producer(p),
                ..
            }) if p.is_running() => {
                p.request(now);
                true
            }
            _ => false,
        }
    }

    /// The safe values of SRDO `n` (`n` 1-based, up to `N`): the normal data, in frame layout,
    /// its consumer writes into its entries when it enters its safe state. False beyond `N` or
    /// for more than 8 bytes.
    pub fn set_safe_values(&mut self, n: u16, data: &[u8]) -> bool {
        match self.slot_mut(n) {
            Some(s) if data.len() <= 8 => {
                s.safe = [0; 8];
                s.safe[..data.len()].copy_from_slice(data);
                true
            }
            _ => false,
        }
    }

    /// What SRDO `n` is doing; `None` beyond `N`.
    #[must_use]
    pub fn status(&self, n: u16) -> Option<SrdoStatus> {
        let s = self.slots.get((n as usize).checked_sub(1)?)?;
        Some(match &s.role {
            Role::Off => SrdoStatus::Unused,
            Role::Producer(p) => SrdoStatus::Producer {
                running: p.is_running(),
                sent: p.sent(),
            },
            Role::Consumer(c) => match c.fault() {
                Some(f) => SrdoStatus::Safe(f),
                None => SrdoStatus::Consumer {
                    running: c.is_running(),
                },
            },
        })
    }

    /// The caller's clock stepped back `by`.
    pub fn step_back(&mut self, by: Duration) {
        for s in &mut self.slots {
            match &mut s.role {
                Role::Producer(p) => p.step_back(by),
                Role::Consumer(c) => c.step_back(by),
                Role::Off => {}
            }
        }
    }

    fn slot_mut(&mut self, n: u16) -> Option<&mut Slot> {
        self.slots.get_mut((n as usize).checked_sub(1)?)
    }
}

impl Slot {
    fn of(cfg: &SrdoConfig, safe: [u8; 8]) -> Slot {
        let len = cfg.mapping.bytes();
        let p = &cfg.params;
        let (a, b) = (cfg.normal_id(), cfg.inverted_id());
        let role = match p.direction {
            SrdoDirection::Transmit => Role::Producer(SrdoProducer::new(a, b, p.sct(), len)),
            SrdoDirection::Receive => {
                Role::Consumer(SrdoConsumer::new(a, b, p.sct(), p.srvt(), len))
            }
            SrdoDirection::Unused => Role::Off,
        };
        Slot {
            role,
            safe,
            withheld: false,
        }
    }

    /// What a consumer's step means for the dictionary and the application: a delivered pair
    /// or the safe values go into the entries (the normal data into the normal entries, its
    /// inverse into the inverted ones), a trip is reported.
    fn apply<D: ObjectDictionary + ?Sized>(
        &self,
        srdo: u16,
        step: ConsumerStep,
        od: &mut D,
        out: &mut impl SrdoOutput,
    ) {
        let data = match step {
            ConsumerStep::Held => return,
            ConsumerStep::Deliver(data) => data,
            ConsumerStep::Trip(_) => self.safe,
        };
        let inverse = (!u64::from_le_bytes(data)).to_le_bytes();
        let (normal, inverted) = halves(od, srdo);
        normal.unpack(od, 0, &data, |_, _| {});
        inverted.unpack(od, 0, &inverse, |_, _| {});
        if let ConsumerStep::Trip(f) = step {
            let e = SrdoEvent::SafeState {
                srdo,
                cause: f.cause,
                measured: f.measured,
            };
            out.srdo_event(f.at, e);
        }
    }
}
