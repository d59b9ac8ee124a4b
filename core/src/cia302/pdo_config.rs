//! Master side: configuring a remote device's PDO over SDO, and mirroring it in the master's own
//! dictionary.
//!
//! [`PdoConfigurator`] is a sans-IO job. It says which SDO access comes next
//! ([`PdoConfigurator::next`]), is told how it ended ([`PdoConfigurator::handle`]), and finally
//! reports [`Configured`] or a [`PdoConfigError`]. [`SdoPdoJob`] carries it over the master's
//! [`crate::cia301::sdo::SdoClient`]; [`mirror`] sets up the master's own end of the PDO.
//!
//! The sequence is CiA 301's: read the COB-ID, disable the PDO (bit 31), write the transmission
//! type, inhibit time, event timer and SYNC start value that are asked for, then the mapping
//! (count 0, entries, count), then the final COB-ID.
//!
//! Some devices refuse to disable a PDO (a constant COB-ID, or a firmware that rejects bit 31).
//! A published embedded master accepted such a device when the PDO was already what was wanted, and so does
//! this job (reported as `fallback`): the COB-ID already selects the wanted identifier and is
//! valid, each parameter is either written or already holds the wanted value (read back after a
//! refusal), and the mapping, which cannot change while the PDO is valid, already is the wanted
//! one. Only a refusal by the device leads to the fallback: no answer, or an abort of the SDO
//! protocol itself (0x0503xxxx/0x0504xxxx), fails the job.

use crate::cia301::pdo::mapping::{Dir, MapEntry, MAX_ENTRIES};
use crate::cia301::pdo::params::{self, sub};
use crate::frame::cob_id::{CobId, NodeId};
use crate::od::abort::AbortCode;
use core::fmt;

/// A PDO's wanted configuration on a device.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PdoConfig {
    /// The COB-ID to end with (bit 31 clear to enable the PDO).
    pub cob_id: CobId,
    /// Transmission type.
    pub transmission_type: u8,
    /// Inhibit time in 100 µs (TPDO), if it is to be written.
    pub inhibit_100us: Option<u16>,
    /// Event timer in ms (TPDO: period; RPDO: reception timeout), if it is to be written.
    pub event_timer_ms: Option<u16>,
    /// SYNC start value (TPDO), if it is to be written.
    pub sync_start: Option<u8>,
    /// The mapping, if it is to be written (`None` leaves the device's mapping alone).
    pub mapping: Option<heapless::Vec<MapEntry, { MAX_ENTRIES as usize }>>,
}

impl PdoConfig {
    /// A PDO on `cob_id` with `transmission_type`; nothing else written.
    #[must_use]
    pub fn new(cob_id: CobId, transmission_type: u8) -> PdoConfig {
        PdoConfig {
            cob_id,
            transmission_type,
            inhibit_100us: None,
            event_timer_ms: None,
            sync_start: None,
            mapping: None,
        }
    }
    /// Also writes the inhibit time (100 µs units).
    #[must_use]
    pub fn inhibit(mut self, inhibit_100us: u16) -> PdoConfig {
        self.inhibit_100us = Some(inhibit_100us);
        self
    }
    /// Also writes the event timer (ms).
    #[must_use]
    pub fn event_timer(mut self, ms: u16) -> PdoConfig {
        self.event_timer_ms = Some(ms);
        self
    }
    /// Also writes the SYNC start value.
    #[must_use]
    pub fn sync_start(mut self, start: u8) -> PdoConfig {
        self.sync_start = Some(start);
        self
    }
    /// Also writes the mapping; `None` if `entries` has more than 64 entries.
    pub fn mapping(mut self, entries: &[MapEntry]) -> Option<PdoConfig> {
        self.mapping = Some(heapless::Vec::from_slice(entries).ok()?);
        Some(self)
    }
}

/// One SDO access the job asks for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SdoAccess {
    /// Upload (read) an entry.
    Read {
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
    },
    /// Download (write) an entry, `len` bytes of `data`.
    Write {
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// Little-endian value.
        data: [u8; 4],
        /// Bytes to write (the entry's size).
        len: u8,
    },
}

