//! A deterministic simulated multi-bus CAN network in virtual time.
//!
//! [`SimNetwork`] owns a virtual microsecond clock, any number of buses and any number of
//! [`Device`](crate::machine::Device)s, each port of a device attached to one bus. It drives the
//! devices exactly as a real runtime does: frames to `handle_rx`, controller reports to
//! `handle_port_status`, `handle_timeout` exactly at `poll_timeout`, and it drains
//! `poll_transmit` into the port controllers, `poll_port_request` into the simulated drivers and
//! `poll_event` into a per-device typed log ([`SimNetwork::events`]).
//!
//! # The wire
//!
//! A frame occupies its segment for [`timing::frame_duration`] (exact bit stuffing, 3-bit
//! intermission, rounded up to whole microseconds). Receivers get it, and the sender gets
//! `PortStatus::TxOk`, when it ends. Whenever a segment is idle, the lowest
//! [`Frame::arbitration_key`](crate::Frame::arbitration_key) among the heads of its ports' transmit
//! queues wins; exact ties go to the lower (device index, port). A frame reaches every other
//! powered, connected port of the segment; with nobody to acknowledge it the sender gets
//! `TxFailed(NoAck)`.
//!
//! # CAN FD
//!
//! A bus built with [`BusConfig::fd`] is a CAN FD bus with a data phase bit rate; a device
//! that says it is FD-capable ([`Device::fd_capable`](crate::Device::fd_capable)) hands CAN
//! FD frames over with [`Device::poll_transmit_fd`](crate::Device::poll_transmit_fd) and gets
//! them with [`Device::handle_rx_fd`](crate::Device::handle_rx_fd). An FD frame occupies its
//! segment for [`timing::fd_frame_duration`] (the arbitration and data phases at their bit
//! rates), arbitrates against classic frames by its identifier, meets the same faults (random
//! and every-n-th drops, undetected bit flips in its data, delays, latency, duplicates,
//! detected errors and retransmission, cut buses, disconnected ports, partitions), and appears
//! in the trace ([`TxRecord::fd`]) and its captures ([`SimNetwork::write_candump`],
//! [`SimNetwork::write_pcap`]) as an FD record.
//!
//! FD frames belong only where every node is FD-capable: a classic-only controller answers
//! one with error frames. [`SimNetwork::add_device`] refuses a classic-only device on a CAN FD
//! bus ([`SimError::ClassicOnFdBus`]), a configuration error at start. On a classic bus an FD
//! frame that a classic-only receiver hears is an error frame (its receivers get
//! `PortStatus::Error(ErrorCause::Form)`); the simulator does not retry it, the sender gets
//! `TxFailed(Form)` (a real controller would retry until it or the classic nodes went error
//! passive).
//!
//! The classic path is unchanged: a transmit queue holds classic frames as before and an FD
//! frame as a header-only stand-in (its identifier, for arbitration) whose frame waits in a
//! queue of its own; only the frame on the wire, delayed deliveries and trace records of FD
//! frames carry the FD frame (boxed where a classic record would grow).
//!
//! # Order within an instant
//!
//! Everything due at the same instant is handled in a fixed order: delayed deliveries (in the
//! order they were scheduled), then frames ending on the wire (by bus, then segment), then
//! scheduled actions ([`SimNetwork::at`], by time and insertion), then device timeouts (by device
//! index). Only then do idle segments arbitrate, so every frame that became pending at one
//! instant competes with the others. Frames queued between two `run_*` calls (through
//! [`SimNetwork::device_mut`]) arbitrate at the current instant when the simulation resumes.
//!
//! # Faults
//!
//! All random faults draw from one generator seeded by [`SimNetwork::new`], in the fixed order
//! above, so a seed reproduces a run exactly, trace and all. See [`FaultRates`] and the methods
//! [`bus_down`](SimNetwork::bus_down), [`disconnect`](SimNetwork::disconnect),
//! [`set_port_latency`](SimNetwork::set_port_latency) (a fixed receive latency, not random),
//! [`set_port_tx_latency`](SimNetwork::set_port_tx_latency) (the same for transmission: a
//! controller that sends late),
//! [`set_port_tx_dead`](SimNetwork::set_port_tx_dead) (a transmitter that reaches nobody: bit
//! errors, error passive, bus-off and its automatic restart, while the port still receives),
//! [`set_port_error_passive`](SimNetwork::set_port_error_passive) (a controller held error
//! passive: the suspend-transmission time after its frames, passive error flags),
//! [`set_bridge`](SimNetwork::set_bridge) (a CAN-to-CAN bridge that copies one bus's frames
//! onto the other, late: a device of its own on both buses),
//! [`partition`](SimNetwork::partition), [`babble`](SimNetwork::babble),
//! [`port_down`](SimNetwork::port_down) and [`power_off`](SimNetwork::power_off).
//!
//! # Example
//!
//! Two devices on two buses; each sends one frame per port every 10 ms.
//!
//! ```
//! use duocan::sim::{BusConfig, SimNetwork};
//! use duocan::{Device, Duration, Frame, Id, Instant, PortStatus};
//!
//! struct Beacon { id: u16, next: Instant, out: Vec<(usize, Frame)>, heard: u32 }
//!
//! impl Device for Beacon {
//!     type Event = Frame;
//!     fn port_count(&self) -> usize { 2 }
//!     fn handle_rx(&mut self, _: Instant, _: usize, _: &Frame) { self.heard += 1; }
//!     fn handle_port_status(&mut self, _: Instant, _: usize, _: PortStatus) {}
//!     fn handle_timeout(&mut self, now: Instant) {
//!         if now >= self.next {
//!             let f = Frame::new(Id::Standard(self.id), &[1]).unwrap();
//!             self.out.extend([(0, f), (1, f)]);
//!             self.next = now + Duration::from_millis(10);
//!         }
//!     }
//!     fn poll_transmit(&mut self) -> Option<(usize, Frame)> { self.out.pop() }
//!     fn poll_timeout(&self) -> Option<Instant> { Some(self.next) }
//!     fn poll_event(&mut self) -> Option<Frame> { None }
//! }
//!
//! let beacon = |id| Beacon { id, next: Instant::ZERO, out: Vec::new(), heard: 0 };
//! let mut sim = SimNetwork::new(1);
//! let a = sim.add_bus(BusConfig::new("can0", 500_000));
//! let b = sim.add_bus(BusConfig::new("can1", 500_000));
//! let x = sim.add_device("x", beacon(0x181), &[a, b])?;
//! let y = sim.add_device("y", beacon(0x182), &[a, b])?;
//! sim.run_until(Instant::from_millis(95));
//! // Sends at 0, 10, …, 90 ms: ten frames on each of the two buses.
//! assert_eq!(sim.device(x).heard, 20);
//! assert_eq!(sim.device(y).heard, 20);
//! assert_eq!(sim.bus_stats(a).delivered, 20);
//! # Ok::<(), duocan::sim::SimError>(())
//! ```

