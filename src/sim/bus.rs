//! Buses, their segments and the port controllers attached to them.

use super::fault::FaultRates;
use crate::frame::instant::{Duration, Instant};
use crate::frame::{FdFrame, Frame};
use std::collections::{BTreeSet, VecDeque};
use std::sync::Arc;

/// Frames a port's transmit queue holds unless [`set_tx_capacity`](super::SimNetwork::set_tx_capacity)
/// says otherwise.
pub const DEFAULT_TX_CAPACITY: usize = 64;

/// The bit a queued frame's serial carries when the frame is a CAN FD one: the queue holds a
/// header-only stand-in (its identifier, for arbitration) and the FD frame waits in the port's
/// `fd_queue`, in the same order. Classic queue entries keep their size (see the module
/// documentation of [`sim`](super)).
pub(super) const FD_SERIAL: u64 = 1 << 63;

/// The header-only classic frame standing in for `f` in a transmit queue: same identifier, so
/// the same arbitration key (an FD frame arbitrates as a data frame of its identifier).
pub(super) fn stand_in(f: &FdFrame) -> Frame {
    Frame::from_array(f.id(), [])
}

/// Counters of one bus since creation or [`reset_stats`](super::SimNetwork::reset_stats).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BusStats {
    /// Transmission attempts that finished (any outcome).
    pub attempts: u64,
    /// Attempts acknowledged by at least one receiver.
    pub delivered: u64,
    /// Attempts that reached nobody: bus down, sender cut off or powered off, no receiver.
    pub lost: u64,
    /// Attempts destroyed by a detected error (retransmitted by the sender).
    pub error_frames: u64,
    /// Attempts cut short by a partition or heal.
    pub aborted: u64,
    /// Wire bits of all finished attempts, stuffing and intermission included.
    pub busy_bits: u64,
    /// Time the bus carried those bits (summed over segments when partitioned).
    pub busy_time: Duration,
}

impl BusStats {
    /// Fraction of `window` the bus was busy (1.0 = saturated; can exceed 1 when partitioned,
    /// since segments carry frames in parallel).
    pub fn load(&self, window: Duration) -> f64 {
        if window.is_zero() {
            return 0.0;
        }
        self.busy_time.as_micros() as f64 / window.as_micros() as f64
    }
}

/// Counters of one port since creation or [`reset_stats`](super::SimNetwork::reset_stats).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PortStats {
    /// Transmission attempts started, retransmissions and babble included.
    pub tx_attempts: u64,
    /// Frames reported sent (`PortStatus::TxOk`).
    pub tx_ok: u64,
    /// Frames reported failed (`PortStatus::TxFailed`).
    pub tx_failed: u64,
    /// Times the device had to wait because this port's transmit queue was full (back-pressure:
    /// the frame is held by the driver, not lost).
    pub tx_blocked: u64,
    /// Frames handed to the device.
    pub rx: u64,
    /// Frames this port missed (reported as receive overflow).
    pub rx_dropped: u64,
    /// Frames this port received twice.
    pub rx_duplicated: u64,
    /// Frames handed to the device late.
    pub rx_delayed: u64,
    /// Frames that waited for the port's transmit latency before they could compete for the
    /// wire.
    pub tx_waited: u64,
    /// Frames delivered with a flipped data bit.
    pub rx_corrupted: u64,
    /// Error frames this port took part in (as sender or receiver).
    pub error_frames: u64,
}

/// A frame on the wire.
#[derive(Clone, Copy, Debug)]
pub(super) struct InFlight {
    pub(super) start: Instant,
    pub(super) end: Instant,
    pub(super) sender: u32,
    /// Sender's generation at start: a reboot meanwhile makes the attempt the old device's.
    pub(super) generation: u32,
    pub(super) frame: Frame,
    /// The frame's serial; none for a babbling controller's.
    pub(super) serial: Option<u64>,
    pub(super) bits: u32,
    pub(super) babble: bool,
    /// Decided at start, because an error frame lasts longer than a good one.
    pub(super) error: bool,
    /// An FD frame a classic-only receiver answered with error frames: not retransmitted.
    pub(super) refused: bool,
}

/// A part of a bus with its own wire: the whole bus, one side of a partition, or the stub of a
/// disconnected port.
#[derive(Debug, Default)]
pub(super) struct Segment {
    /// Global port indices, ascending.
    pub(super) members: Vec<u32>,
    /// `(arbitration key, port)` of every member with a frame ready: the first entry wins.
    pub(super) ready: BTreeSet<(u64, u32)>,
    pub(super) busy: Option<InFlight>,
    /// The CAN FD frame on the wire, while `busy` is one.
    pub(super) fd: Option<FdFrame>,
}

