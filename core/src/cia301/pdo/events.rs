//! What the PDO engine reports: its events, its errors, and the status of each PDO.

use super::mapping::Dir;
use crate::frame::instant::Instant;
use crate::frame::Id;
use crate::od::abort::AbortCode;
use core::fmt;

/// What the PDO engine reports (inside the node's events: `NodeEventKind::Pdo`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum PdoEvent {
    /// An RPDO's data was written into the dictionary: at reception for asynchronous RPDOs, at
    /// the SYNC after reception for synchronous ones. One event per PDO, not per entry; can be
    /// switched off ([`crate::node::Node::set_rpdo_events`]) at high rates.
    RpdoReceived {
        /// RPDO number (1 = 0x1400).
        pdo: u16,
    },
    /// An RPDO with an event timer was not received in time (EMCY 0x8250 raised). Fires once per
    /// loss, exactly at the last reception + the event timer.
    RpdoTimeout {
        /// RPDO number.
        pdo: u16,
        /// Its last reception.
        last: Instant,
    },
    /// An RPDO frame shorter than its mapping was refused (EMCY 0x8210 raised). Reported once
    /// per error episode; a correct frame ends it.
    RpdoTooShort {
        /// RPDO number.
        pdo: u16,
        /// Bytes the mapping needs.
        expected: u8,
        /// Bytes received.
        got: u8,
    },
    /// A valid PDO's stored configuration cannot be used (a mapped entry is gone, a reserved
    /// transmission type was stored behind the stack's back); the PDO stays silent.
    Unusable {
        /// Receive or transmit.
        dir: Dir,
        /// PDO number.
        pdo: u16,
        /// What is wrong, as the abort code a write of it would get.
        reason: AbortCode,
    },
    /// An MPDO's value was written into the dictionary (`mpdo` feature; switched off with the
    /// RPDO events, [`crate::node::Node::set_rpdo_events`]).
    #[cfg(feature = "mpdo")]
    MpdoWritten {
        /// RPDO number.
        pdo: u16,
        /// The local object written.
        index: u16,
        /// Its sub-index.
        sub: u8,
    },
    /// An MPDO's value was refused by the local object (`mpdo` feature): missing, not
    /// RPDO-mappable, read-only, or larger than the value.
    #[cfg(feature = "mpdo")]
    MpdoRefused {
        /// RPDO number.
        pdo: u16,
        /// The local object.
        index: u16,
        /// Its sub-index.
        sub: u8,
        /// Why, as the abort code an RPDO mapping of it would get.
        reason: AbortCode,
    },
}

/// One line: `RPDO 2 not received in time (last at 1.250 s)`.
impl fmt::Display for PdoEvent {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PdoEvent::RpdoReceived { pdo } => write!(f, "RPDO {pdo} received"),
            PdoEvent::RpdoTimeout { pdo, last } => {
                write!(f, "RPDO {pdo} not received in time (last at {last})")
            }
            PdoEvent::RpdoTooShort { pdo, expected, got } => write!(
                f,
                "RPDO {pdo} refused: {got} bytes, its mapping needs {expected}"
            ),
            PdoEvent::Unusable { dir, pdo, reason } => write!(
                f,
                "{} {pdo} unusable, it stays silent: {reason}",
                match dir {
                    Dir::Receive => "RPDO",
                    Dir::Transmit => "TPDO",
                }
            ),
            #[cfg(feature = "mpdo")]
            PdoEvent::MpdoWritten { pdo, index, sub } => {
                write!(f, "MPDO on RPDO {pdo} wrote {index:#06x}/{sub}")
            }
            #[cfg(feature = "mpdo")]
            PdoEvent::MpdoRefused {
                pdo,
                index,
                sub,
                reason,
            } => write!(
                f,
                "MPDO on RPDO {pdo} refused by {index:#06x}/{sub}: {reason}"
            ),
        }
    }
}

/// Why an application request for a PDO was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PdoError {
    /// The node has no such PDO (number 0 or beyond its capacity).
    NoSuchPdo {
        /// The number asked for.
        pdo: u16,
    },
    /// The PDO is not running: invalid COB-ID, empty or unusable mapping, or the node is not
    /// operational.
    NotRunning {
        /// The PDO.
        pdo: u16,
    },
    /// Its transmission type does not send on application events (only 0, 254, 255 do).
    NotEventDriven {
        /// The PDO.
        pdo: u16,
        /// Its transmission type.
        transmission_type: u8,
    },
}

impl fmt::Display for PdoError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PdoError::NoSuchPdo { pdo } => write!(
                f,
                "TPDO{pdo} does not exist on this node: raise the node's TPDO capacity"
            ),
            PdoError::NotRunning { pdo } => write!(
                f,
                "TPDO{pdo} is not running: check its COB-ID (bit 31), its mapping and that the node is operational"
            ),
            PdoError::NotEventDriven {
                pdo,
                transmission_type,
            } => write!(
                f,
                "TPDO{pdo} has transmission type {transmission_type}: only types 0, 254 and 255 send on request"
            ),
        }
    }
}

impl core::error::Error for PdoError {}

/// What a TPDO is doing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TpdoStatus {
    /// Its identifier, if its COB-ID is valid.
    pub id: Option<Id>,
    /// Transmission type.
    pub transmission_type: u8,
    /// Sending (valid, usable, node operational).
    pub running: bool,
    /// Mapped length in bits.
    pub mapped_bits: u32,
    /// Frames sent.
    pub sent: u32,
    /// Last transmission.
    pub last_sent: Option<Instant>,
    /// Why a valid PDO is unusable.
    pub error: Option<AbortCode>,
}

/// What an RPDO is doing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RpdoStatus {
    /// Its identifier, if its COB-ID is valid.
    pub id: Option<Id>,
    /// Transmission type.
    pub transmission_type: u8,
    /// Receiving (valid, usable, node operational).
    pub running: bool,
    /// Mapped length in bits.
    pub mapped_bits: u32,
    /// Frames accepted.
    pub received: u32,
    /// Last accepted frame.
    pub last_received: Option<Instant>,
    /// The reception timeout expired and no frame came since.
    pub timed_out: bool,
    /// The last frame was too short.
    pub length_error: bool,
    /// Why a valid PDO is unusable.
    pub error: Option<AbortCode>,
}