mod bridge;
mod bus;
mod device;
mod drive;
mod engine;
mod fault;
mod fd;
mod ids;
mod passive;
mod rx;
mod sched;
pub mod timing;
mod trace;
mod tx_dead;

#[cfg(test)]
mod tests;

pub use bridge::{Bridge, BridgeConfig, BridgeDirection, BridgeStats, Bridged};
pub use bus::{BusStats, PortStats, StampClock, DEFAULT_TX_CAPACITY};

/// Events each device's log holds while recording is off, unless
/// [`SimNetwork::set_event_capacity`] says otherwise.
pub const DEFAULT_EVENT_CAPACITY: usize = 16_384;
pub use fault::FaultRates;
pub(crate) use fault::{chance, either, flip_bit};
pub use ids::{BusConfig, BusId, DevId, DeviceRef, PortRef, SimError};
pub use trace::{RxFault, RxRecord, TraceRecord, TxOutcome, TxRecord};

use crate::frame::instant::{Duration, Instant};
use crate::frame::{FdFrame, Frame};
use crate::machine::PortStatus;
use bus::{Bus, Port};
use core::cmp::Reverse;
use core::fmt;
use device::DeviceState;
use sched::{Action, DelayedRx, Timed};
use std::collections::BinaryHeap;

/// A simulated CAN network: buses, devices, a virtual clock and a fault injector.
pub struct SimNetwork {
    seed: u64,
    now: Instant,
    rng: fastrand::Rng,
    buses: Vec<Bus>,
    devices: Vec<DeviceState>,
    ports: Vec<Port>,
    /// `(deadline, device)`; entries that no longer match the device's deadline are skipped.
    deadlines: BinaryHeap<Reverse<(Instant, u32)>>,
    delayed: BinaryHeap<Timed<DelayedRx>>,
    actions: BinaryHeap<Timed<Action>>,
    seq: u64,
    /// Devices changed through `device_mut` (or powered on, added, replaced) since they were
    /// last driven.
    touched: Vec<u32>,
    /// Devices holding a frame whose port queue just freed a slot.
    refill: Vec<u32>,
    trace: Vec<TraceRecord>,
    recording: bool,
    /// Most events a device's log holds while recording is off.
    event_capacity: usize,
    /// Scratch buffers reused on the frame path.
    statuses: Vec<(usize, PortStatus)>,
    receivers: Vec<u32>,
    in_action: bool,
    rx_hook: Option<RxHook>,
    /// The bridge's device index ([`SimNetwork::set_bridge`]).
    bridge: Option<u32>,
}

