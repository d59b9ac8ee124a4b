//! Program download, the master's side (CiA 302-3): a new program for a slave, as a pure
//! state machine ([`ProgramDownload`]) of SDO accesses that [`super::Master::download_program`]
//! runs on the master's client.
//!
//! # The order
//!
//! 1. stop the program (0x1F51 sub 1 = 0);
//! 2. clear the staging area (0x1F51 sub 1 = 3);
//! 3. the image to 0x1F50 sub 1, by SDO block transfer (with its CRC);
//! 4. start (0x1F51 sub 1 = 1): the slave puts the verified image in control and runs it;
//! 5. read 0x1F56 sub 1 and compare it with the expected software identification (0x1F55
//!    sub n of the master; 0: not checked).
//!
//! # Failure
//!
//! Any failed access ends the procedure there, its error naming the step and the abort code
//! (a transfer the master gives up on, a timeout, is aborted on the bus by the SDO client;
//! one the slave refuses was aborted by the slave). The new program is never started after a
//! failed step. When steps 1–3 fail, the master then writes reset (0x1F51 sub 1 = 2), which
//! drops whatever the slave staged and runs the program it had: reset rather than start, so
//! that an image the slave did store while its answer was lost is not started either.
//! [`ProgramDownloadError::resumed`] says whether the slave took it.
//!
//! # Memory
//!
//! The machine holds the image (one allocation, made by the caller) and a few words; the SDO
//! client copies it into the session's transfer buffer, bounded by the client's limit.

use crate::cia301::sdo::{SdoError, SdoErrorKind};
use crate::cia302::program::{control, PROGRAM_CONTROL, PROGRAM_DATA, PROGRAM_IDENTIFICATION};
use crate::frame::cob_id::NodeId;
use crate::od::abort::AbortCode;
use alloc::vec::Vec;
use core::fmt;

/// A step of the procedure.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ProgramStep {
    /// 0x1F51 = stop.
    Stop,
    /// 0x1F51 = clear.
    Clear,
    /// 0x1F50: the image.
    Download,
    /// 0x1F51 = start.
    Start,
    /// 0x1F56 read and compared.
    Verify,
}

impl fmt::Display for ProgramStep {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            ProgramStep::Stop => "stop (0x1F51)",
            ProgramStep::Clear => "clear (0x1F51)",
            ProgramStep::Download => "download (0x1F50)",
            ProgramStep::Start => "start (0x1F51)",
            ProgramStep::Verify => "verify (0x1F56)",
        })
    }
}

/// A program download that finished.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ProgramReport {
    /// The slave.
    pub node: NodeId,
    /// Bytes of the image.
    pub bytes: usize,
    /// The slave's software identification after start (0x1F56 sub 1).
    pub identification: u32,
}

/// What went wrong in a step.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum ProgramErrorKind {
    /// The SDO access failed (the abort code of either side, a timeout included).
    Sdo(SdoError),
    /// The slave runs a program whose identification is not the expected one.
    WrongIdentification {
        /// 0x1F55 sub n.
        expected: u32,
        /// 0x1F56 sub 1 of the slave.
        actual: u32,
    },
    /// 0x1F56 answered with other than 4 bytes.
    BadReply {
        /// Bytes received.
        len: usize,
    },
    /// The master stopped managing the network (it became standby) during the step: a
    /// standby sends nothing, so the procedure ends there.
    Abandoned,
}

/// A program download that failed: where and how.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ProgramDownloadError {
    /// The slave.
    pub node: NodeId,
    /// The step that failed.
    pub step: ProgramStep,
    /// How.
    pub kind: ProgramErrorKind,
    /// After a failed stop, clear or download: the slave took the reset and runs its old
    /// program again. False otherwise.
    pub resumed: bool,
}

impl ProgramDownloadError {
    /// The abort code of the failed access, if it was an SDO failure with one.
    #[must_use]
    pub fn code(&self) -> Option<AbortCode> {
        match self.kind {
            ProgramErrorKind::Sdo(e) => e.code(),
            _ => None,
        }
    }
}

impl fmt::Display for ProgramDownloadError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "program download to {}, step {}: ", self.node, self.step)?;
        match self.kind {
            ProgramErrorKind::Sdo(e) => write!(f, "{e}")?,
            ProgramErrorKind::WrongIdentification { expected, actual } => write!(
                f,
                "the slave runs software {actual:#010x}, expected {expected:#010x} (0x1F55)"
            )?,
            ProgramErrorKind::BadReply { len } => {
                write!(f, "0x1F56 answered with {len} bytes instead of 4")?
            }
            ProgramErrorKind::Abandoned => f.write_str("abandoned: the master became standby")?,
        }
        if self.resumed {
            f.write_str("; the old program runs again")?;
        }
        Ok(())
    }
}