impl SdoAccess {
    fn write(index: u16, sub: u8, value: u32, len: u8) -> SdoAccess {
        SdoAccess::Write {
            index,
            sub,
            data: value.to_le_bytes(),
            len,
        }
    }
    /// The entry's index.
    pub fn index(&self) -> u16 {
        match *self {
            SdoAccess::Read { index, .. } | SdoAccess::Write { index, .. } => index,
        }
    }
    /// The entry's sub-index.
    pub fn sub(&self) -> u8 {
        match *self {
            SdoAccess::Read { sub, .. } | SdoAccess::Write { sub, .. } => sub,
        }
    }
    /// The bytes to download (empty for a read).
    pub fn data(&self) -> &[u8] {
        match self {
            SdoAccess::Read { .. } => &[],
            SdoAccess::Write { data, len, .. } => &data[..(*len as usize).min(4)],
        }
    }
}

/// A successful configuration.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Configured {
    /// The device refused to disable the PDO and was accepted because it already matched.
    pub fallback: bool,
    /// The COB-ID read at the start.
    pub previous_cob_id: CobId,
}

/// How one SDO access failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AccessError {
    /// The device aborted it with this code.
    Aborted(AbortCode),
    /// The device was not heard: the client timed out or gave up (with the abort code it sent,
    /// if any), or could not start the transfer.
    NoAnswer(Option<AbortCode>),
}

impl fmt::Display for AccessError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            AccessError::Aborted(code) => write!(f, "the device aborted with {code}"),
            AccessError::NoAnswer(Some(code)) => {
                write!(
                    f,
                    "no answer from the device (the client aborted with {code})"
                )
            }
            AccessError::NoAnswer(None) => f.write_str("no answer from the device"),
        }
    }
}

impl core::error::Error for AccessError {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        match self {
            AccessError::Aborted(code) | AccessError::NoAnswer(Some(code)) => Some(code),
            AccessError::NoAnswer(None) => None,
        }
    }
}

/// What went wrong.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PdoConfigErrorKind {
    /// The device aborted the access with this code.
    Aborted(AbortCode),
    /// The device did not answer (the SDO client's abort code, if it sent one).
    NoAnswer(Option<AbortCode>),
    /// The device refused to disable the PDO and holds something else than wanted (read back).
    Mismatch {
        /// Wanted value.
        wanted: u32,
        /// Value found.
        found: u32,
    },
    /// A read returned no value or one longer than 4 bytes.
    BadReply {
        /// Bytes received.
        len: usize,
    },
}

/// Why configuring a remote PDO failed: which device, which entry, what happened.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PdoConfigError {
    /// The device.
    pub node: NodeId,
    /// Entry index.
    pub index: u16,
    /// Entry sub-index.
    pub sub: u8,
    /// The device refused to disable the PDO, so the job was checking instead of configuring.
    pub fallback: bool,
    /// What happened.
    pub kind: PdoConfigErrorKind,
}

impl fmt::Display for PdoConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "configuring the PDO of {} failed at {:#06x}sub{}: ",
            self.node, self.index, self.sub
        )?;
        match self.kind {
            PdoConfigErrorKind::Aborted(code) => write!(f, "the device aborted with {code}"),
            PdoConfigErrorKind::NoAnswer(Some(code)) => {
                write!(f, "no answer from the device (the client aborted with {code})")
            }
            PdoConfigErrorKind::NoAnswer(None) => write!(f, "no answer from the device"),
            PdoConfigErrorKind::Mismatch { wanted, found } => write!(
                f,
                "the device refuses to disable the PDO and holds {found:#x} instead of {wanted:#x}: \
                 configure it by other means (its EDS defaults, a DCF) or change the wanted configuration"
            ),
            PdoConfigErrorKind::BadReply { len } => {
                write!(f, "the device answered with {len} bytes, not 1–4")
            }
        }
    }
}

