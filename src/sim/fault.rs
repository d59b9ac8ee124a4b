//! Fault injection: random per-frame faults, fixed port latency and deliberate wiring faults.

use super::bus::{Segment, StampClock};
use super::ids::{BusId, PortRef};
use super::SimNetwork;
use crate::frame::instant::Duration;
use crate::frame::Frame;
use crate::machine::{ErrorCause, PortStatus};

/// Probabilities of random faults, per frame (bus rates, for every receiver of the bus) or per
/// frame and receiving port (port rates). A bus rate and a port rate of the same kind combine as
/// independent chances.
///
/// Randomness is drawn only for kinds whose rate is above zero, so a network without faults
/// never touches the generator.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FaultRates {
    /// A receiver misses the frame (controller overflow); it gets
    /// `PortStatus::Error(ErrorCause::RxOverflow)` instead.
    pub drop: f64,
    /// A receiver gets the frame twice (the double reception real CAN allows when an error hits
    /// the last EOF bit).
    pub duplicate: f64,
    /// A receiver gets the frame late, by 1 µs to `max_delay`; frames to that port stay in order.
    pub delay: f64,
    /// Longest extra delay (at least 1 µs is used).
    pub max_delay: Duration,
    /// An error is detected during the frame: nobody receives it, every port on the segment gets
    /// `PortStatus::Error(ErrorCause::Crc)`, the sender retransmits. As a port rate: that port,
    /// when receiving, is the one to detect it (and destroys the frame for everyone).
    pub corrupt_detected: f64,
    /// One data bit flips and nobody notices: as a bus rate every receiver gets the same wrong
    /// frame, as a port rate only that one. Frames without data are left alone.
    pub corrupt_undetected: f64,
    /// As a port rate only: an error is detected during a frame *this port sends* (a ground
    /// shift or a worn transceiver at its node, whose levels the others read wrong): nobody
    /// receives it, every port on the segment gets `PortStatus::Error(ErrorCause::Crc)`, the
    /// sender retransmits. Other senders' frames on the bus are not touched.
    pub corrupt_sent: f64,
    /// As a bus rate only: an error is detected during a frame that carries at least
    /// [`long_from`](FaultRates::long_from) data bytes (reflections on a bus too long for its
    /// bit rate, a stub that grew: a disturbance that needs the frame on the wire for a while,
    /// so a one-byte heartbeat passes where an eight-byte PDO fails). As
    /// [`corrupt_detected`](FaultRates::corrupt_detected) otherwise: nobody receives it, every
    /// port gets `PortStatus::Error(ErrorCause::Crc)`, the sender retransmits.
    pub corrupt_long: f64,
    /// The data length from which [`corrupt_long`](FaultRates::corrupt_long) applies.
    pub long_from: u8,
}

impl FaultRates {
    /// No faults.
    pub const NONE: FaultRates = FaultRates {
        drop: 0.0,
        duplicate: 0.0,
        delay: 0.0,
        max_delay: Duration::ZERO,
        corrupt_detected: 0.0,
        corrupt_undetected: 0.0,
        corrupt_sent: 0.0,
        corrupt_long: 0.0,
        long_from: 0,
    };

    /// True when no fault can happen.
    pub fn is_none(&self) -> bool {
        self.drop <= 0.0
            && self.duplicate <= 0.0
            && self.delay <= 0.0
            && self.corrupt_detected <= 0.0
            && self.corrupt_undetected <= 0.0
            && self.corrupt_sent <= 0.0
            && self.corrupt_long <= 0.0
    }
    /// With drop probability `p`.
    #[must_use]
    pub fn with_drop(self, p: f64) -> Self {
        FaultRates { drop: p, ..self }
    }
    /// With duplication probability `p`.
    #[must_use]
    pub fn with_duplicate(self, p: f64) -> Self {
        FaultRates {
            duplicate: p,
            ..self
        }
    }
    /// With delay probability `p`, by up to `max`.
    #[must_use]
    pub fn with_delay(self, p: f64, max: Duration) -> Self {
        FaultRates {
            delay: p,
            max_delay: max,
            ..self
        }
    }
    /// With detected-corruption (error frame) probability `p`.
    #[must_use]
    pub fn with_corrupt_detected(self, p: f64) -> Self {
        FaultRates {
            corrupt_detected: p,
            ..self
        }
    }
    /// With probability `p` of an error destroying a frame the port sends (a port rate).
    #[must_use]
    pub fn with_corrupt_sent(self, p: f64) -> Self {
        FaultRates {
            corrupt_sent: p,
            ..self
        }
    }
    /// With probability `p` of an error destroying a frame of `from` data bytes or more (a bus
    /// rate).
    #[must_use]
    pub fn with_corrupt_long(self, p: f64, from: u8) -> Self {
        FaultRates {
            corrupt_long: p,
            long_from: from,
            ..self
        }
    }
    /// With undetected-corruption (bit flip) probability `p`.
    #[must_use]
    pub fn with_corrupt_undetected(self, p: f64) -> Self {
        FaultRates {
            corrupt_undetected: p,
            ..self
        }
    }
}