impl Segment {
    pub(super) fn insert_member(&mut self, p: u32) {
        if let Err(at) = self.members.binary_search(&p) {
            self.members.insert(at, p);
        }
    }
    pub(super) fn remove_member(&mut self, p: u32) {
        if let Ok(at) = self.members.binary_search(&p) {
            self.members.remove(at);
        }
    }
}

/// One simulated bus.
pub(super) struct Bus {
    pub(super) name: Arc<str>,
    pub(super) bitrate: u32,
    /// The data phase's bit rate of CAN FD frames with BRS.
    pub(super) data_bitrate: u32,
    /// A CAN FD bus: only FD-capable devices may be attached.
    pub(super) fd: bool,
    pub(super) up: bool,
    /// Global indices of every attached port, ascending.
    pub(super) ports: Vec<u32>,
    /// Segments `0..groups` are the partition groups (one when whole); later ones are stubs of
    /// disconnected ports.
    pub(super) segments: Vec<Segment>,
    pub(super) groups: u32,
    pub(super) faults: Option<FaultRates>,
    /// Every n-th delivered frame is lost for every receiver (0: none), and the count so far.
    pub(super) drop_every: (u32, u32),
    /// Attached ports whose own rates include detected corruption: only then does starting a
    /// frame look at every receiver.
    pub(super) detect_ports: u32,
    pub(super) stats: BusStats,
}

impl Bus {
    pub(super) fn new(name: &str, bitrate: u32, data_bitrate: Option<u32>) -> Self {
        Bus {
            name: name.into(),
            bitrate,
            data_bitrate: data_bitrate.unwrap_or(bitrate),
            fd: data_bitrate.is_some(),
            up: true,
            ports: Vec::new(),
            segments: vec![Segment::default()],
            groups: 1,
            faults: None,
            drop_every: (0, 0),
            detect_ports: 0,
            stats: BusStats::default(),
        }
    }
}

/// A port controller: transmit queue, wiring state and counters.
pub(super) struct Port {
    pub(super) dev: u32,
    /// The port number the device uses.
    pub(super) local: u32,
    pub(super) bus: u32,
    /// Partition group (0 unless listed in a partition).
    pub(super) group: u32,
    /// Segment currently wired to: `group`, or a stub while disconnected.
    pub(super) seg: u32,
    pub(super) connected: bool,
    /// False while the interface is down (socket closed).
    pub(super) iface_up: bool,
    /// Frames waiting, with their serial (see [`TxRecord::serial`](super::TxRecord)) and the
    /// instant they may compete for the wire (see
    /// [`set_port_tx_latency`](super::SimNetwork::set_port_tx_latency)).
    pub(super) queue: VecDeque<(Frame, u64, Instant)>,
    /// The CAN FD frames of `queue` (entries whose serial has [`FD_SERIAL`]), in order.
    pub(super) fd_queue: VecDeque<FdFrame>,
    /// Its device is FD-capable ([`Device::fd_capable`](crate::Device::fd_capable)).
    pub(super) fd_capable: bool,
    pub(super) capacity: usize,
    pub(super) babble: Option<Frame>,
    pub(super) transmitting: bool,
    /// Re-initialised while a frame was on the wire: that frame is not retried should its
    /// attempt fail (a controller reset drops what it was sending).
    pub(super) flushed: bool,
    /// The entry this port has in its segment's ready set.
    pub(super) ready: Option<(u32, u64)>,
    pub(super) faults: Option<FaultRates>,
    /// Every n-th frame this port would receive is lost (0: none), and the count so far.
    pub(super) drop_every: (u32, u32),
    /// Fixed receive latency (see [`set_port_latency`](super::SimNetwork::set_port_latency)).
    pub(super) latency: Duration,
    /// Fixed transmit latency (see
    /// [`set_port_tx_latency`](super::SimNetwork::set_port_tx_latency)).
    pub(super) tx_latency: Duration,
    /// When a scheduled wake-up puts the queue's head up for arbitration (its latency over).
    pub(super) wake: Option<Instant>,
    /// Frames are handed over with their wire time as receive timestamp (the default), or
    /// with the hand-over time (see [`set_port_stamps`](super::SimNetwork::set_port_stamps)).
    pub(super) stamps: bool,
    /// Its timestamp clock (see
    /// [`set_port_stamp_drift`](super::SimNetwork::set_port_stamp_drift)).
    pub(super) clock: StampClock,
    /// Deliveries scheduled for later and the due time of the last one: later frames queue
    /// behind them so a port never sees frames out of order.
    pub(super) delayed: u32,
    pub(super) delay_tail: Instant,
    /// Its transmitter reaches nobody (see
    /// [`set_port_tx_dead`](super::SimNetwork::set_port_tx_dead)).
    pub(super) tx_dead: bool,
    /// Its transmit error counter.
    pub(super) tec: u16,
    /// The level its transmit error counter is held at (0: none; see
    /// [`set_port_error_passive`](super::SimNetwork::set_port_error_passive)).
    pub(super) tec_floor: u16,
    /// Error passive after its own frame: it may not start another before this instant (the
    /// suspend-transmission time).
    pub(super) suspended: Option<Instant>,
    /// Bus-off until this instant (its automatic restart).
    pub(super) bus_off: Option<Instant>,
    /// When its next failing attempt ends (a dead transmitter with a frame to send).
    pub(super) dead_wake: Option<Instant>,
    pub(super) stats: PortStats,
}