impl core::error::Error for ProgramDownloadError {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        match &self.kind {
            ProgramErrorKind::Sdo(e) => Some(e),
            _ => None,
        }
    }
}

/// One SDO access of the procedure.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ProgramAccess<'a> {
    /// A download; `block`: by block transfer.
    Write {
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// The bytes.
        data: &'a [u8],
        /// Block transfer wanted.
        block: bool,
    },
    /// An upload.
    Read {
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
    },
}

#[derive(Clone, Debug, PartialEq, Eq)]
enum Phase {
    Step(ProgramStep),
    /// The reset after a failed step, the error to report after it, and how many more times
    /// a refused reset is tried.
    Resume(ProgramDownloadError, u8),
    Done(Result<ProgramReport, ProgramDownloadError>),
}

/// The program download procedure for one slave (the order and the failure rule are in the
/// module docs). Sans-IO: [`ProgramDownload::access`] gives the SDO access to do,
/// [`ProgramDownload::handle`] takes its result.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ProgramDownload {
    node: NodeId,
    image: Vec<u8>,
    expected: u32,
    phase: Phase,
}

/// How many times a refused reset is sent again. A slave that lost the transfer (it
/// restarted) answers each block segment still on the bus with an abort, and an SDO client
/// takes an abort as the answer to the request it has out: up to one sub-block, at most 127
/// segments, of such answers may arrive before the slave hears the reset.
const RESUME_TRIES: u8 = 128;

const STOP: [u8; 1] = [control::STOP];
const START: [u8; 1] = [control::START];
const RESET: [u8; 1] = [control::RESET];
const CLEAR: [u8; 1] = [control::CLEAR];

impl ProgramDownload {
    /// `image` for `node`, whose identification after start must be `expected` (0: not
    /// checked).
    #[must_use]
    pub fn new(node: NodeId, image: Vec<u8>, expected: u32) -> ProgramDownload {
        ProgramDownload {
            node,
            image,
            expected,
            phase: Phase::Step(ProgramStep::Stop),
        }
    }

    /// The slave.
    pub fn node(&self) -> NodeId {
        self.node
    }
    /// Bytes of the image.
    pub fn len(&self) -> usize {
        self.image.len()
    }
    /// True for an empty image.
    pub fn is_empty(&self) -> bool {
        self.image.is_empty()
    }
    /// The step under way; `None` when finished or resuming after a failure.
    pub fn step(&self) -> Option<ProgramStep> {
        match self.phase {
            Phase::Step(s) => Some(s),
            _ => None,
        }
    }

