//! The boot process of one slave (CiA 302-2 "boot slave"): identity check, configuration,
//! error control start, as a pure state machine. It names the SDO access to do next and is told
//! how each ended; the manager carries the accesses over the master's SDO client and decides
//! about starting.
//!
//! Order: 0x1000 (always read: a slave that does not answer is missing, status B), then 0x1018
//! sub 1–4 where 0x1F85–0x1F88 expect a value (0 = not checked), then every configuration step,
//! then the producer heartbeat time (0x1017) so that the heartbeat starts from a configured slave.

use super::config::{ConfigStep, ExpectedIdentity, SlaveConfig};
use crate::cia301::pdo::params::MAX_PDOS;
use crate::cia301::sdo::{SdoError, SdoErrorKind};
use crate::cia302::pdo_config::{AccessError, PdoConfigError, PdoConfigurator, SdoAccess};
use crate::od::comm;
use alloc::boxed::Box;
use core::fmt;

/// CiA 302-2 error status of the boot process: why a slave was not (or no longer is) booted.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ErrorStatus {
    /// The node is not in the slave assignment (0x1F81 bit 0 clear).
    A,
    /// No answer to the upload of 0x1000.
    B,
    /// 0x1000 differs from 0x1F84 (device type).
    C,
    /// 0x1018 sub 1 differs from 0x1F85 (vendor-ID).
    D,
    /// Heartbeat event: no heartbeat received.
    E,
    /// Node guarding event: no answer to guarding requests.
    F,
    /// Objects for program download not configured or inconsistent.
    G,
    /// Software update required but not allowed.
    H,
    /// Software update required but the program download failed.
    I,
    /// The configuration download failed.
    J,
    /// No heartbeat received while starting error control.
    K,
    /// The slave was operational already (keep-alive slave adopted as it is).
    L,
    /// 0x1018 sub 2 differs from 0x1F86 (product code).
    M,
    /// 0x1018 sub 3 differs from 0x1F87 (revision number).
    N,
    /// 0x1018 sub 4 differs from 0x1F88 (serial number).
    O,
}

impl ErrorStatus {
    /// The letter CiA 302-2 uses.
    pub const fn letter(self) -> char {
        use ErrorStatus::*;
        match self {
            A => 'A',
            B => 'B',
            C => 'C',
            D => 'D',
            E => 'E',
            F => 'F',
            G => 'G',
            H => 'H',
            I => 'I',
            J => 'J',
            K => 'K',
            L => 'L',
            M => 'M',
            N => 'N',
            O => 'O',
        }
    }
    /// What the letter means.
    pub const fn description(self) -> &'static str {
        use ErrorStatus::*;
        match self {
            A => "the node is not assigned as a slave (0x1F81 bit 0)",
            B => "no answer to the upload of 0x1000",
            C => "device type 0x1000 differs from 0x1F84",
            D => "vendor-ID 0x1018 sub 1 differs from 0x1F85",
            E => "heartbeat lost",
            F => "node guarding lost",
            G => "program download objects not configured or inconsistent",
            H => "software update required but not allowed",
            I => "software update required but the download failed",
            J => "configuration download failed",
            K => "no heartbeat after error control was started",
            L => "the slave was operational already",
            M => "product code 0x1018 sub 2 differs from 0x1F86",
            N => "revision number 0x1018 sub 3 differs from 0x1F87",
            O => "serial number 0x1018 sub 4 differs from 0x1F88",
        }
    }
    /// The identity check failing with this status: the slave's entry and the master's.
    pub const fn identity_objects(self) -> Option<((u16, u8), u16)> {
        use super::objects::*;
        match self {
            ErrorStatus::C => Some(((comm::DEVICE_TYPE, 0), DEVICE_TYPE_ID)),
            ErrorStatus::D => Some(((comm::IDENTITY, 1), VENDOR_ID)),
            ErrorStatus::M => Some(((comm::IDENTITY, 2), PRODUCT_CODE)),
            ErrorStatus::N => Some(((comm::IDENTITY, 3), REVISION_NUMBER)),
            ErrorStatus::O => Some(((comm::IDENTITY, 4), SERIAL_NUMBER)),
            _ => None,
        }
    }
}

impl fmt::Display for ErrorStatus {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "error status {}: {}", self.letter(), self.description())
    }
}

