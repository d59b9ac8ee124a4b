//! What is seen of a slave's boot process: the CiA 302-2 error status letters ([`ErrorStatus`],
//! with the identity entries each check compares), why a step failed ([`BootError`]), and the
//! phase the slave is in as far as this master's boot process goes ([`BootPhase`]).

use crate::cia301::sdo::SdoError;
use crate::cia302::pdo_config::PdoConfigError;
use crate::od::comm;
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
        use crate::cia302::master::objects::*;
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
    /// The node's concise DCF (0x1F22 sub n) cannot be read: nothing was written.
    ConciseDcf(crate::cia302::master::ConciseError),
}

/// A slave whose identity entry holds something else than 0x1F84–0x1F88 expect: the one
/// declaration of it, carried by the master's event
/// ([`MasterEventKind::IdentityMismatch`](super::super::MasterEventKind::IdentityMismatch)) and
/// by whatever reports a refused slave above the master.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct IdentityMismatch {
    /// C, D, M, N or O.
    pub status: ErrorStatus,
    /// The slave's entry (0x1000 or 0x1018).
    pub index: u16,
    /// Its sub-index.
    pub sub: u8,
    /// What the master expects.
    pub expected: u32,
    /// What the slave has.
    pub actual: u32,
}

/// `error status D: … (0x1018sub1 is 0x00004321, expected 0x00001234)`.
impl fmt::Display for IdentityMismatch {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let IdentityMismatch {
            status,
            index,
            sub,
            expected,
            actual,
        } = self;
        write!(
            f,
            "{status} ({index:#06x}sub{sub} is {actual:#010x}, expected {expected:#010x})"
        )
    }
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
            BootError::ConciseDcf(e) => write!(f, "0x1F22: {e}"),
        }
    }
}

impl core::error::Error for BootError {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        match self {
            BootError::Sdo(e) => Some(e),
            BootError::Pdo(e) => Some(e),
            BootError::ConciseDcf(e) => Some(e),
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
    /// The boot process failed; waits for the next boot-up or
    /// [`Master::boot_slave`](crate::cia302::master::Master::boot_slave).
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