    /// The access to do now; `None` when finished.
    pub fn access(&self) -> Option<ProgramAccess<'_>> {
        let control = |data: &'static [u8]| ProgramAccess::Write {
            index: PROGRAM_CONTROL,
            sub: 1,
            data,
            block: false,
        };
        Some(match &self.phase {
            Phase::Step(ProgramStep::Stop) => control(&STOP),
            Phase::Step(ProgramStep::Clear) => control(&CLEAR),
            Phase::Step(ProgramStep::Download) => ProgramAccess::Write {
                index: PROGRAM_DATA,
                sub: 1,
                data: &self.image,
                block: true,
            },
            Phase::Step(ProgramStep::Start) => control(&START),
            Phase::Step(ProgramStep::Verify) => ProgramAccess::Read {
                index: PROGRAM_IDENTIFICATION,
                sub: 1,
            },
            Phase::Resume(..) => control(&RESET),
            Phase::Done(_) => return None,
        })
    }

    /// Takes the result of the access [`ProgramDownload::access`] gave.
    pub fn handle(&mut self, result: Result<&[u8], SdoError>) {
        let step = match &mut self.phase {
            Phase::Step(s) => *s,
            Phase::Resume(e, tries) => {
                let refused = matches!(
                    result,
                    Err(SdoError {
                        kind: SdoErrorKind::Server(_),
                        ..
                    })
                );
                if refused && *tries > 0 {
                    *tries -= 1;
                    return;
                }
                let mut e = *e;
                e.resumed = result.is_ok();
                self.phase = Phase::Done(Err(e));
                return;
            }
            Phase::Done(_) => return,
        };
        let fail = |kind| ProgramDownloadError {
            node: self.node,
            step,
            kind,
            resumed: false,
        };
        let data = match result {
            Ok(d) => d,
            Err(e) => {
                let e = fail(ProgramErrorKind::Sdo(e));
                self.phase = match step {
                    ProgramStep::Stop | ProgramStep::Clear | ProgramStep::Download => {
                        Phase::Resume(e, RESUME_TRIES)
                    }
                    _ => Phase::Done(Err(e)),
                };
                return;
            }
        };
        self.phase = match step {
            ProgramStep::Stop => Phase::Step(ProgramStep::Clear),
            ProgramStep::Clear => Phase::Step(ProgramStep::Download),
            ProgramStep::Download => Phase::Step(ProgramStep::Start),
            ProgramStep::Start => Phase::Step(ProgramStep::Verify),
            ProgramStep::Verify => Phase::Done(match <[u8; 4]>::try_from(data) {
                Err(_) => Err(fail(ProgramErrorKind::BadReply { len: data.len() })),
                Ok(b) => {
                    let actual = u32::from_le_bytes(b);
                    if self.expected != 0 && actual != self.expected {
                        Err(fail(ProgramErrorKind::WrongIdentification {
                            expected: self.expected,
                            actual,
                        }))
                    } else {
                        Ok(ProgramReport {
                            node: self.node,
                            bytes: self.image.len(),
                            identification: actual,
                        })
                    }
                }
            }),
        };
    }

    /// Ends the procedure where it is, without another access (the master may send nothing
    /// more): a step under way fails as [`ProgramErrorKind::Abandoned`]; a reset not yet
    /// taken leaves the error that asked for it, not resumed.
    pub fn abandon(&mut self) {
        let error = match &self.phase {
            Phase::Step(step) => ProgramDownloadError {
                node: self.node,
                step: *step,
                kind: ProgramErrorKind::Abandoned,
                resumed: false,
            },
            Phase::Resume(e, _) => *e,
            Phase::Done(_) => return,
        };
        self.phase = Phase::Done(Err(error));
    }

    /// The outcome, once finished.
    pub fn result(&self) -> Option<Result<ProgramReport, ProgramDownloadError>> {
        match &self.phase {
            Phase::Done(r) => Some(*r),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cia301::sdo::Direction;

    fn refused(node: NodeId, index: u16, code: AbortCode) -> SdoError {
        SdoError {
            node,
            index,
            sub: 1,
            direction: Direction::Download,
            kind: SdoErrorKind::Server(code),
        }
    }

    #[test]
    fn the_steps_in_order_then_the_identification() {
        let n = NodeId::must(4);
        let mut p = ProgramDownload::new(n, alloc::vec![7; 100], 0xAB);
        let mut seen = alloc::vec![];
        while let Some(a) = p.access() {
            seen.push(a.clone_shape());
            let reply = if matches!(a, ProgramAccess::Read { .. }) {
                &[0xAB, 0, 0, 0][..]
            } else {
                &[]
            };
            p.handle(Ok(reply));
        }
        assert_eq!(
            seen,
            [
                (PROGRAM_CONTROL, Some(0), false),
                (PROGRAM_CONTROL, Some(3), false),
                (PROGRAM_DATA, Some(7), true),
                (PROGRAM_CONTROL, Some(1), false),
                (PROGRAM_IDENTIFICATION, None, false),
            ]
        );
        assert_eq!(
            p.result(),
            Some(Ok(ProgramReport {
                node: n,
                bytes: 100,
                identification: 0xAB
            }))
        );
    }

    #[test]
    fn a_failed_download_resets_and_never_starts() {
        let n = NodeId::must(4);
        let mut p = ProgramDownload::new(n, alloc::vec![1; 10], 0);
        p.handle(Ok(&[]));
        p.handle(Ok(&[]));
        let e = refused(n, PROGRAM_DATA, AbortCode::CANNOT_STORE);
        p.handle(Err(e));
        assert_eq!(
            p.access().map(|a| a.clone_shape()),
            Some((PROGRAM_CONTROL, Some(2), false))
        );
        p.handle(Ok(&[]));
        let err = p.result().unwrap().unwrap_err();
        assert_eq!((err.step, err.resumed), (ProgramStep::Download, true));
        assert_eq!(err.code(), Some(AbortCode::CANNOT_STORE));
        assert!(p.access().is_none());
    }

    impl ProgramAccess<'_> {
        /// (index, first data byte, block) for comparisons.
        fn clone_shape(&self) -> (u16, Option<u8>, bool) {
            match *self {
                ProgramAccess::Write {
                    index, data, block, ..
                } => (index, data.first().copied(), block),
                ProgramAccess::Read { index, .. } => (index, None, false),
            }
        }
    }
}