/// Why a step of the boot process failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BootError {
    /// The SDO access failed: abort code from either side (timeouts included), node, object.
    Sdo(SdoError),
    /// Configuring one of the slave's PDOs failed (which entry, and how).
    Pdo(PdoConfigError),
    /// A PDO step names a PDO number outside 1–512.
    NoSuchPdo {
        /// The number.
        pdo: u16,
    },
    /// An identity entry was read but is not 4 bytes long.
    BadReply {
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// Bytes received.
        len: usize,
    },
}

impl fmt::Display for BootError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BootError::Sdo(e) => write!(f, "{e}"),
            BootError::Pdo(e) => write!(f, "{e}"),
            BootError::NoSuchPdo { pdo } => {
                write!(f, "PDO {pdo} does not exist: CiA 301 numbers PDOs 1 to 512")
            }
            BootError::BadReply { index, sub, len } => write!(
                f,
                "{index:#06x}sub{sub} answered with {len} bytes instead of 4: the device does not follow CiA 301"
            ),
        }
    }
}

impl core::error::Error for BootError {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        match self {
            BootError::Sdo(e) => Some(e),
            BootError::Pdo(e) => Some(e),
            _ => None,
        }
    }
}

/// Where a slave is, as far as this master's boot process goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum BootPhase {
    /// Not assigned (0x1F81 bit 0 clear).
    Unassigned,
    /// The master is standby (or not the NMT master): it only observes.
    Observed,
    /// Waiting for its boot-up (after a reset, a loss, or never heard); probed periodically.
    WaitBootUp,
    /// Keep-alive slave: waiting to learn whether it is operational already.
    WaitState,
    /// Reading 0x1000 / 0x1018.
    Identifying,
    /// Writing its configuration.
    Configuring,
    /// Configured; waiting for the network start.
    WaitStart,
    /// Configured; its start is left to the application.
    Ready,
    /// Started by this master.
    Started,
    /// Found operational and left as it was (keep-alive slave at boot, or at a takeover).
    Adopted,
    /// The boot process failed; waits for the next boot-up or [`super::Master::boot_slave`].
    Failed(ErrorStatus),
}

impl BootPhase {
    /// True once configured (or adopted): what gates the network start.
    pub const fn is_booted(self) -> bool {
        matches!(
            self,
            BootPhase::WaitStart | BootPhase::Ready | BootPhase::Started | BootPhase::Adopted
        )
    }
    /// True while an identity check or configuration runs.
    pub const fn is_running(self) -> bool {
        matches!(self, BootPhase::Identifying | BootPhase::Configuring)
    }
}

/// One SDO access of the process.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Access<'a> {
    Read { index: u16, sub: u8 },
    Write { index: u16, sub: u8, data: &'a [u8] },
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Step {
    DeviceType,
    /// 0x1018 sub 1–4.
    Identity(u8),
    /// Index into the configuration steps.
    Config(usize),
    Heartbeat,
    Done,
}

/// What one access's result means for the process.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Outcome {
    /// Another access follows.
    Continue,
    /// Identity checked and configuration written.
    Done,
    /// An identity entry holds something else.
    Mismatch {
        status: ErrorStatus,
        index: u16,
        sub: u8,
        expected: u32,
        actual: u32,
    },
    /// An access failed.
    Failed {
        status: ErrorStatus,
        reason: BootError,
    },
}

/// One run of the boot process for one slave.
#[derive(Clone, Debug)]
pub(crate) struct Process {
    step: Step,
    heartbeat: [u8; 2],
    /// The configurator of the PDO step under way, and the access it asks for now (boxed: a
    /// mapping of 64 entries is large, and most of the time no PDO step runs).
    pdo: Option<Box<(PdoConfigurator, Option<SdoAccess>)>>,
}

fn expected(id: &ExpectedIdentity, sub: u8) -> u32 {
    match sub {
        1 => id.vendor,
        2 => id.product,
        3 => id.revision,
        _ => id.serial,
    }
}

fn identity_status(sub: u8) -> ErrorStatus {
    match sub {
        1 => ErrorStatus::D,
        2 => ErrorStatus::M,
        3 => ErrorStatus::N,
        _ => ErrorStatus::O,
    }
}

impl Process {
    pub(crate) fn new(cfg: &SlaveConfig) -> Process {
        Process {
            step: Step::DeviceType,
            heartbeat: cfg.heartbeat_producer_ms.unwrap_or(0).to_le_bytes(),
            pdo: None,
        }
    }

    /// True once past the identity check.
    pub(crate) fn configuring(&self) -> bool {
        matches!(self.step, Step::Config(_) | Step::Heartbeat | Step::Done)
    }