impl Port {
    pub(super) fn new(dev: u32, local: u32, bus: u32) -> Self {
        Port {
            dev,
            local,
            bus,
            group: 0,
            seg: 0,
            connected: true,
            iface_up: true,
            queue: VecDeque::new(),
            fd_queue: VecDeque::new(),
            fd_capable: false,
            capacity: DEFAULT_TX_CAPACITY,
            babble: None,
            transmitting: false,
            flushed: false,
            ready: None,
            faults: None,
            drop_every: (0, 0),
            latency: Duration::ZERO,
            tx_latency: Duration::ZERO,
            wake: None,
            stamps: true,
            clock: StampClock::EXACT,
            delayed: 0,
            delay_tail: Instant::ZERO,
            tx_dead: false,
            tec: 0,
            tec_floor: 0,
            suspended: None,
            bus_off: None,
            dead_wake: None,
            stats: PortStats::default(),
        }
    }
    /// The frame this port would put on the wire next: a babbling controller repeats its frame
    /// and holds the queue back. `Err(due)`: the next frame's transmit latency runs until `due`.
    pub(super) fn head(&self, now: Instant) -> Result<Option<&Frame>, Instant> {
        match (&self.babble, self.queue.front()) {
            (Some(f), _) => Ok(Some(f)),
            (None, Some((_, _, due))) if *due > now => Err(*due),
            (None, q) => Ok(q.map(|(f, _, _)| f)),
        }
    }
}

/// A port's receive timestamp clock ([`SimNetwork::set_port_stamp_drift`](super::SimNetwork::set_port_stamp_drift)):
/// off by some microseconds at an instant and running some parts per million fast (negative:
/// slow) from then on. [`StampClock::default`] is exact.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StampClock {
    ppm: i32,
    since: Instant,
    offset: i64,
}

impl StampClock {
    pub(super) const EXACT: StampClock = StampClock {
        ppm: 0,
        since: Instant::ZERO,
        offset: 0,
    };

    /// Running `ppm` fast from `now` on, keeping the offset it had then; zero: exact again.
    pub(super) fn drifting(self, ppm: i32, now: Instant) -> StampClock {
        if ppm == 0 {
            return StampClock::EXACT;
        }
        StampClock {
            ppm,
            since: now,
            offset: self.offset_at(now),
        }
    }

    /// How fast it runs (parts per million; zero: exact).
    pub fn ppm(&self) -> i32 {
        self.ppm
    }

    /// When its rate last changed (`Instant::ZERO` for one never set).
    pub fn since(&self) -> Instant {
        self.since
    }

    /// How far off the clock is at `t` (µs; positive: ahead).
    pub fn offset_at(&self, t: Instant) -> i64 {
        let run = t.saturating_since(self.since).as_micros() as i128;
        let off = self.offset as i128 + run * self.ppm as i128 / 1_000_000;
        off.clamp(i64::MIN as i128, i64::MAX as i128) as i64
    }

    /// The stamp this clock gives an instant `t`.
    pub(super) fn stamp(&self, t: Instant) -> Instant {
        Instant::from_micros(t.as_micros().saturating_add_signed(self.offset_at(t)))
    }
}
