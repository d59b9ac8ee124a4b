//! The boot process of one slave as a pure state machine: the order of its SDO accesses
//! (identity, configuration steps with their PDO configurators, heartbeat), and what each
//! access's result means ([`Outcome`]).

use super::status::{BootError, ErrorStatus};
use crate::cia301::pdo::params::MAX_PDOS;
use crate::cia301::sdo::{SdoError, SdoErrorKind};
use crate::cia302::master::config::{ConfigStep, ExpectedIdentity, SlaveConfig, WriteAborts};
use crate::cia302::pdo_config::{AccessError, PdoConfigurator, SdoAccess};
use crate::od::abort::AbortCode;
use crate::od::comm;
use alloc::boxed::Box;

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
    /// The write the slave refused last, not yet reported (index, sub, code).
    aborted: Option<(u16, u8, AbortCode)>,
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
            aborted: None,
        }
    }

    /// The write the slave refused in the last access, once (with
    /// [`WriteAborts::Continue`]).
    pub(crate) fn take_abort(&mut self) -> Option<(u16, u8, AbortCode)> {
        self.aborted.take()
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
                if let (Step::Config(i), SdoErrorKind::Server(code)) = (step, e.kind) {
                    if let Some(ConfigStep::Write { index, sub, .. }) = cfg.steps.get(i) {
                        if cfg.write_aborts == WriteAborts::Continue {
                            self.aborted = Some((*index, *sub, code));
                            return self.advance(cfg, id);
                        }
                    }
                }
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