    /// The access to do now; `None` when done.
    pub(crate) fn access<'a>(&'a self, cfg: &'a SlaveConfig) -> Option<Access<'a>> {
        match self.step {
            Step::DeviceType => Some(Access::Read {
                index: comm::DEVICE_TYPE,
                sub: 0,
            }),
            Step::Identity(sub) => Some(Access::Read {
                index: comm::IDENTITY,
                sub,
            }),
            Step::Config(i) => match cfg.steps.get(i)? {
                ConfigStep::Write { index, sub, data } => Some(Access::Write {
                    index: *index,
                    sub: *sub,
                    data,
                }),
                ConfigStep::Pdo { .. } => match self.pdo.as_ref()?.1.as_ref()? {
                    SdoAccess::Read { index, sub } => Some(Access::Read {
                        index: *index,
                        sub: *sub,
                    }),
                    a @ SdoAccess::Write { index, sub, .. } => Some(Access::Write {
                        index: *index,
                        sub: *sub,
                        data: a.data(),
                    }),
                },
            },
            Step::Heartbeat => Some(Access::Write {
                index: comm::HEARTBEAT_PRODUCER,
                sub: 0,
                data: &self.heartbeat,
            }),
            Step::Done => None,
        }
    }

    /// The step after `step`, skipping identity entries nobody checks and absent steps.
    fn next(step: Step, cfg: &SlaveConfig, id: &ExpectedIdentity) -> Step {
        let mut s = step;
        loop {
            s = match s {
                Step::DeviceType => Step::Identity(1),
                Step::Identity(4) => Step::Config(0),
                Step::Identity(k) => Step::Identity(k + 1),
                Step::Config(i) => Step::Config(i + 1),
                Step::Heartbeat | Step::Done => Step::Done,
            };
            // Normalise: an identity step is kept only if checked, a config index only if it
            // exists, the heartbeat only if asked for.
            s = match s {
                Step::Identity(k) if expected(id, k) == 0 => continue,
                Step::Config(i) if i >= cfg.steps.len() => {
                    if cfg.heartbeat_producer_ms.is_some() {
                        Step::Heartbeat
                    } else {
                        Step::Done
                    }
                }
                other => other,
            };
            return s;
        }
    }

    /// Moves to the step after the current one; a PDO step gets its configurator.
    fn advance(&mut self, cfg: &SlaveConfig, id: &ExpectedIdentity) -> Outcome {
        self.step = Self::next(self.step, cfg, id);
        self.pdo = None;
        if let Step::Config(i) = self.step {
            if let Some(ConfigStep::Pdo { dir, pdo, config }) = cfg.steps.get(i) {
                if !(1..=MAX_PDOS).contains(pdo) {
                    self.step = Step::Done;
                    return Outcome::Failed {
                        status: ErrorStatus::J,
                        reason: BootError::NoSuchPdo { pdo: *pdo },
                    };
                }
                let job = PdoConfigurator::new(cfg.node, *dir, *pdo, (**config).clone());
                let first = job.next();
                self.pdo = Some(Box::new((job, first)));
            }
        }
        if self.step == Step::Done {
            Outcome::Done
        } else {
            Outcome::Continue
        }
    }

    /// Takes the result of the current PDO configurator's access.
    fn handle_pdo(
        &mut self,
        cfg: &SlaveConfig,
        id: &ExpectedIdentity,
        result: Result<&[u8], SdoError>,
    ) -> Outcome {
        let Some((job, current)) = self.pdo.as_deref_mut() else {
            return self.advance(cfg, id);
        };
        // A refusal by the device is the configurator's to judge (its fallback); anything
        // else means the device was not heard.
        job.handle(result.map_err(|e| match e.kind {
            SdoErrorKind::Server(code) => AccessError::Aborted(code),
            _ => AccessError::NoAnswer(e.code()),
        }));
        match job.result() {
            Some(Ok(_)) => self.advance(cfg, id),
            Some(Err(e)) => {
                self.step = Step::Done;
                self.pdo = None;
                Outcome::Failed {
                    status: ErrorStatus::J,
                    reason: BootError::Pdo(e),
                }
            }
            None => {
                *current = job.next();
                if current.is_some() {
                    Outcome::Continue
                } else {
                    self.advance(cfg, id)
                }
            }
        }
    }