/// A frame handed to a device's port, as the receive hook sees it
/// ([`SimNetwork::set_rx_hook`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RxNote {
    /// When the frame ended on the wire (its receive timestamp).
    pub wire: Instant,
    /// The receiving port.
    pub receiver: PortRef,
    /// The sending port.
    pub sender: PortRef,
    /// The frame's serial among its sender's (see [`TxRecord::serial`]); `None` for a
    /// babbling controller's frames.
    pub serial: Option<u64>,
    /// The frame as received; for a CAN FD frame its identifier with no data, the frame
    /// itself being in `fd`.
    pub frame: Frame,
    /// The CAN FD frame as received, if it is one.
    pub fd: Option<FdFrame>,
    /// The frame is a bridge's copy ([`SimNetwork::set_bridge`]; `sender` is the bridge's
    /// port): where the frame it copied came from.
    pub bridged: Option<Bridged>,
}

/// What [`SimNetwork::set_rx_hook`] takes.
pub type RxHook = Box<dyn FnMut(&RxNote)>;

impl SimNetwork {
    /// An empty network at time zero; `seed` decides every random fault.
    pub fn new(seed: u64) -> Self {
        SimNetwork {
            seed,
            now: Instant::ZERO,
            rng: fastrand::Rng::with_seed(seed),
            buses: Vec::new(),
            devices: Vec::new(),
            ports: Vec::new(),
            deadlines: BinaryHeap::new(),
            delayed: BinaryHeap::new(),
            actions: BinaryHeap::new(),
            seq: 0,
            touched: Vec::new(),
            refill: Vec::new(),
            trace: Vec::new(),
            recording: true,
            event_capacity: DEFAULT_EVENT_CAPACITY,
            statuses: Vec::new(),
            receivers: Vec::new(),
            in_action: false,
            rx_hook: None,
            bridge: None,
        }
    }

    /// How many frames the simulator has taken from `dev` so far (across its replacements):
    /// the serial its next frame gets (see [`TxRecord::serial`]).
    pub fn frames_taken(&self, dev: impl Into<DeviceRef>) -> u64 {
        self.devices[dev.into().index()].pulled
    }

    /// Calls `hook` for every frame handed to a device's port, just before the device gets it
    /// (`None` removes it): which transmission of which sender each copy is, for a test's
    /// oracle. Unlike the trace, it keeps nothing.
    pub fn set_rx_hook(&mut self, hook: Option<RxHook>) {
        self.rx_hook = hook;
    }

    /// The random seed the network was created with.
    pub fn seed(&self) -> u64 {
        self.seed
    }

    /// Adds a bus.
    pub fn add_bus(&mut self, config: BusConfig) -> BusId {
        let id = BusId(self.buses.len() as u32);
        self.buses
            .push(Bus::new(&config.name, config.bitrate, config.data_bitrate));
        id
    }

    /// Number of buses.
    pub fn bus_count(&self) -> usize {
        self.buses.len()
    }

    /// The bus's name.
    ///
    /// # Panics
    /// If `bus` is not a bus of this simulation (as for every method taking a handle).
    pub fn bus_name(&self, bus: BusId) -> &str {
        &self.bus(bus).name
    }

    /// The bus's bit rate.
    pub fn bitrate(&self, bus: BusId) -> u32 {
        self.bus(bus).bitrate
    }

    /// The bus's data phase bit rate for CAN FD frames with BRS (its nominal bit rate on a
    /// bus without one).
    pub fn data_bitrate(&self, bus: BusId) -> u32 {
        self.bus(bus).data_bitrate
    }

    /// Whether the bus is a CAN FD bus ([`BusConfig::fd`]).
    pub fn is_fd(&self, bus: BusId) -> bool {
        self.bus(bus).fd
    }

    // ----- time -----

    /// The current virtual time.
    pub fn now(&self) -> Instant {
        self.now
    }

    /// Processes everything due up to and including `t`, then sets the clock to `t` (never
    /// backwards). Does nothing when called from a scheduled action.
    pub fn run_until(&mut self, t: Instant) {
        if self.in_action {
            return;
        }
        self.settle();
        while let Some(next) = self.next_time() {
            if next > t {
                break;
            }
            self.process_instant(next);
        }
        self.now = self.now.max(t);
    }

    /// Runs for `d` of virtual time.
    pub fn run_for(&mut self, d: Duration) {
        self.run_until(self.now + d);
    }

    /// Processes the next instant that has work and returns it; `None` when nothing will ever
    /// happen again (no frame on a wire, no deadline, no action, no delayed delivery).
    pub fn step(&mut self) -> Option<Instant> {
        if self.in_action {
            return None;
        }
        self.settle();
        let t = self.next_time()?;
        self.process_instant(t);
        Some(t)
    }

