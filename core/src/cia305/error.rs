//! What an LSS master request can end in besides its result.

use super::codec::{Inquiry, LssAddress, LssFrameError};
use core::fmt;

/// The LSS service a request or an error is about.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum LssService {
    /// Switch state global.
    SwitchGlobal,
    /// Switch state selective.
    SwitchSelective,
    /// Configure node-ID.
    ConfigureNodeId,
    /// Configure bit timing.
    ConfigureBitTiming,
    /// Activate bit timing.
    ActivateBitTiming,
    /// Store configuration.
    Store,
    /// Inquire identity part or node-ID.
    Inquire(Inquiry),
    /// Identify remote slave.
    IdentifyRemote,
    /// Identify non-configured remote slave.
    IdentifyNonConfigured,
    /// Fastscan.
    Fastscan,
}

impl fmt::Display for LssService {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            LssService::SwitchGlobal => "switch state global",
            LssService::SwitchSelective => "switch state selective",
            LssService::ConfigureNodeId => "configure node-ID",
            LssService::ConfigureBitTiming => "configure bit timing",
            LssService::ActivateBitTiming => "activate bit timing",
            LssService::Store => "store configuration",
            LssService::Inquire(Inquiry::Vendor) => "inquire vendor-ID",
            LssService::Inquire(Inquiry::Product) => "inquire product code",
            LssService::Inquire(Inquiry::Revision) => "inquire revision number",
            LssService::Inquire(Inquiry::Serial) => "inquire serial number",
            LssService::Inquire(Inquiry::NodeId) => "inquire node-ID",
            LssService::IdentifyRemote => "identify remote slave",
            LssService::IdentifyNonConfigured => "identify non-configured remote slave",
            LssService::Fastscan => "fastscan",
        })
    }
}

/// Why an LSS master request failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum LssError {
    /// Another request is still running (LSS serves one at a time).
    Busy,
    /// A node-ID outside 1–127 (and not 0xFF, "none").
    InvalidNodeId(u8),
    /// No slave answered before the timeout.
    Timeout(LssService),
    /// The slave answered with an error code (`spec`: the manufacturer's code when `error` is
    /// 0xFF).
    Refused {
        /// The service.
        service: LssService,
        /// CiA 305 error code: 1 not supported / out of range, 2 medium failed (store).
        error: u8,
        /// Manufacturer-specific error.
        spec: u8,
    },
    /// A slave answered with the answer of another service.
    WrongAnswer {
        /// The service waited for.
        service: LssService,
        /// The command specifier that came.
        cs: u8,
    },
    /// A slave's answer is not an LSS frame.
    Malformed {
        /// The service waited for.
        service: LssService,
        /// What was wrong with the frame.
        error: LssFrameError,
    },
    /// Fastscan lost the slave it was confirming (`sub`: the identity part, 0 vendor … 3
    /// serial) in every attempt, the first and [`RESTARTS`](super::fastscan::RESTARTS) more:
    /// it keeps leaving the bus, or another master or stray answers keep interfering.
    ScanLost {
        /// The identity part whose confirmation went unanswered.
        sub: u8,
    },
    /// Fastscan found a slave the plan has no node-ID for (it was switched back to waiting).
    NoNodeId(LssAddress),
}

impl fmt::Display for LssError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LssError::Busy => f.write_str("another LSS request is running"),
            LssError::InvalidNodeId(n) => {
                write!(f, "node-ID {n} is outside 1-127 (0xFF means none)")
            }
            LssError::Timeout(s) => write!(f, "{s}: no LSS slave answered in time"),
            LssError::Refused {
                service,
                error,
                spec,
            } => {
                let why = match (service, error) {
                    (LssService::Store, 1) => "not supported",
                    (LssService::Store, 2) => "the storage medium failed",
                    (_, 1) => "out of range or not supported",
                    (_, 0xFF) => "manufacturer-specific error",
                    _ => "reserved error code",
                };
                write!(
                    f,
                    "{service}: the slave refused with code {error} ({why}, spec {spec})"
                )
            }
            LssError::WrongAnswer { service, cs } => {
                write!(f, "{service}: a slave answered with command {cs:#04x}")
            }
            LssError::Malformed { service, error } => {
                write!(f, "{service}: a slave's answer is malformed: {error}")
            }
            LssError::ScanLost { sub } => {
                let part = [
                    "vendor-ID",
                    "product code",
                    "revision number",
                    "serial number",
                ];
                let part = part.get(usize::from(*sub)).unwrap_or(&"part");
                write!(
                    f,
                    "fastscan: the slave's {part} went unconfirmed in {} attempts (the slave keeps leaving, or another master or stray answers interfere)",
                    super::fastscan::RESTARTS + 1
                )
            }
            LssError::NoNodeId(a) => write!(f, "fastscan: the plan has no node-ID for {a}"),
        }
    }
}

impl core::error::Error for LssError {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        match self {
            LssError::Malformed { error, .. } => Some(error),
            _ => None,
        }
    }
}
