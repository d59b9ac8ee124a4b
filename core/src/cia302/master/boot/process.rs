//! The boot process of one slave as a pure state machine: the order of its SDO accesses
//! (identity, configuration steps with their PDO configurators, heartbeat), and what each
//! access's result means ([`Outcome`]).

use super::status::{BootError, ErrorStatus, IdentityMismatch};
use crate::cia301::pdo::params::MAX_PDOS;
use crate::cia301::sdo::{SdoError, SdoErrorKind};
use crate::cia302::master::config::{
    ConfigStep, ConfigurationStamp, ExpectedIdentity, SlaveConfig, WriteAborts,
};
use crate::cia302::master::objects::{SAVE, VERIFY_CONFIGURATION};
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
    /// 0x1020 sub 1 and 2 read, when a configuration stamp is expected.
    VerifyDate,
    VerifyTime,
    /// Index into the configuration steps.
    Config(usize),
    Heartbeat,
    /// 0x1020 sub 1 and 2 written, when a stamp is expected and no write was refused.
    StampDate,
    StampTime,
    /// 0x1010 sub 1 "save", when asked for and no write was refused.
    Store,
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
    Mismatch(IdentityMismatch),
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
    /// How many writes the slave refused in this run: with any, the stamp is not written nor
    /// the configuration stored, so the next boot writes it again.
    aborts: u32,
    /// The expected configuration stamp (0x1F26/0x1F27 when the process began).
    stamp: ConfigurationStamp,
    date: [u8; 4],
    time: [u8; 4],
    /// The slave's 0x1020 sub 1 held the expected date.
    date_matches: bool,
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
    pub(crate) fn new(cfg: &SlaveConfig, stamp: ConfigurationStamp) -> Process {
        Process {
            step: Step::DeviceType,
            heartbeat: cfg.heartbeat_producer_ms.unwrap_or(0).to_le_bytes(),
            pdo: None,
            aborted: None,
            aborts: 0,
            stamp,
            date: stamp.date.to_le_bytes(),
            time: stamp.time.to_le_bytes(),
            date_matches: false,
        }
    }

    /// The write the slave refused in the last access, once (with
    /// [`WriteAborts::Continue`]).
    pub(crate) fn take_abort(&mut self) -> Option<(u16, u8, AbortCode)> {
        self.aborted.take()
    }

    /// True once past the identity check.
    pub(crate) fn configuring(&self) -> bool {
        !matches!(
            self.step,
            Step::DeviceType | Step::Identity(_) | Step::VerifyDate | Step::VerifyTime
        )
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
            Step::VerifyDate | Step::VerifyTime => Some(Access::Read {
                index: VERIFY_CONFIGURATION,
                sub: if self.step == Step::VerifyDate { 1 } else { 2 },
            }),
            Step::StampDate => Some(Access::Write {
                index: VERIFY_CONFIGURATION,
                sub: 1,
                data: &self.date,
            }),
            Step::StampTime => Some(Access::Write {
                index: VERIFY_CONFIGURATION,
                sub: 2,
                data: &self.time,
            }),
            Step::Store => Some(Access::Write {
                index: comm::STORE_PARAMETERS,
                sub: 1,
                data: &SAVE,
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

    /// The step after `step`, skipping those that do not apply.
    fn next(&self, step: Step, cfg: &SlaveConfig, id: &ExpectedIdentity) -> Step {
        let mut s = step;
        loop {
            s = match s {
                Step::DeviceType => Step::Identity(1),
                Step::Identity(4) => Step::VerifyDate,
                Step::Identity(k) => Step::Identity(k + 1),
                Step::VerifyDate => Step::VerifyTime,
                Step::VerifyTime => Step::Config(0),
                Step::Config(i) if i + 1 < cfg.steps.len() => Step::Config(i + 1),
                Step::Config(_) => Step::Heartbeat,
                Step::Heartbeat => Step::StampDate,
                Step::StampDate => Step::StampTime,
                Step::StampTime => Step::Store,
                Step::Store | Step::Done => Step::Done,
            };
            let applies = match s {
                Step::Identity(k) => expected(id, k) != 0,
                Step::VerifyDate | Step::VerifyTime => self.stamp.is_set(),
                Step::Config(i) => i < cfg.steps.len(),
                Step::Heartbeat => cfg.heartbeat_producer_ms.is_some(),
                Step::StampDate | Step::StampTime => self.stamp.is_set() && self.aborts == 0,
                Step::Store => cfg.store && self.aborts == 0,
                Step::DeviceType | Step::Done => true,
            };
            if applies {
                return s;
            }
        }
    }

    /// Moves to the step after the current one; a PDO step gets its configurator.
    fn advance(&mut self, cfg: &SlaveConfig, id: &ExpectedIdentity) -> Outcome {
        self.step = self.next(self.step, cfg, id);
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
                if let SdoErrorKind::Server(code) = e.kind {
                    // A slave without 0x1020 (or refusing it) is configured as one that
                    // holds another stamp.
                    if matches!(step, Step::VerifyDate | Step::VerifyTime) {
                        self.step = Step::VerifyTime;
                        return self.advance(cfg, id);
                    }
                    if let (Some(Access::Write { index, sub, .. }), WriteAborts::Continue) =
                        (self.access(cfg), cfg.write_aborts)
                    {
                        self.aborted = Some((index, sub, code));
                        self.aborts += 1;
                        return self.advance(cfg, id);
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
        let stamp = |want: u32| <[u8; 4]>::try_from(data).ok() == Some(want.to_le_bytes());
        match step {
            Step::VerifyDate => self.date_matches = stamp(self.stamp.date),
            // Configured already: nothing is written.
            Step::VerifyTime if self.date_matches && stamp(self.stamp.time) => {
                self.step = Step::Done;
                return Outcome::Done;
            }
            _ => {}
        }
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
                return Outcome::Mismatch(IdentityMismatch {
                    status,
                    index,
                    sub,
                    expected: want,
                    actual,
                });
            }
        }
        self.advance(cfg, id)
    }
}
