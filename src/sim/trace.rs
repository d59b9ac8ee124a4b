//! The recorder: what happened on the wires, comparable between runs.

use super::ids::{BusId, PortRef};
use crate::frame::instant::Instant;
use crate::frame::{FdFrame, Frame};
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
    /// The frame as sent; for a CAN FD frame its identifier with no data, the frame itself
    /// being in `fd`.
    pub frame: Frame,
    /// The CAN FD frame as sent, if it is one (boxed: a trace of classic frames keeps its
    /// records' size).
    pub fd: Option<Box<FdFrame>>,
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
    /// The frame as sent; for a CAN FD frame its identifier with no data, the frame itself
    /// being in `fd`.
    pub frame: Frame,
    /// The CAN FD frame as sent, if it is one.
    pub fd: Option<Box<FdFrame>>,
    /// What happened to it at this port.
    pub fault: RxFault,
}

/// What a receiving port suffered.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RxFault {
    /// Lost in the controller (reported as receive overflow), or by an error-passive
    /// receiver that detected an error in it (its passive error flag destroys the frame for
    /// it alone; reported as a CRC error).
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
    /// A data bit of a CAN FD frame flipped without detection: the device got the frame of
    /// the record's `fd` with data bit `bit` (0: the most significant bit of byte 0) flipped.
    CorruptedFd {
        /// The flipped bit.
        bit: u16,
    },
}

/// The frame of a record, for display: the CAN FD one if it is one.
struct Shown<'a>(&'a Frame, Option<&'a FdFrame>);

impl fmt::Display for Shown<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.1 {
            Some(fd) => write!(f, "{fd}"),
            None => write!(f, "{}", self.0),
        }
    }
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
                Shown(&t.frame, t.fd.as_deref()),
                if t.babble { " (babble)" } else { "" },
                t.outcome
            ),
            TraceRecord::Rx(r) => {
                write!(
                    f,
                    "{} {} rx {} {}: {:?}",
                    r.at,
                    r.bus,
                    r.port,
                    Shown(&r.frame, r.fd.as_deref()),
                    r.fault
                )
            }
        }
    }
}

impl TxRecord {
    /// The frame as a capture record: [`Record::Fd`](crate::capture::Record::Fd) for a CAN FD
    /// frame, so that a capture of the trace keeps it as one.
    pub fn capture_record(&self) -> crate::capture::Record {
        match &self.fd {
            Some(f) => crate::capture::Record::Fd(f.clone()),
            None => crate::capture::Record::Frame(self.frame),
        }
    }
}

impl super::SimNetwork {
    /// Writes what the buses carried as a candump log: every delivered frame of the trace,
    /// stamped with the instant it ended on the wire, its bus's name as the interface. CAN FD
    /// frames are `##` lines.
    pub fn write_candump(&self, out: impl std::io::Write) -> std::io::Result<()> {
        let mut w = crate::capture::candump::CandumpWriter::new(out);
        for t in self.delivered() {
            let (at, name) = (t.end.as_micros(), &*self.bus(t.bus).name);
            match &t.fd {
                Some(f) => w.write_fd(at, name, f)?,
                None => w.write(at, name, &t.frame)?,
            }
        }
        w.flush()
    }

    /// Writes what the buses carried as a pcap file (`LINKTYPE_CAN_SOCKETCAN`), as
    /// [`write_candump`](Self::write_candump) does: CAN FD frames are `canfd_frame` packets.
    pub fn write_pcap(&self, out: impl std::io::Write) -> std::io::Result<()> {
        let mut w = crate::capture::pcap::PcapWriter::new(out)?;
        for t in self.delivered() {
            match &t.fd {
                Some(f) => w.write_fd(t.end.as_micros(), f)?,
                None => w.write(t.end.as_micros(), &t.frame)?,
            }
        }
        w.flush()
    }

    fn delivered(&self) -> impl Iterator<Item = &TxRecord> {
        self.trace.iter().filter_map(|r| match r {
            TraceRecord::Tx(t) if matches!(t.outcome, TxOutcome::Delivered { .. }) => Some(t),
            _ => None,
        })
    }
}
