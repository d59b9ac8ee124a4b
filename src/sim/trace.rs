//! The recorder: what happened on the wires, comparable between runs.

use super::ids::{BusId, PortRef};
use crate::frame::instant::Instant;
use crate::frame::Frame;
use core::fmt;
use std::sync::Arc;

/// One entry of [`SimNetwork::trace`](super::SimNetwork::trace).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum TraceRecord {
    /// A transmission attempt, recorded when it ends.
    Tx(TxRecord),
    /// A fault that hit one receiver of a delivered frame; follows the frame's [`TxRecord`].
    Rx(RxRecord),
}

/// A transmission attempt.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TxRecord {
    /// Start of frame.
    pub start: Instant,
    /// End of the attempt, intermission included (or the instant it was aborted).
    pub end: Instant,
    /// The bus.
    pub bus: BusId,
    /// The segment of the bus that carried it (0 unless partitioned or cut off).
    pub segment: u32,
    /// The sending port.
    pub sender: PortRef,
    /// The sending device's name.
    pub sender_name: Arc<str>,
    /// The frame as sent.
    pub frame: Frame,
    /// Which frame of its sender it is: the sender device's frames are numbered from 0 in the
    /// order its `poll_transmit` handed them over (on any port); a retransmission keeps the
    /// number. `None` for a babbling controller's frames.
    pub serial: Option<u64>,
    /// Whether a babbling controller sent it rather than the device.
    pub babble: bool,
    /// What became of it.
    pub outcome: TxOutcome,
}

/// What became of a transmission attempt.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TxOutcome {
    /// Acknowledged; handed to this many receiving ports (before per-receiver faults).
    Delivered {
        /// Powered, connected ports on the segment other than the sender.
        receivers: u32,
    },
    /// Nobody else was on the segment to acknowledge it.
    NoAck,
    /// The bus was down (cut).
    BusDown,
    /// The sending port was disconnected.
    SenderDisconnected,
    /// The sending device was powered off or rebooted during the attempt.
    SenderOff,
    /// A detected error destroyed it; the sender retransmits.
    ErrorFrame,
    /// A partition or heal of the bus cut it short; the sender retransmits.
    Aborted,
}

/// A fault at one receiving port.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RxRecord {
    /// When the frame ended on the wire.
    pub at: Instant,
    /// The bus.
    pub bus: BusId,
    /// The receiving port.
    pub port: PortRef,
    /// The frame as sent.
    pub frame: Frame,
    /// What happened to it at this port.
    pub fault: RxFault,
}

/// What a receiving port suffered.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RxFault {
    /// Lost in the controller (reported as receive overflow).
    Dropped,
    /// Handed to the device twice.
    Duplicated,
    /// Handed to the device at `until` instead of at the end of the frame.
    Delayed {
        /// When the device gets it.
        until: Instant,
    },
    /// A data bit flipped without detection; the device got `delivered`.
    Corrupted {
        /// The frame as delivered.
        delivered: Frame,
    },
}

/// One line per record, e.g. `0.001053s bus0/0 dev1.0 "b" 0x181 [1] 01 -> Delivered { receivers: 2 }`.
impl fmt::Display for TraceRecord {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TraceRecord::Tx(t) => write!(
                f,
                "{} {}/{} {} {:?} {}{} -> {:?}",
                t.end,
                t.bus,
                t.segment,
                t.sender,
                t.sender_name,
                t.frame,
                if t.babble { " (babble)" } else { "" },
                t.outcome
            ),
            TraceRecord::Rx(r) => {
                write!(
                    f,
                    "{} {} rx {} {}: {:?}",
                    r.at, r.bus, r.port, r.frame, r.fault
                )
            }
        }
    }
}