    /// Runs `action` when the clock reaches `t` (at the current instant if `t` is past).
    /// Actions due at the same instant run in the order they were scheduled, after that
    /// instant's frame deliveries and before its device timeouts. An action may change devices,
    /// inject faults and schedule more actions, but not advance time.
    pub fn at(&mut self, t: Instant, action: impl FnOnce(&mut SimNetwork) + 'static) {
        let seq = self.next_seq();
        self.actions.push(Timed {
            at: t.max(self.now),
            seq,
            item: Box::new(action),
        });
    }

    /// Runs `action` after `d` from now.
    pub fn after(&mut self, d: Duration, action: impl FnOnce(&mut SimNetwork) + 'static) {
        self.at(self.now + d, action);
    }

    // ----- trace -----

    /// Every recorded transmission attempt and fault, in the order they happened.
    pub fn trace(&self) -> &[TraceRecord] {
        &self.trace
    }

    /// Takes the trace out, leaving it empty.
    pub fn take_trace(&mut self) -> Vec<TraceRecord> {
        std::mem::take(&mut self.trace)
    }

    /// Empties the trace.
    pub fn clear_trace(&mut self) {
        self.trace.clear();
    }

    /// Switches recording on or off (on by default); counters keep counting either way.
    ///
    /// Recording keeps the whole history: every transmission in the trace and every device
    /// event in its log. Off, nothing goes to the trace and each device's event log holds at
    /// most [`DEFAULT_EVENT_CAPACITY`] events (see [`set_event_capacity`](Self::set_event_capacity))
    /// until [`take_events`](Self::take_events) empties it; the rest are dropped and counted
    /// ([`events_dropped`](Self::events_dropped)), so memory stays fixed however long the run.
    pub fn set_recording(&mut self, on: bool) {
        self.recording = on;
    }

    /// Most events each device's log holds while recording is off.
    pub fn set_event_capacity(&mut self, capacity: usize) {
        self.event_capacity = capacity;
    }

    // ----- counters -----

    /// Counters of a bus.
    pub fn bus_stats(&self, bus: BusId) -> &BusStats {
        &self.bus(bus).stats
    }

    /// Fraction of the time since zero the bus was busy (see [`BusStats::load`]).
    pub fn bus_load(&self, bus: BusId) -> f64 {
        self.bus(bus)
            .stats
            .load(self.now.saturating_since(Instant::ZERO))
    }

    /// Counters of a port.
    pub fn port_stats(&self, port: PortRef) -> &PortStats {
        &self.ports[self.port_index(port)].stats
    }

    /// Frames waiting in a port's transmit queue (not counting one on the wire).
    pub fn tx_queue_len(&self, port: PortRef) -> usize {
        self.ports[self.port_index(port)].queue.len()
    }

    /// Zeroes every bus and port counter.
    pub fn reset_stats(&mut self) {
        for b in &mut self.buses {
            b.stats = BusStats::default();
        }
        for p in &mut self.ports {
            p.stats = PortStats::default();
        }
    }

    // ----- helpers shared by the submodules -----

    fn next_seq(&mut self) -> u64 {
        self.seq += 1;
        self.seq
    }

    fn bus(&self, bus: BusId) -> &Bus {
        match self.buses.get(bus.index()) {
            Some(b) => b,
            None => panic!("{bus} is not a bus of this simulation"),
        }
    }

    fn device_state(&self, dev: DeviceRef) -> &DeviceState {
        match self.devices.get(dev.index()) {
            Some(d) => d,
            None => panic!("{dev} is not a device of this simulation"),
        }
    }

    fn port_index(&self, port: PortRef) -> usize {
        let d = self.device_state(port.device);
        if port.port >= d.ports as usize {
            panic!("{port}: {:?} has {} ports", d.name, d.ports);
        }
        d.first_port as usize + port.port
    }

    pub(super) fn port_ref(&self, p: usize) -> PortRef {
        let port = &self.ports[p];
        DeviceRef(port.dev).port(port.local as usize)
    }

    fn record(&mut self, r: impl FnOnce() -> TraceRecord) {
        if self.recording {
            self.trace.push(r());
        }
    }
}

impl fmt::Debug for SimNetwork {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("SimNetwork")
            .field("seed", &self.seed)
            .field("now", &self.now)
            .field(
                "buses",
                &self.buses.iter().map(|b| &*b.name).collect::<Vec<_>>(),
            )
            .field(
                "devices",
                &self.devices.iter().map(|d| &*d.name).collect::<Vec<_>>(),
            )
            .field("trace_len", &self.trace.len())
            .finish_non_exhaustive()
    }
}