/// True with probability `p`, drawing only when the outcome is in doubt.
pub(crate) fn chance(rng: &mut fastrand::Rng, p: f64) -> bool {
    if p <= 0.0 {
        false
    } else if p >= 1.0 {
        true
    } else {
        rng.f64() < p
    }
}

/// Counts one frame against an every-n-th drop (`(n, count)`, n = 0: none); true when this
/// frame is the n-th.
pub(super) fn nth(every: &mut (u32, u32)) -> bool {
    if every.0 == 0 {
        return false;
    }
    every.1 += 1;
    if every.1 >= every.0 {
        every.1 = 0;
        true
    } else {
        false
    }
}

/// Probability that at least one of two independent chances hits.
pub(crate) fn either(a: f64, b: f64) -> f64 {
    1.0 - (1.0 - a.clamp(0.0, 1.0)) * (1.0 - b.clamp(0.0, 1.0))
}

/// The frame with one random data bit flipped, or `None` if it carries no data.
pub(crate) fn flip_bit(rng: &mut fastrand::Rng, frame: &Frame) -> Option<Frame> {
    let len = frame.data().len();
    if len == 0 {
        return None;
    }
    let bit = rng.usize(0..len * 8);
    let mut data = [0u8; 8];
    data[..len].copy_from_slice(frame.data());
    data[bit / 8] ^= 0x80 >> (bit % 8);
    Frame::new(frame.id(), &data[..len]).ok()
}

impl SimNetwork {
    /// Sets the random fault rates of a bus (applied to every frame on it).
    pub fn set_bus_faults(&mut self, bus: BusId, rates: FaultRates) {
        self.bus(bus);
        self.buses[bus.index()].faults = (!rates.is_none()).then_some(rates);
    }

    /// Every `n`-th frame delivered on the bus is lost for every receiver (each gets
    /// `PortStatus::Error(ErrorCause::RxOverflow)`, as for a random drop); 0 stops it. Unlike
    /// the random rates, nothing is drawn: the same frames are lost every run.
    pub fn drop_every_on_bus(&mut self, bus: BusId, n: u32) {
        self.bus(bus);
        self.buses[bus.index()].drop_every = (n, 0);
    }
    /// Every `n`-th frame the port would receive is lost; 0 stops it.
    pub fn drop_every(&mut self, port: PortRef, n: u32) {
        let p = self.port_index(port);
        self.ports[p].drop_every = (n, 0);
    }
    /// The random fault rates of a bus as set ([`FaultRates::NONE`] unless set).
    pub fn bus_faults(&self, bus: BusId) -> FaultRates {
        self.bus(bus).faults.unwrap_or(FaultRates::NONE)
    }
    /// The random fault rates of one receiving port as set.
    pub fn port_faults(&self, port: PortRef) -> FaultRates {
        self.ports[self.port_index(port)]
            .faults
            .unwrap_or(FaultRates::NONE)
    }
    /// Sets the random fault rates of one receiving port.
    pub fn set_port_faults(&mut self, port: PortRef, rates: FaultRates) {
        let p = self.port_index(port);
        let before = self.ports[p]
            .faults
            .is_some_and(|f| f.corrupt_detected > 0.0);
        let after = rates.corrupt_detected > 0.0;
        let bus = &mut self.buses[self.ports[p].bus as usize];
        match (before, after) {
            (false, true) => bus.detect_ports += 1,
            (true, false) => bus.detect_ports -= 1,
            _ => {}
        }
        self.ports[p].faults = (!rates.is_none()).then_some(rates);
    }

    /// Gives one receiving port a fixed latency: every frame it receives is handed to its device
    /// exactly `latency` after the frame ended on the wire (on top of any random delay), in the
    /// order the port received them, like a driver or gateway queue that runs behind. Zero
    /// removes it. Frames already on their way keep their delivery time and later ones never
    /// overtake them: after the latency is lowered, newer frames wait for the older ones and are
    /// handed over at the same instant as the last of them. Nothing is random, nothing is
    /// traced; the transmit side of the port is not affected.
    pub fn set_port_latency(&mut self, port: PortRef, latency: Duration) {
        let p = self.port_index(port);
        self.ports[p].latency = latency;
    }