    /// Takes the result of the current access. `id` is what the master expects (its
    /// 0x1F84–0x1F88 entries for this node, read when the result arrives).
    pub(crate) fn handle(
        &mut self,
        cfg: &SlaveConfig,
        id: &ExpectedIdentity,
        result: Result<&[u8], SdoError>,
    ) -> Outcome {
        let step = self.step;
        if self.pdo.is_some() {
            return self.handle_pdo(cfg, id, result);
        }
        let data = match result {
            Ok(d) => d,
            Err(e) => {
                let status = match step {
                    Step::DeviceType => ErrorStatus::B,
                    Step::Identity(k) => identity_status(k),
                    _ => ErrorStatus::J,
                };
                self.step = Step::Done;
                return Outcome::Failed {
                    status,
                    reason: BootError::Sdo(e),
                };
            }
        };
        let check = match step {
            Step::DeviceType => Some((comm::DEVICE_TYPE, 0, id.device_type, ErrorStatus::C)),
            Step::Identity(k) => Some((comm::IDENTITY, k, expected(id, k), identity_status(k))),
            _ => None,
        };
        if let Some((index, sub, want, status)) = check {
            let Ok(bytes) = <[u8; 4]>::try_from(data) else {
                self.step = Step::Done;
                return Outcome::Failed {
                    status,
                    reason: BootError::BadReply {
                        index,
                        sub,
                        len: data.len(),
                    },
                };
            };
            let actual = u32::from_le_bytes(bytes);
            if want != 0 && actual != want {
                self.step = Step::Done;
                return Outcome::Mismatch {
                    status,
                    index,
                    sub,
                    expected: want,
                    actual,
                };
            }
        }
        self.advance(cfg, id)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cia301::sdo::{Direction, SdoErrorKind};
    use crate::frame::cob_id::NodeId;
    use crate::od::abort::AbortCode;

    const N: NodeId = NodeId::must(9);

    fn run(
        cfg: &SlaveConfig,
        id: &ExpectedIdentity,
        mut answer: impl FnMut(Access<'_>) -> Result<[u8; 4], SdoError>,
    ) -> (Vec<(u16, u8, bool)>, Outcome) {
        let mut p = Process::new(cfg);
        let mut seen = Vec::new();
        loop {
            let a = p.access(cfg).unwrap();
            let (index, sub, write) = match a {
                Access::Read { index, sub } => (index, sub, false),
                Access::Write { index, sub, .. } => (index, sub, true),
            };
            seen.push((index, sub, write));
            let r = answer(a);
            let out = p.handle(cfg, id, r.as_ref().map(|b| &b[..]).map_err(|e| *e));
            if out != Outcome::Continue {
                assert_eq!(p.access(cfg), None);
                return (seen, out);
            }
        }
    }

    #[test]
    fn reads_only_what_is_checked_then_configures_then_heartbeat() {
        let cfg = SlaveConfig::new(N)
            .write_u8(0x2000, 1, 7)
            .write_u32(0x2001, 0, 9)
            .heartbeat(100, 250);
        let id = ExpectedIdentity {
            vendor: 0x1234,
            serial: 42,
            ..Default::default()
        };
        let (seen, out) = run(&cfg, &id, |a| {
            Ok(match a {
                Access::Read { sub: 1, .. } => 0x1234u32,
                Access::Read { sub: 4, .. } => 42,
                _ => 0,
            }
            .to_le_bytes())
        });
        assert_eq!(out, Outcome::Done);
        assert_eq!(
            seen,
            [
                (0x1000, 0, false),
                (0x1018, 1, false),
                (0x1018, 4, false),
                (0x2000, 1, true),
                (0x2001, 0, true),
                (0x1017, 0, true)
            ]
        );
    }

    #[test]
    fn mismatch_names_the_letter_and_both_values() {
        let cfg = SlaveConfig::new(N);
        let id = ExpectedIdentity {
            device_type: 0x191,
            product: 5,
            ..Default::default()
        };
        let (_, out) = run(&cfg, &id, |a| {
            Ok(match a {
                Access::Read { sub: 0, .. } => 0x191u32,
                _ => 6,
            }
            .to_le_bytes())
        });
        assert_eq!(
            out,
            Outcome::Mismatch {
                status: ErrorStatus::M,
                index: 0x1018,
                sub: 2,
                expected: 5,
                actual: 6
            }
        );
    }

    #[test]
    fn failures_map_to_letters() {
        let err = |index, sub, direction| SdoError {
            node: N,
            index,
            sub,
            direction,
            kind: SdoErrorKind::Client(AbortCode::TIMEOUT),
        };
        let cfg = SlaveConfig::new(N).write_u8(0x2000, 0, 1);
        let (_, out) = run(&cfg, &ExpectedIdentity::default(), |_| {
            Err(err(0x1000, 0, Direction::Upload))
        });
        assert!(matches!(
            out,
            Outcome::Failed {
                status: ErrorStatus::B,
                ..
            }
        ));
        let (seen, out) = run(&cfg, &ExpectedIdentity::default(), |a| match a {
            Access::Write { .. } => Err(err(0x2000, 0, Direction::Download)),
            _ => Ok([0; 4]),
        });
        assert_eq!(seen.len(), 2);
        assert!(matches!(
            out,
            Outcome::Failed {
                status: ErrorStatus::J,
                ..
            }
        ));
    }

    #[test]
    fn short_identity_reply_is_refused() {
        let cfg = SlaveConfig::new(N);
        let mut p = Process::new(&cfg);
        let out = p.handle(&cfg, &ExpectedIdentity::default(), Ok(&[1, 2]));
        assert_eq!(
            out,
            Outcome::Failed {
                status: ErrorStatus::C,
                reason: BootError::BadReply {
                    index: 0x1000,
                    sub: 0,
                    len: 2
                }
            }
        );
    }

    #[test]
    fn pdo_step_runs_the_configurator_in_cia_order() {
        use crate::cia301::pdo::MapEntry;
        use crate::cia302::pdo_config::PdoConfig;
        use crate::frame::cob_id::CobId;
        let pdo = PdoConfig::new(CobId(0x189), 254)
            .event_timer(100)
            .mapping(&[MapEntry::new(0x2000, 1, 16)])
            .unwrap();
        let cfg = SlaveConfig::new(N).tpdo(1, pdo).write_u8(0x2001, 0, 1);
        let (seen, out) = run(&cfg, &ExpectedIdentity::default(), |a| {
            Ok(match a {
                Access::Read { index: 0x1800, .. } => 0x189u32,
                _ => 0,
            }
            .to_le_bytes())
        });
        assert_eq!(out, Outcome::Done);
        assert_eq!(
            seen,
            [
                (0x1000, 0, false),
                (0x1800, 1, false),
                (0x1800, 1, true),
                (0x1800, 2, true),
                (0x1800, 5, true),
                (0x1A00, 0, true),
                (0x1A00, 1, true),
                (0x1A00, 0, true),
                (0x1800, 1, true),
                (0x2001, 0, true),
            ]
        );
    }

    #[test]
    fn pdo_refused_and_different_fails_with_j_naming_the_entry() {
        use crate::cia302::pdo_config::{PdoConfig, PdoConfigErrorKind};
        use crate::frame::cob_id::CobId;
        let cfg = SlaveConfig::new(N).tpdo(2, PdoConfig::new(CobId(0x289), 1));
        let refused = |index, sub| SdoError {
            node: N,
            index,
            sub,
            direction: Direction::Download,
            kind: SdoErrorKind::Server(AbortCode::READ_ONLY),
        };
        // The device refuses every write and its COB-ID is another one.
        let (_, out) = run(&cfg, &ExpectedIdentity::default(), |a| match a {
            Access::Write { index, sub, .. } => Err(refused(index, sub)),
            Access::Read { index: 0x1801, .. } => Ok(0x4000_0199u32.to_le_bytes()),
            Access::Read { .. } => Ok([0; 4]),
        });
        let Outcome::Failed {
            status: ErrorStatus::J,
            reason: BootError::Pdo(e),
        } = out
        else {
            panic!("{out:?}")
        };
        assert_eq!((e.node, e.index, e.sub), (N, 0x1801, 1));
        assert!(e.fallback);
        assert!(matches!(e.kind, PdoConfigErrorKind::Mismatch { .. }));
    }

    #[test]
    fn pdo_number_out_of_range_fails_without_panicking() {
        use crate::cia302::pdo_config::PdoConfig;
        use crate::frame::cob_id::CobId;
        let cfg = SlaveConfig::new(N).rpdo(513, PdoConfig::new(CobId(0x209), 255));
        let mut p = Process::new(&cfg);
        let out = p.handle(&cfg, &ExpectedIdentity::default(), Ok(&[0; 4]));
        assert_eq!(
            out,
            Outcome::Failed {
                status: ErrorStatus::J,
                reason: BootError::NoSuchPdo { pdo: 513 }
            }
        );
        assert_eq!(p.access(&cfg), None);
    }

    #[test]
    fn letters_and_descriptions() {
        assert_eq!(ErrorStatus::O.letter(), 'O');
        assert_eq!(
            ErrorStatus::C.to_string(),
            "error status C: device type 0x1000 differs from 0x1F84"
        );
        assert_eq!(
            ErrorStatus::N.identity_objects(),
            Some(((0x1018, 3), 0x1F87))
        );
    }
}