impl core::error::Error for PdoConfigError {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        match &self.kind {
            PdoConfigErrorKind::Aborted(code) | PdoConfigErrorKind::NoAnswer(Some(code)) => {
                Some(code)
            }
            _ => None,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Param {
    Type,
    Inhibit,
    Timer,
    SyncStart,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Step {
    ReadCob,
    Disable,
    /// Write a parameter.
    Param(Param),
    /// Fallback: read a refused parameter back.
    CheckParam(Param),
    MapClear,
    MapEntry(u8),
    MapCount,
    /// Fallback: the mapping count must already match.
    CheckMapCount,
    /// Fallback: mapping entry k (1-based) must already match.
    CheckMapEntry(u8),
    Enable,
    Done,
}

/// Configures one PDO of one remote device over SDO (sans-IO).
#[derive(Clone, Debug)]
pub struct PdoConfigurator {
    node: NodeId,
    comm: u16,
    map: u16,
    transmit: bool,
    cfg: PdoConfig,
    step: Step,
    fallback: bool,
    previous: CobId,
    outcome: Option<Result<Configured, PdoConfigError>>,
}

/// True for aborts of the SDO protocol itself (timeouts, toggle, block errors): the device was
/// not heard, so nothing about its PDO is known.
fn protocol_failure(code: AbortCode) -> bool {
    matches!(code.0 >> 16, 0x0503 | 0x0504)
}

impl PdoConfigurator {
    /// A job configuring `node`'s PDO `pdo` (1-based) of direction `dir` (the device's side:
    /// [`Dir::Transmit`] for one of its TPDOs) to `cfg`.
    ///
    /// # Panics
    /// If `pdo` is not 1–512.
    #[must_use]
    pub fn new(node: NodeId, dir: Dir, pdo: u16, cfg: PdoConfig) -> PdoConfigurator {
        assert!((1..=params::MAX_PDOS).contains(&pdo), "PDO number 1..=512");
        let (comm, map) = match dir {
            Dir::Receive => (params::RPDO_COMM, params::RPDO_MAPPING),
            Dir::Transmit => (params::TPDO_COMM, params::TPDO_MAPPING),
        };
        PdoConfigurator {
            node,
            comm: comm + pdo - 1,
            map: map + pdo - 1,
            transmit: dir == Dir::Transmit,
            cfg,
            step: Step::ReadCob,
            fallback: false,
            previous: CobId(CobId::INVALID),
            outcome: None,
        }
    }

    /// The device being configured.
    pub fn node(&self) -> NodeId {
        self.node
    }

    /// The outcome, once finished.
    pub fn result(&self) -> Option<Result<Configured, PdoConfigError>> {
        self.outcome
    }

    /// The access to perform next; `None` when finished.
    pub fn next(&self) -> Option<SdoAccess> {
        let c = self.comm;
        let m = self.map;
        let mapping = self.cfg.mapping.as_ref();
        let entry = |k: u8| {
            mapping
                .and_then(|v| v.get(k as usize - 1))
                .map_or(0, |e| e.raw())
        };
        Some(match self.step {
            Step::ReadCob => SdoAccess::Read {
                index: c,
                sub: sub::COB_ID,
            },
            Step::Disable => SdoAccess::write(c, sub::COB_ID, self.previous.0 | CobId::INVALID, 4),
            Step::Param(p) => {
                let (s, v, len) = self.param(p);
                SdoAccess::write(c, s, v, len)
            }
            Step::CheckParam(p) => SdoAccess::Read {
                index: c,
                sub: self.param(p).0,
            },
            Step::MapClear => SdoAccess::write(m, 0, 0, 1),
            Step::MapEntry(k) => SdoAccess::write(m, k, entry(k), 4),
            Step::MapCount => SdoAccess::write(m, 0, mapping.map_or(0, |v| v.len() as u32), 1),
            Step::CheckMapCount => SdoAccess::Read { index: m, sub: 0 },
            Step::CheckMapEntry(k) => SdoAccess::Read { index: m, sub: k },
            Step::Enable => SdoAccess::write(c, sub::COB_ID, self.cfg.cob_id.0, 4),
            Step::Done => return None,
        })
    }

    fn param(&self, p: Param) -> (u8, u32, u8) {
        match p {
            Param::Type => (sub::TRANSMISSION_TYPE, self.cfg.transmission_type as u32, 1),
            Param::Inhibit => (
                sub::INHIBIT_TIME,
                self.cfg.inhibit_100us.unwrap_or(0) as u32,
                2,
            ),
            Param::Timer => (
                sub::EVENT_TIMER,
                self.cfg.event_timer_ms.unwrap_or(0) as u32,
                2,
            ),
            Param::SyncStart => (sub::SYNC_START, self.cfg.sync_start.unwrap_or(0) as u32, 1),
        }
    }

    /// The parameter written after `p`, if any is asked for.
    fn param_after(&self, p: Param) -> Option<Param> {
        let order = [Param::Type, Param::Inhibit, Param::Timer, Param::SyncStart];
        let from = order.iter().position(|x| *x == p).map_or(4, |i| i + 1);
        order[from..].iter().copied().find(|x| match x {
            Param::Type => true,
            Param::Inhibit => self.transmit && self.cfg.inhibit_100us.is_some(),
            Param::Timer => self.cfg.event_timer_ms.is_some(),
            Param::SyncStart => self.transmit && self.cfg.sync_start.is_some(),
        })
    }

    /// What follows the parameters.
    fn after_params(&self) -> Step {
        match (&self.cfg.mapping, self.fallback) {
            (None, false) => Step::Enable,
            (None, true) => Step::Done,
            (Some(_), false) => Step::MapClear,
            (Some(_), true) => Step::CheckMapCount,
        }
    }

    fn next_param(&self, p: Param) -> Step {
        match self.param_after(p) {
            Some(n) => Step::Param(n),
            None => self.after_params(),
        }
    }

    fn fail(&mut self, a: SdoAccess, kind: PdoConfigErrorKind) {
        self.outcome = Some(Err(PdoConfigError {
            node: self.node,
            index: a.index(),
            sub: a.sub(),
            fallback: self.fallback,
            kind,
        }));
        self.step = Step::Done;
    }

    /// How the access [`PdoConfigurator::next`] asked for ended: the uploaded bytes (empty for a
    /// download) or why it failed.
    pub fn handle(&mut self, result: Result<&[u8], AccessError>) {
        let Some(a) = self.next() else { return };
        let value = match result {
            Ok(d) if matches!(a, SdoAccess::Read { .. }) => {
                if d.is_empty() || d.len() > 4 {
                    return self.fail(a, PdoConfigErrorKind::BadReply { len: d.len() });
                }
                let mut b = [0u8; 4];
                b[..d.len()].copy_from_slice(d);
                Some(u32::from_le_bytes(b))
            }
            Ok(_) => None,
            Err(AccessError::NoAnswer(code)) => {
                return self.fail(a, PdoConfigErrorKind::NoAnswer(code));
            }
            Err(AccessError::Aborted(code)) => {
                let refused = !protocol_failure(code);
                match self.step {
                    Step::Disable if refused => {
                        // The published master's fallback: accept the PDO as it is if it already matches.
                        self.fallback = true;
                        let want = self.cfg.cob_id;
                        let have = self.previous;
                        if !want.is_valid() || (want.0 & 0x3FFF_FFFF) != (have.0 & 0x3FFF_FFFF) {
                            let kind = PdoConfigErrorKind::Mismatch {
                                wanted: want.0,
                                found: have.0,
                            };
                            return self.fail(a, kind);
                        }
                        self.step = Step::Param(Param::Type);
                        return;
                    }
                    Step::Param(p) if self.fallback && refused => {
                        self.step = Step::CheckParam(p);
                        return;
                    }
                    _ => return self.fail(a, PdoConfigErrorKind::Aborted(code)),
                }
            }
        };
        self.step = match self.step {
            Step::ReadCob => {
                self.previous = CobId(value.unwrap_or(CobId::INVALID));
                if self.previous.is_valid() {
                    Step::Disable
                } else {
                    Step::Param(Param::Type)
                }
            }
            Step::Disable => Step::Param(Param::Type),
            Step::Param(p) => self.next_param(p),
            Step::CheckParam(p) => {
                let wanted = self.param(p).1;
                let found = value.unwrap_or(0);
                if found != wanted {
                    return self.fail(a, PdoConfigErrorKind::Mismatch { wanted, found });
                }
                self.next_param(p)
            }
            Step::MapClear => match self.cfg.mapping.as_ref().map_or(0, |v| v.len()) {
                0 => Step::MapCount,
                _ => Step::MapEntry(1),
            },
            Step::MapEntry(k) => {
                if (k as usize) < self.cfg.mapping.as_ref().map_or(0, |v| v.len()) {
                    Step::MapEntry(k + 1)
                } else {
                    Step::MapCount
                }
            }
            Step::MapCount => Step::Enable,
            Step::CheckMapCount | Step::CheckMapEntry(_) => {
                let v = self.cfg.mapping.as_ref();
                let n = v.map_or(0, |v| v.len());
                let (wanted, next_k) = match self.step {
                    Step::CheckMapCount => (n as u32, 1),
                    Step::CheckMapEntry(k) => (
                        v.and_then(|v| v.get(k as usize - 1)).map_or(0, |e| e.raw()),
                        k as usize + 1,
                    ),
                    _ => (0, 0),
                };
                let found = value.unwrap_or(0);
                if found != wanted {
                    return self.fail(a, PdoConfigErrorKind::Mismatch { wanted, found });
                }
                if next_k <= n {
                    Step::CheckMapEntry(next_k as u8)
                } else {
                    Step::Done
                }
            }
            Step::Enable | Step::Done => Step::Done,
        };
        if self.step == Step::Done && self.outcome.is_none() {
            self.outcome = Some(Ok(Configured {
                fallback: self.fallback,
                previous_cob_id: self.previous,
            }));
        }
    }
}

#[cfg(feature = "alloc")]
mod mirror;
mod over_sdo;
#[cfg(feature = "alloc")]
pub use mirror::{mirror, Local, Mirror, MirrorError};
pub use over_sdo::SdoPdoJob;

#[cfg(test)]
mod tests {
    use super::*;

    fn run(
        job: &mut PdoConfigurator,
        mut f: impl FnMut(SdoAccess) -> Result<Vec<u8>, AbortCode>,
    ) -> Vec<SdoAccess> {
        let mut log = vec![];
        while let Some(a) = job.next() {
            log.push(a);
            let r = f(a);
            job.handle(r.as_deref().map_err(|e| AccessError::Aborted(*e)));
        }
        log
    }

    #[test]
    fn sequence_follows_cia_301() {
        let cfg = PdoConfig::new(CobId(0x185), 1)
            .inhibit(5)
            .mapping(&[MapEntry::new(0x6000, 1, 8), MapEntry::new(0x6001, 0, 16)])
            .unwrap();
        let mut job = PdoConfigurator::new(NodeId::must(5), Dir::Transmit, 1, cfg);
        let log = run(&mut job, |a| match a {
            SdoAccess::Read { .. } => Ok(0x4000_0185u32.to_le_bytes().to_vec()),
            SdoAccess::Write { .. } => Ok(vec![]),
        });
        let w = |i, s, v: u32, l: u8| SdoAccess::write(i, s, v, l);
        assert_eq!(
            log,
            [
                SdoAccess::Read {
                    index: 0x1800,
                    sub: 1
                },
                w(0x1800, 1, 0xC000_0185, 4),
                w(0x1800, 2, 1, 1),
                w(0x1800, 3, 5, 2),
                w(0x1A00, 0, 0, 1),
                w(0x1A00, 1, 0x6000_0108, 4),
                w(0x1A00, 2, 0x6001_0010, 4),
                w(0x1A00, 0, 2, 1),
                w(0x1800, 1, 0x185, 4),
            ]
        );
        assert_eq!(
            job.result(),
            Some(Ok(Configured {
                fallback: false,
                previous_cob_id: CobId(0x4000_0185)
            }))
        );
    }

    #[test]
    fn no_answer_fails_without_fallback() {
        let mut job = PdoConfigurator::new(
            NodeId::must(5),
            Dir::Receive,
            2,
            PdoConfig::new(CobId(0x305), 255),
        );
        job.handle(Ok(&0x305u32.to_le_bytes()));
        job.handle(Err(AccessError::NoAnswer(Some(AbortCode::TIMEOUT))));
        let e = job.result().unwrap().unwrap_err();
        assert_eq!(
            (e.index, e.sub, e.fallback, e.kind),
            (
                0x1401,
                1,
                false,
                PdoConfigErrorKind::NoAnswer(Some(AbortCode::TIMEOUT))
            )
        );
        assert_eq!(job.next(), None);
    }

    #[test]
    fn protocol_aborts_from_the_device_fail_without_fallback() {
        let mut job = PdoConfigurator::new(
            NodeId::must(5),
            Dir::Receive,
            2,
            PdoConfig::new(CobId(0x305), 255),
        );
        run(&mut job, |a| match a {
            SdoAccess::Read { .. } => Ok(0x305u32.to_le_bytes().to_vec()),
            SdoAccess::Write { .. } => Err(AbortCode::TIMEOUT),
        });
        let e = job.result().unwrap().unwrap_err();
        assert_eq!((e.index, e.sub, e.fallback), (0x1401, 1, false));
        assert_eq!(e.kind, PdoConfigErrorKind::Aborted(AbortCode::TIMEOUT));
        assert!(e.to_string().contains("node 0x05"));
    }
}