    /// Whether the port hands frames to its device with their wire time as receive timestamp
    /// (`true`, the default: a controller or driver that stamps frames as they arrive, as
    /// SocketCAN's kernel timestamps do) or with the time they are handed over (`false`: a
    /// driver without timestamps, whose device sees a late frame as a late arrival).
    pub fn set_port_stamps(&mut self, port: PortRef, stamps: bool) {
        let p = self.port_index(port);
        self.ports[p].stamps = stamps;
    }

    /// Makes one port's timestamp clock run `ppm` parts per million fast (negative: slow)
    /// from now on, as two adapters stamping with their own crystals drift apart: each frame's
    /// receive timestamp is its wire time plus the offset the clock has gathered (which a new
    /// rate keeps and goes on from). Zero resynchronises the clock: its stamps are exact
    /// again, at once (a driver that steps its clock back to the host's). Nothing else
    /// changes: frames reach the device when they did. A port that hands frames over without
    /// timestamps ([`set_port_stamps`](Self::set_port_stamps)) is not affected.
    pub fn set_port_stamp_drift(&mut self, port: PortRef, ppm: i32) {
        let (p, now) = (self.port_index(port), self.now);
        self.ports[p].clock = self.ports[p].clock.drifting(ppm, now);
    }

    /// One port's receive timestamp clock, as
    /// [`set_port_stamp_drift`](Self::set_port_stamp_drift) left it.
    pub fn port_stamp_clock(&self, port: PortRef) -> StampClock {
        self.ports[self.port_index(port)].clock
    }

    /// Gives one port a fixed transmit latency: every frame its device hands it competes for the
    /// wire only `latency` later, in the order handed over (a frame never overtakes an older
    /// one of the same port), like a controller whose mailboxes wait behind traffic only it
    /// sees or a driver that batches its writes. The device learns each frame's outcome when it
    /// ends on the wire, as always. Zero removes it; frames already waiting keep their time.
    /// Counted in [`PortStats::tx_waited`](super::PortStats::tx_waited). The receive side of
    /// the port is not affected.
    pub fn set_port_tx_latency(&mut self, port: PortRef, latency: Duration) {
        let p = self.port_index(port);
        self.ports[p].tx_latency = latency;
    }

    /// The fixed transmit latency of a port (zero unless set).
    pub fn port_tx_latency(&self, port: PortRef) -> Duration {
        self.ports[self.port_index(port)].tx_latency
    }

    /// The fixed receive latency of a port (zero unless set).
    pub fn port_latency(&self, port: PortRef) -> Duration {
        self.ports[self.port_index(port)].latency
    }

    /// Cuts the bus: frames still take their wire time but reach nobody, and their senders get
    /// `TxFailed(NoAck)` when they end. Frames already on the wire are lost too.
    pub fn bus_down(&mut self, bus: BusId) {
        self.bus(bus);
        self.buses[bus.index()].up = false;
    }

    /// Repairs a cut bus.
    pub fn bus_up(&mut self, bus: BusId) {
        self.bus(bus);
        self.buses[bus.index()].up = true;
    }

    /// Whether the bus is up.
    pub fn is_bus_up(&self, bus: BusId) -> bool {
        self.bus(bus).up
    }

    /// Unplugs a port from its bus: its frames go nowhere (`TxFailed(NoAck)` after their wire
    /// time) and it receives nothing; the rest of the bus carries on. Nothing is reported, as
    /// with a cut cable.
    pub fn disconnect(&mut self, port: PortRef) {
        let p = self.port_index(port);
        if !self.ports[p].connected {
            return;
        }
        let b = self.ports[p].bus as usize;
        let old = self.ports[p].seg as usize;
        let bus = &mut self.buses[b];
        bus.segments[old].remove_member(p as u32);
        // Reuse an idle, empty stub before growing, so plugging and unplugging stays bounded.
        let groups = bus.groups as usize;
        let stub = match (groups..bus.segments.len())
            .find(|&s| bus.segments[s].members.is_empty() && bus.segments[s].busy.is_none())
        {
            Some(s) => s,
            None => {
                bus.segments.push(Segment::default());
                bus.segments.len() - 1
            }
        };
        bus.segments[stub].insert_member(p as u32);
        self.ports[p].connected = false;
        self.ports[p].seg = stub as u32;
        self.refresh_port(p);
    }

    /// Plugs a disconnected port back in (into its partition group).
    pub fn reconnect(&mut self, port: PortRef) {
        let p = self.port_index(port);
        if self.ports[p].connected {
            return;
        }
        let b = self.ports[p].bus as usize;
        let (old, group) = (self.ports[p].seg as usize, self.ports[p].group as usize);
        self.buses[b].segments[old].remove_member(p as u32);
        self.buses[b].segments[group].insert_member(p as u32);
        self.ports[p].connected = true;
        self.ports[p].seg = group as u32;
        self.refresh_port(p);
    }

    /// Whether the port is plugged in.
    pub fn is_connected(&self, port: PortRef) -> bool {
        self.ports[self.port_index(port)].connected
    }

    /// Splits the bus: each listed group of ports becomes a segment of its own, with its own
    /// arbitration and timeline; ports not listed form one more segment. Frames on the wire
    /// when the topology changes are cut short and retransmitted.
    ///
    /// # Panics
    /// If a listed port is not attached to `bus`.
    pub fn partition(&mut self, bus: BusId, groups: &[&[PortRef]]) {
        let b = bus.index();
        self.bus(bus);
        let mut assignment = Vec::new();
        for (g, group) in groups.iter().enumerate() {
            for &port in group.iter() {
                let p = self.port_index(port);
                if self.ports[p].bus as usize != b {
                    panic!("{port} is not attached to {bus}");
                }
                assignment.push((p, g as u32 + 1));
            }
        }
        self.abort_in_flight(b);
        for &p in &self.buses[b].ports {
            self.ports[p as usize].group = 0;
        }
        for (p, g) in assignment {
            self.ports[p].group = g;
        }
        self.buses[b].groups = groups.len() as u32 + 1;
        self.rebuild_segments(b);
    }

    /// Joins every partition group of the bus again.
    pub fn heal(&mut self, bus: BusId) {
        self.partition(bus, &[]);
    }

    /// Makes the port's controller babble: `frame` is permanently pending (it comes back after
    /// every transmission) and holds the port's own queue back. The device is not told about
    /// these transmissions. `None` stops it.
    pub fn babble(&mut self, port: PortRef, frame: Option<Frame>) {
        let p = self.port_index(port);
        self.ports[p].babble = frame;
        self.refresh_port(p);
    }

    /// Sets how many frames the port's transmit queue holds (default
    /// [`DEFAULT_TX_CAPACITY`](super::DEFAULT_TX_CAPACITY)). Like a driver that waits for room
    /// in the controller, the simulator stops pulling frames from a device whose next frame
    /// targets a full queue and resumes as soon as a slot frees: nothing is lost, the device's own
    /// bounded queues fill up instead.
    pub fn set_tx_capacity(&mut self, port: PortRef, capacity: usize) {
        let p = self.port_index(port);
        self.ports[p].capacity = capacity;
    }

    /// Takes the port's interface down (socket closed, interface gone): the device is told
    /// `PortStatus::Down(InterfaceDown)` now, the queue is dropped, it receives nothing and every
    /// frame it hands the port fails at once with `TxFailed(InterfaceDown)`.
    pub fn port_down(&mut self, port: PortRef) {
        let p = self.port_index(port);
        if !self.ports[p].iface_up {
            return;
        }
        self.ports[p].iface_up = false;
        self.ports[p].queue.clear();
        self.ports[p].fd_queue.clear();
        self.refresh_port(p);
        self.port_status(p, PortStatus::Down(ErrorCause::InterfaceDown));
    }

    /// Brings the port's interface back; the device is told `PortStatus::Up`.
    pub fn port_up(&mut self, port: PortRef) {
        let p = self.port_index(port);
        if self.ports[p].iface_up {
            return;
        }
        self.ports[p].iface_up = true;
        self.refresh_port(p);
        self.port_status(p, PortStatus::Up);
    }

    /// Recomputes segment membership from groups and connections after a partition or heal.
    fn rebuild_segments(&mut self, b: usize) {
        let bus = &mut self.buses[b];
        bus.segments.clear();
        bus.segments
            .resize_with(bus.groups as usize, Segment::default);
        for &p in &bus.ports {
            let port = &mut self.ports[p as usize];
            port.ready = None;
            port.seg = if port.connected {
                port.group
            } else {
                bus.segments.push(Segment::default());
                bus.segments.len() as u32 - 1
            };
            bus.segments[port.seg as usize].members.push(p);
        }
        for i in 0..self.buses[b].ports.len() {
            let p = self.buses[b].ports[i] as usize;
            self.refresh_port(p);
        }
    }
}
