//! The fault classes a plant suffers, each applied at an instant for a while, and a seeded
//! generator that composes them over time, in sequence and overlapping.

use crate::foreign::FOREIGN;
use crate::plant::*;
use crate::run::Run;
use duocan::sim::{FaultRates, PortRef};
use duocan::{Device, Duration, Frame, Id, Instant, NmtState, PortStatus};
use duocan_redundancy::supervisor::flying_master::MasterRole;
use std::collections::BTreeMap;

/// A fault class and its parameters.
#[derive(Clone, Copy, Debug)]
pub enum Fault {
    /// Bus `bus` cut for `dur`.
    Cut { bus: usize, dur: Duration },
    /// Bus `first` cut for `dur`; the other bus cut from `dur − overlap` after (overlap
    /// negative: a gap; zero: at the instant the first is repaired) for `second`.
    Sequence {
        first: usize,
        dur: Duration,
        overlap: i64,
        second: Duration,
    },
    /// Bus `bus` down and up every `half` for `dur`.
    Flap {
        bus: usize,
        half: Duration,
        dur: Duration,
    },
    /// A device's port hands its frames over late: a fixed `lag` for `dur`.
    Lag {
        node: u8,
        port: usize,
        lag: Duration,
        dur: Duration,
    },
    /// The same, the lag growing by a millisecond every `step` up to `top` and back.
    GrowingLag {
        node: u8,
        port: usize,
        top: u64,
        step: Duration,
    },
    /// The same, switching between 0 and `lag` every `every`, `times` times.
    SwitchingLag {
        node: u8,
        port: usize,
        lag: Duration,
        every: Duration,
        times: u32,
    },
    /// A board's port babbles for `dur`.
    Babble {
        node: u8,
        port: usize,
        dur: Duration,
    },
    /// A board's port unplugged for `dur`.
    Unplug {
        node: u8,
        port: usize,
        dur: Duration,
    },
    /// A pair's board dies (power off) and an impostor beats its heartbeat on `bus` for `dur`;
    /// then the board comes back.
    Impostor { node: u8, bus: usize, dur: Duration },
    /// A second device with a live board's node-ID beats its heartbeat (saying `state`) every
    /// `period` on both buses for `dur` (a spare configured with the same node-ID, plugged in
    /// by mistake: operational at the board's period, or still pre-operational or stopped, or
    /// configured with twice the period).
    Duplicate {
        node: u8,
        dur: Duration,
        state: NmtState,
        period: Duration,
    },
    /// A board puts itself in `state` (its application, its error behaviour).
    Stops { node: u8, state: NmtState },
    /// A board dies for `dur`, then boots again.
    BoardDies { node: u8, dur: Duration },
    /// A board in a boot loop (a brownout, a watchdog that fires before its application is
    /// up): `times` times, it is reset (off for `off`) and boots again, `every` apart.
    BootLoop {
        node: u8,
        every: Duration,
        off: Duration,
        times: u32,
    },
    /// A master dies for `dur`, then boots again.
    MasterDies { id: u8, dur: Duration },
    /// A master in a boot loop (its supply browning out, a watchdog firing during the
    /// negotiation): `times` times, it is off for `off` and boots again, `every` apart; each
    /// boot restarts its flying-master negotiation.
    MasterBootLoop {
        id: u8,
        every: Duration,
        off: Duration,
        times: u32,
    },
    /// A master's clock steps back by `by`.
    StepBack { id: u8, by: Duration },
    /// A master's clock jumps ahead by `by`.
    JumpAhead { id: u8, by: Duration },
    /// A device's timer clock runs `ppm` parts per million fast (negative: slow) for `dur`, then
    /// right again, keeping what it gained or lost (a crystal off its rate, a virtual machine
    /// whose clock is throttled): its heartbeats, SYNC, consumer times and negotiation all
    /// stretch or shrink together, unnoticed by the device.
    ClockRate { node: u8, ppm: i32, dur: Duration },
    /// A device's transceiver on `port` receives but cannot send for `dur` (TXD stuck
    /// recessive, a broken TX line): its controller's every attempt is a bit error, error
    /// passive, bus-off, restarted, and again (see [`crate::tx_dead`]); nothing it sends
    /// reaches that bus.
    TxDead {
        node: u8,
        port: usize,
        dur: Duration,
    },
    /// Noise on bus `bus` for `dur`: a frame is hit by an error (every port on the bus sees the
    /// error frame, nobody receives it, its sender sends it again) with probability
    /// `permille`/1000: retransmissions, their delays, and a stream of error reports.
    Noise {
        bus: usize,
        permille: u16,
        dur: Duration,
    },
    /// A bus whose termination degrades (a resistor drifting, a connector corroding, a stub
    /// that grew): errors hit its frames at a rate that climbs in ten steps over `ramp` from
    /// nothing to `permille`/1000, stays there for `hold`, and ends at once (repaired). Slow
    /// where [`Fault::Noise`] is sudden: for a long while the bus works, its frames later and
    /// later by their retransmissions, every port on it reporting errors, none failing.
    Degrading {
        bus: usize,
        permille: u16,
        ramp: Duration,
        hold: Duration,
    },
    /// A device's controller on `port` sends late for `dur`: every frame it is handed competes
    /// for the wire only `delay` later (mailboxes behind traffic only it sees, a driver that
    /// batches), while its twin on the other bus leaves on time.
    SlowTx {
        node: u8,
        port: usize,
        delay: Duration,
        dur: Duration,
    },
    /// A device whose writes to its two ports drift apart for `dur` (its two port-writer
    /// tasks scheduled apart on a loaded CPU): every frame it hands `port` competes for the
    /// wire a varying delay later, drawn from `load` in bursts ([`drift_profile`]): delays
    /// that grow and shrink (up to 80 ms, often past the skew window), and holds in which the
    /// port keeps every frame for up to 80 ms and then flushes the burst at once, while the
    /// other port sends on time (so the two buses carry its frames, and other senders' frames
    /// around them, in different orders). Each port keeps its own order.
    TxDrift {
        node: u8,
        port: usize,
        dur: Duration,
        load: u64,
    },
    /// A device's controller on `port` runs at the wrong bit rate for `dur` (a board swapped
    /// in with a misconfigured controller): it decodes nothing there and nothing it sends is a
    /// frame to the others (so it is cut off that bus), and while error-active it flags every
    /// frame on the bus as an error: its error counters take it passive, its own garbled
    /// attempts take it bus-off, it recovers and starts again — modelled as bursts of
    /// [`WRONG_RATE_BURST`] in every [`WRONG_RATE_CYCLE`] in which every frame on that bus is
    /// destroyed and sent again, a delay for every sender's copies there at once.
    WrongBitRate {
        node: u8,
        port: usize,
        dur: Duration,
    },
    /// A device's port stamps the frames it receives with a clock `ppm` parts per million off
    /// for `dur`, then resynchronised (two adapters each stamping with its own crystal: the
    /// skew between twins grows for ever; minutes of a real drift compressed into seconds).
    /// Frames reach the device when they did; only their stamps move.
    Drift {
        node: u8,
        port: usize,
        ppm: i32,
        dur: Duration,
    },
    /// A device's controller on `port` overruns for `dur`: it misses a frame with probability
    /// `permille`/1000 (and reports the overflow), the other devices get it.
    Overrun {
        node: u8,
        port: usize,
        permille: u16,
        dur: Duration,
    },
    /// A ground shift at a device's transceiver on `port` (a return path through the shield,
    /// a corroded ground pin): the others read *its* frames wrong, so an error destroys each
    /// frame it sends there with probability `permille`/1000, and it sends it again; every
    /// other sender's frames on that bus pass. It comes and goes with that node's load: on for
    /// `every`, off for `every`, for `dur`. The port's errors are the bus's to every
    /// receiver, while the bus is fine for everybody else.
    GroundShift {
        node: u8,
        port: usize,
        permille: u16,
        every: Duration,
        dur: Duration,
    },
    /// The application gives a board a new heartbeat producer time (`ms`) through the active
    /// master's SDO client, as CiA 301 allows at run time: the board beats at once at the new
    /// period; the consumer times stay (50 ms). Until its next boot, when its master
    /// configures it again (20 ms).
    ProducerTime { node: u8, ms: u16 },
    /// Reflections on `bus` (a bus too long for its bit rate, a stub that grew): a detected
    /// error destroys each frame of `from` data bytes or more there with probability
    /// `permille`/1000, and its sender sends it again, for `dur`; shorter frames pass. A
    /// one-byte heartbeat gets through where an eight-byte PDO or SDO frame fails: port
    /// health sees a bus that works while what the application sends waits behind
    /// retransmissions (at 1000 per mille its sender goes error passive, then bus-off).
    LongFrames {
        bus: usize,
        permille: u16,
        from: u8,
        dur: Duration,
    },
    /// A marginal transceiver on `port` of a board or a master: its controller's transmit
    /// error counter held at `tec` (128 to 255: error passive, short of bus-off) for `dur`,
    /// then counting down by one per frame sent (see
    /// [`duocan::sim::SimNetwork::set_port_error_passive`]). It still sends and receives
    /// every frame, but after each of its own it waits the suspend-transmission time (8 bit
    /// times), so it loses the bus to every frame queued meanwhile, whatever its identifier;
    /// its controller reports error passive.
    ErrorPassive {
        node: u8,
        port: usize,
        tec: u16,
        dur: Duration,
    },
    /// A bridge loop: a misconfigured CAN-to-CAN gateway or diagnostic repeater copies the
    /// frames it receives on one bus onto the other `delay` later (`way` 0: bus 1 to bus 2, 1:
    /// bus 2 to bus 1, 2: both ways, never a frame it sent itself), those of `ids` only (raw,
    /// both ends included; `None`: all), holding at most `queue` (more are dropped), for `dur`
    /// (see [`duocan::sim::SimNetwork::set_bridge`]). The receiving bus carries many frames
    /// twice, its own copy and the bridged one, and a frame of a node cut from it still
    /// appears there.
    Bridge {
        way: u8,
        delay: Duration,
        ids: Option<(u32, u32)>,
        queue: usize,
        dur: Duration,
    },
}

impl Fault {
    /// The class, for the coverage report.
    pub fn class(&self) -> &'static str {
        match self {
            Fault::Cut { .. } => "bus cut",
            Fault::Sequence { overlap, .. } if *overlap == 0 => "buses in sequence, no overlap",
            Fault::Sequence { overlap, .. } if *overlap > 0 => "buses in sequence, overlapping",
            Fault::Sequence { .. } => "buses in sequence, with a gap",
            Fault::Flap { .. } => "flapping bus",
            Fault::Lag { .. } => "fixed lag",
            Fault::GrowingLag { .. } => "growing lag",
            Fault::SwitchingLag { .. } => "switching lag",
            Fault::Babble { .. } => "babbling port",
            Fault::Unplug { .. } => "port unplugged",
            Fault::Impostor { .. } => "impostor heartbeat",
            Fault::Stops { .. } => "board stops by itself",
            Fault::BoardDies { .. } => "board dies",
            Fault::BootLoop { .. } => "board in a boot loop",
            Fault::MasterDies { .. } => "master dies",
            Fault::MasterBootLoop { .. } => "master in a boot loop",
            Fault::StepBack { .. } => "clock step back",
            Fault::JumpAhead { .. } => "clock jump ahead",
            Fault::ClockRate { .. } => "clock at a wrong rate",
            Fault::TxDead { .. } => "transceiver that cannot send",
            Fault::Noise { .. } => "noisy bus",
            Fault::Degrading { .. } => "degrading bus",
            Fault::GroundShift { .. } => "ground shift at one sender",
            Fault::ProducerTime { .. } => "producer time changed at run time",
            Fault::LongFrames { .. } => "long frames lost on one bus",
            Fault::ErrorPassive { .. } => "controller stuck error passive",
            Fault::Bridge { .. } => "bridge loop between the buses",
            Fault::Overrun { .. } => "controller overrun",
            Fault::SlowTx { .. } => "slow transmitter",
            Fault::TxDrift { .. } => "port writes drifting apart",
            Fault::Duplicate { state, period, .. }
                if *state != NmtState::Operational || *period != SLAVE_HB =>
            {
                "duplicate node-ID, another state or period"
            }
            Fault::Duplicate { .. } => "duplicate node-ID of a live board",
            Fault::WrongBitRate { .. } => "node at the wrong bit rate",
            Fault::Drift { .. } => "drifting receive clock",
        }
    }

    /// How long it lasts from its start (its effects may last longer).
    pub fn span(&self) -> Duration {
        let ms = Duration::from_millis;
        match *self {
            Fault::Cut { dur, .. }
            | Fault::Flap { dur, .. }
            | Fault::Lag { dur, .. }
            | Fault::Babble { dur, .. }
            | Fault::Unplug { dur, .. }
            | Fault::Impostor { dur, .. }
            | Fault::BoardDies { dur, .. }
            | Fault::MasterDies { dur, .. }
            | Fault::Noise { dur, .. }
            | Fault::Overrun { dur, .. }
            | Fault::SlowTx { dur, .. }
            | Fault::TxDrift { dur, .. }
            | Fault::Duplicate { dur, .. }
            | Fault::WrongBitRate { dur, .. }
            | Fault::Drift { dur, .. }
            | Fault::ClockRate { dur, .. }
            | Fault::GroundShift { dur, .. }
            | Fault::LongFrames { dur, .. }
            | Fault::ErrorPassive { dur, .. }
            | Fault::Bridge { dur, .. }
            | Fault::TxDead { dur, .. } => dur,
            Fault::Sequence {
                dur,
                overlap,
                second,
                ..
            } => {
                Duration::from_micros((dur.as_micros() as i64 - overlap * 1_000).max(0) as u64)
                    + second
            }
            Fault::GrowingLag { top, step, .. } => step.saturating_mul(2 * top),
            Fault::Degrading { ramp, hold, .. } => ramp + hold,
            Fault::BootLoop { every, times, .. } | Fault::MasterBootLoop { every, times, .. } => {
                every.saturating_mul(times as u64)
            }
            Fault::SwitchingLag { every, times, .. } => every.saturating_mul(times as u64),
            Fault::Stops { .. }
            | Fault::StepBack { .. }
            | Fault::JumpAhead { .. }
            | Fault::ProducerTime { .. } => ms(0),
        }
    }

    /// Whether it takes a connection away (at most one such at a time, so that every two devices
    /// keep a bus between them, except what a sequence with overlap does on purpose).
    pub fn connectivity(&self) -> bool {
        matches!(
            self,
            Fault::Cut { .. }
                | Fault::Sequence { .. }
                | Fault::Flap { .. }
                | Fault::Babble { .. }
                | Fault::Unplug { .. }
                | Fault::Impostor { .. }
                | Fault::Noise { .. }
                | Fault::Degrading { .. }
                | Fault::GroundShift { .. }
                | Fault::LongFrames { .. }
                | Fault::Overrun { .. }
                | Fault::SlowTx { .. }
                | Fault::TxDrift { .. }
                | Fault::WrongBitRate { .. }
                | Fault::TxDead { .. }
        )
    }
}

/// Device `node`'s port `port` (a master's id, or a slave's node-ID).
pub fn port_of(run: &Run, node: u8, port: usize) -> PortRef {
    if node == STRONG || node == WEAK {
        run.plant.master(node).port(port)
    } else if let Some((d, _)) = run.plant.foreign.filter(|_| node == FOREIGN) {
        d.port(port)
    } else {
        run.plant.slave(node).0.port(port)
    }
}

pub fn dev_index(run: &Run, node: u8) -> usize {
    run.timeline
        .devs
        .iter()
        .position(|d| d.node_id == node)
        .unwrap()
}

/// The bus device `node`'s port `port` is cabled to, and the other way round: its port on bus
/// `port` (crossed cabling swaps them).
pub fn bus_of(run: &Run, node: u8, port: usize) -> usize {
    run.timeline.devs[dev_index(run, node)].port(port)
}

fn cut(run: &mut Run, bus: usize, down: bool) {
    let (t, b) = (run.now(), run.plant.buses[bus]);
    if down {
        run.plant.sim.bus_down(b);
        run.timeline.cut[bus].start(t);
    } else {
        run.plant.sim.bus_up(b);
        run.timeline.cut[bus].end(t);
    }
}

fn set_lag(run: &mut Run, node: u8, port: usize, lag: Duration) {
    let p = port_of(run, node, port);
    run.plant.sim.set_port_latency(p, lag);
    let (t, d) = (run.now(), dev_index(run, node));
    run.timeline.devs[d].lags[port].push((t, lag));
    let slow = &mut run.timeline.devs[d].slow[port];
    if lag > crate::timeline::LAG_SLACK {
        slow.start(t);
    } else {
        slow.end(t);
    }
}

/// A device that beats `node`'s heartbeat every `period` on each of its ports (one bus, or
/// both).
pub struct Impostor {
    frame: Frame,
    period: Duration,
    next: Option<Instant>,
    ports: usize,
    out: heapless::Deque<usize, 2>,
}

impl Device for Impostor {
    type Event = ();
    fn port_count(&self) -> usize {
        self.ports
    }
    fn handle_rx(&mut self, _: Instant, _: usize, _: &Frame) {}
    fn handle_port_status(&mut self, _: Instant, _: usize, _: PortStatus) {}
    fn handle_timeout(&mut self, now: Instant) {
        while let Some(t) = self.next.filter(|t| *t <= now) {
            self.out.clear();
            for p in 0..self.ports {
                let _ = self.out.push_back(p);
            }
            self.next = Some(t + self.period);
        }
    }
    fn poll_transmit(&mut self) -> Option<(usize, Frame)> {
        self.out.pop_front().map(|p| (p, self.frame))
    }
    fn poll_timeout(&self) -> Option<Instant> {
        self.next
    }
    fn poll_event(&mut self) -> Option<()> {
        None
    }
}

/// Holds a fault for `dur`: `hold(run, true)` now, `hold(run, false)` when it ends (each sets
/// the simulator and the timeline's spans alike).
fn for_a_while(run: &mut Run, dur: Duration, hold: impl Fn(&mut Run, bool) + 'static) {
    hold(run, true);
    let end = run.now() + dur;
    run.at(end, move |r| hold(r, false));
}

/// Unplugs `node`'s `port` for `dur` (`noisy`: its bus has error frames meanwhile).
fn unplug(run: &mut Run, node: u8, port: usize, dur: Duration, noisy: bool) {
    let p = port_of(run, node, port);
    let d = dev_index(run, node);
    let bus = bus_of(run, node, port);
    for_a_while(run, dur, move |r, on| {
        if on {
            r.plant.sim.disconnect(p);
        } else {
            r.plant.sim.reconnect(p);
        }
        let t = r.now();
        r.timeline.devs[d].unplugged[port].set(t, on);
        if noisy {
            r.timeline.noisy[bus].set(t, on);
        }
    });
}

/// Applies `f` from now on (its end scheduled).
pub fn apply(run: &mut Run, f: Fault) {
    let now = run.now();
    match f {
        Fault::Noise { bus, permille, dur } => {
            let b = run.plant.buses[bus];
            let rates = FaultRates::NONE.with_corrupt_detected(f64::from(permille) / 1000.0);
            for_a_while(run, dur, move |r, on| {
                let rates = if on { rates } else { FaultRates::NONE };
                r.plant.sim.set_bus_faults(b, rates);
                let t = r.now();
                r.timeline.noisy[bus].set(t, on);
            });
        }
        Fault::ErrorPassive {
            node,
            port,
            tec,
            dur,
        } => {
            let p = port_of(run, node, port);
            for_a_while(run, dur, move |r, on| {
                r.plant.sim.set_port_error_passive(p, on.then_some(tec));
            });
        }
        Fault::Bridge {
            way,
            delay,
            ids,
            queue,
            dur,
        } => {
            use duocan::sim::{BridgeConfig, BridgeDirection};
            let [b1, b2] = run.plant.buses;
            let direction = match way {
                0 => BridgeDirection::FirstToSecond,
                1 => BridgeDirection::SecondToFirst,
                _ => BridgeDirection::Both,
            };
            let config = BridgeConfig {
                direction,
                delay,
                ids,
                queue,
            };
            for_a_while(run, dur, move |r, on| {
                if on {
                    r.plant.sim.set_bridge(b1, b2, config);
                } else {
                    r.plant.sim.clear_bridge();
                }
            });
        }
        Fault::LongFrames {
            bus,
            permille,
            from,
            dur,
        } => {
            let b = run.plant.buses[bus];
            let rates = FaultRates::NONE.with_corrupt_long(f64::from(permille) / 1000.0, from);
            for_a_while(run, dur, move |r, on| {
                let rates = if on { rates } else { FaultRates::NONE };
                r.plant.sim.set_bus_faults(b, rates);
                let t = r.now();
                r.timeline.noisy[bus].set(t, on);
            });
        }
        Fault::Degrading {
            bus,
            permille,
            ramp,
            hold,
        } => {
            let b = run.plant.buses[bus];
            run.timeline.noisy[bus].set(now, true);
            for step in 1..=10u32 {
                let rate = f64::from(permille) * f64::from(step) / 10_000.0;
                let at = Duration::from_micros(ramp.as_micros() * u64::from(step - 1) / 10);
                run.at(now + at, move |r| {
                    r.plant
                        .sim
                        .set_bus_faults(b, FaultRates::NONE.with_corrupt_detected(rate));
                });
            }
            run.at(now + ramp + hold, move |r| {
                r.plant.sim.set_bus_faults(b, FaultRates::NONE);
                let t = r.now();
                r.timeline.noisy[bus].set(t, false);
            });
        }
        Fault::Drift {
            node,
            port,
            ppm,
            dur,
        } => {
            let (p, d) = (port_of(run, node, port), dev_index(run, node));
            let drift = move |r: &mut Run, ppm: i32| {
                r.plant.sim.set_port_stamp_drift(p, ppm);
                let clock = r.plant.sim.port_stamp_clock(p);
                r.plant.oracle.borrow_mut().drift(d, port, clock);
            };
            drift(run, ppm);
            run.at(now + dur, move |r| drift(r, 0));
        }
        Fault::WrongBitRate { node, port, dur } => {
            // It decodes nothing there and nothing it sends is a frame: off that bus.
            unplug(run, node, port, dur, true);
            let b = run.plant.buses[bus_of(run, node, port)];
            // Error-active bursts: every frame on the bus flagged (as the bus's rate: the
            // simulator's port rate is a receiver's, and this controller receives nothing).
            let flags = FaultRates::NONE.with_corrupt_detected(1.0);
            let end = now + dur;
            let mut t = now;
            while t < end {
                run.at(t, move |r| r.plant.sim.set_bus_faults(b, flags));
                let off = (t + WRONG_RATE_BURST).min(end);
                run.at(off, move |r| {
                    r.plant.sim.set_bus_faults(b, FaultRates::NONE)
                });
                t += WRONG_RATE_CYCLE;
            }
        }
        Fault::Overrun {
            node,
            port,
            permille,
            dur,
        } => {
            let p = port_of(run, node, port);
            let d = dev_index(run, node);
            let rates = FaultRates::NONE.with_drop(f64::from(permille) / 1000.0);
            for_a_while(run, dur, move |r, on| {
                let rates = if on { rates } else { FaultRates::NONE };
                r.plant.sim.set_port_faults(p, rates);
                let t = r.now();
                r.timeline.devs[d].overrun[port].set(t, on);
            });
        }
        Fault::GroundShift {
            node,
            port,
            permille,
            every,
            dur,
        } => {
            let p = port_of(run, node, port);
            let d = dev_index(run, node);
            let rates = FaultRates::NONE.with_corrupt_sent(f64::from(permille) / 1000.0);
            let times = (dur.as_micros() / every.as_micros().max(1)).max(1);
            for k in 0..=times {
                let on = k % 2 == 0 && k < times;
                run.at(now + every.saturating_mul(k), move |r| {
                    r.plant
                        .sim
                        .set_port_faults(p, if on { rates } else { FaultRates::NONE });
                });
            }
            // Its frames on that bus wait behind their retransmissions meanwhile; its layer
            // may fail the port for a transmit stall, so the bus need not carry them.
            run.timeline.devs[d].shifted[port].start(now);
            let end = now + every.saturating_mul(times);
            run.at(end, move |r| {
                let t = r.now();
                r.timeline.devs[d].shifted[port].end(t);
            });
        }
        Fault::ProducerTime { node, ms } => {
            // The application asks the master that holds the network (none: nothing happens).
            for id in [STRONG, WEAK] {
                let m = run.plant.master(id);
                if run.plant.sim.is_powered(m) && run.plant.sup(id).role() == MasterRole::Active {
                    run.plant.sim.device_mut(m).producer = Some((node, ms));
                }
            }
        }
        Fault::SlowTx {
            node,
            port,
            delay,
            dur,
        } => {
            let p = port_of(run, node, port);
            let d = dev_index(run, node);
            for_a_while(run, dur, move |r, on| {
                let latency = if on { delay } else { Duration::ZERO };
                r.plant.sim.set_port_tx_latency(p, latency);
                // At the end, frames handed over just before still wait their delay.
                let t = r.now() + (if on { Duration::ZERO } else { delay });
                r.timeline.devs[d].slow_tx[port].set(t, on);
            });
        }
        Fault::TxDrift {
            node,
            port,
            dur,
            load,
        } => {
            let p = port_of(run, node, port);
            let d = dev_index(run, node);
            let profile = drift_profile(load, now, now + dur);
            let top = profile
                .iter()
                .map(|(_, l)| *l)
                .max()
                .unwrap_or(Duration::ZERO);
            run.timeline.devs[d].slow_tx[port].start(now);
            for (t, latency) in profile {
                run.at(t, move |r| r.plant.sim.set_port_tx_latency(p, latency));
            }
            run.at(now + dur, move |r| {
                r.plant.sim.set_port_tx_latency(p, Duration::ZERO);
                // Frames handed over just before still wait their delay.
                let t = r.now() + top;
                r.timeline.devs[d].slow_tx[port].end(t);
            });
        }
        Fault::Cut { bus, dur } => {
            cut(run, bus, true);
            run.at(now + dur, move |r| cut(r, bus, false));
        }
        Fault::Sequence {
            first,
            dur,
            overlap,
            second,
        } => {
            cut(run, first, true);
            run.at(now + dur, move |r| cut(r, first, false));
            let other = 1 - first;
            let start = Instant::from_micros(
                (now + dur)
                    .as_micros()
                    .saturating_add_signed(-overlap * 1_000),
            );
            run.at(start, move |r| cut(r, other, true));
            run.at(start + second, move |r| cut(r, other, false));
        }
        Fault::Flap { bus, half, dur } => {
            let mut t = now;
            let mut down = true;
            while t < now + dur {
                run.at(t, move |r| cut(r, bus, down));
                down = !down;
                t += half;
            }
            run.at(t, move |r| cut(r, bus, false));
        }
        Fault::Lag {
            node,
            port,
            lag,
            dur,
        } => {
            set_lag(run, node, port, lag);
            run.at(now + dur, move |r| set_lag(r, node, port, Duration::ZERO));
        }
        Fault::GrowingLag {
            node,
            port,
            top,
            step,
        } => {
            for k in 0..=2 * top {
                let lag = if k <= top { k } else { 2 * top - k };
                run.at(now + step.saturating_mul(k), move |r| {
                    set_lag(r, node, port, Duration::from_millis(lag))
                });
            }
        }
        Fault::SwitchingLag {
            node,
            port,
            lag,
            every,
            times,
        } => {
            for k in 0..=times {
                let l = if k % 2 == 0 && k < times {
                    lag
                } else {
                    Duration::ZERO
                };
                run.at(now + every.saturating_mul(k as u64), move |r| {
                    set_lag(r, node, port, l)
                });
            }
        }
        Fault::Babble { node, port, dur } => {
            let p = port_of(run, node, port);
            let bus = bus_of(run, node, port);
            let flood = Frame::from_array(Id::Standard(0x001), [0xFF; 8]);
            for_a_while(run, dur, move |r, on| {
                r.plant.sim.babble(p, on.then_some(flood));
                let t = r.now();
                r.timeline.babbled[bus].set(t, on);
                if !on {
                    stalled_after_babble(r, bus);
                }
            });
        }
        Fault::Unplug { node, port, dur } => unplug(run, node, port, dur, false),
        Fault::Impostor { .. } | Fault::Duplicate { .. } => {
            let impostor = matches!(f, Fault::Impostor { .. });
            let (node, dur, buses, state, period) = match f {
                Fault::Impostor { node, bus, dur } => {
                    board_off(run, node);
                    let bus = vec![run.plant.buses[bus]];
                    (node, dur, bus, NmtState::Operational, SLAVE_HB)
                }
                // The board stays as it is: its own faults power it on and off.
                Fault::Duplicate {
                    node,
                    dur,
                    state,
                    period,
                } => (node, dur, run.plant.buses.to_vec(), state, period),
                _ => unreachable!(),
            };
            let frame = Frame::from_array(Id::Standard(0x700 + node as u16), [state.code()]);
            let imp = Impostor {
                frame,
                period,
                next: Some(now + period),
                ports: buses.len(),
                out: heapless::Deque::new(),
            };
            let d = run
                .plant
                .sim
                .add_device(format!("impostor{node:#x}"), imp, &buses)
                .unwrap();
            let mut spans = crate::timeline::Spans::default();
            spans.start(now);
            run.timeline.impostors.push((node, spans));
            run.at(now + dur, move |r| {
                r.plant.sim.power_off(d);
                let t = r.now();
                if let Some(x) = r.timeline.impostors.iter_mut().rev().find(|x| x.0 == node) {
                    x.1.end(t);
                }
                if impostor {
                    board_on(r, node);
                }
            });
        }
        Fault::Stops { node, state } => {
            let (d, _) = run.plant.slave(node);
            if run.plant.sim.is_powered(d) {
                run.plant
                    .sim
                    .device_mut(d)
                    .inner
                    .machine
                    .set_nmt_state(now, state);
            }
        }
        Fault::BoardDies { node, dur } => {
            board_off(run, node);
            run.at(now + dur, move |r| board_on(r, node));
        }
        Fault::BootLoop {
            node,
            every,
            off,
            times,
        } => {
            for k in 0..times as u64 {
                let t = now + every.saturating_mul(k);
                run.at(t, move |r| board_off(r, node));
                run.at(t + off, move |r| board_on(r, node));
            }
        }
        Fault::MasterBootLoop {
            id,
            every,
            off,
            times,
        } => {
            for k in 0..times as u64 {
                let dies = Fault::MasterDies { id, dur: off };
                run.at(now + every.saturating_mul(k), move |r| apply(r, dies));
            }
        }
        Fault::MasterDies { id, dur } => {
            let d = run.plant.master(id);
            let i = dev_index(run, id);
            // The other master is up but has not learned who holds the network (it is still
            // detecting or negotiating after its own boot): nobody holds it after this death,
            // and the next active master comes from a CiA 302-2 negotiation, not a takeover.
            let other = if id == STRONG { WEAK } else { STRONG };
            let learning = matches!(
                run.plant.sup(other).role(),
                MasterRole::Detecting | MasterRole::Negotiating | MasterRole::Standby(None)
            );
            if run.plant.sim.is_powered(run.plant.master(other)) && learning {
                run.no_master_at(now);
            }
            run.plant.sim.power_off(d);
            run.timeline.devs[i].off.start(now);
            run.at(now + dur, move |r| {
                let t = r.now();
                // Rebooted while the other master is off (also when this one was up again
                // already: an outage overlapping another ends in a power cycle): nobody holds
                // the network at this instant, and this master starts cold.
                let other = r.plant.master(if id == STRONG { WEAK } else { STRONG });
                if !r.plant.sim.is_powered(other) {
                    r.no_master_at(t);
                }
                r.plant.reboot_master(id);
                r.timeline.devs[i].off.end(t);
                r.timeline.devs[i].reboots.push(t);
                r.plant.oracle.borrow_mut().rebuilt[i] = Some(t);
                for s in r.settle_from.iter_mut() {
                    *s = t;
                }
            });
        }
        Fault::TxDead { node, port, dur } => crate::tx_dead::apply(run, node, port, dur),
        Fault::ClockRate { node, ppm, dur } => {
            let set = move |r: &mut Run, ppm: i32| {
                let t = r.now();
                let i = dev_index(r, node);
                if node == STRONG || node == WEAK {
                    r.plant.sim.device_mut(r.plant.master(node)).run_at(t, ppm);
                } else {
                    r.plant.sim.device_mut(r.plant.slave(node).0).run_at(t, ppm);
                }
                r.plant.oracle.borrow_mut().clock[i].run_at(t, ppm);
                r.timeline.devs[i].rates.push((t, ppm));
            };
            set(run, ppm);
            run.at(now + dur, move |r| set(r, 0));
        }
        Fault::StepBack { id, by } => {
            let d = run.plant.master(id);
            if !run.plant.sim.is_powered(d) {
                return;
            }
            let by = by.as_micros() as i64;
            run.plant.sim.device_mut(d).shift(now, -by);
            run.plant.oracle.borrow_mut().clock[(id - 1) as usize].shift(now, -by);
            for s in run.settle_from.iter_mut() {
                *s = now;
            }
        }
        Fault::JumpAhead { id, by } => {
            let d = run.plant.master(id);
            if !run.plant.sim.is_powered(d) {
                return;
            }
            let i = dev_index(run, id);
            run.timeline.devs[i].jumps.push((now, by));
            let by = by.as_micros() as i64;
            run.plant.sim.device_mut(d).shift(now, by);
            run.plant.oracle.borrow_mut().clock[(id - 1) as usize].shift(now, by);
            for s in run.settle_from.iter_mut() {
                *s = now;
            }
        }
    }
}

/// The ports on bus `bus` that a babble, just ended, left failed for a transmit stall: each
/// sends nothing until its re-initialisation (see [`crate::timeline::Dev::stalled`]).
fn stalled_after_babble(run: &mut Run, bus: usize) {
    let now = run.now();
    let sim = &run.plant.sim;
    let mut spans = vec![];
    for (k, d) in run.plant.masters.iter().enumerate() {
        if sim.is_powered(*d) {
            let port = run.timeline.devs[dev_index(run, k as u8 + 1)].port(bus);
            let h = sim.device(*d).inner.link.inner.health().port(port);
            let clock = run.plant.oracle.borrow().clock[k];
            let at = h.next_reinit().filter(|_| h.stalled());
            spans.push((dev_index(run, k as u8 + 1), at, clock));
        }
    }
    for (id, d, _) in &run.plant.slaves {
        if sim.is_powered(*d) {
            let port = run.timeline.devs[dev_index(run, *id)].port(bus);
            let h = sim.device(*d).inner.link.inner.health().port(port);
            let at = h.next_reinit().filter(|_| h.stalled());
            let i = dev_index(run, *id);
            spans.push((i, at, run.plant.oracle.borrow().clock[i]));
        }
    }
    for (i, at, clock) in spans {
        let Some(at) = at else { continue };
        // On the simulated time line; back at its next heartbeat (a probe) if sooner.
        let until = clock
            .back(at)
            .min(now + SLAVE_HB.max(MASTER_HB) + Duration::from_millis(2));
        if until > now {
            let port = run.timeline.devs[i].port(bus);
            let sp = &mut run.timeline.devs[i].stalled[port];
            sp.start(now);
            sp.end(until);
        }
    }
}

fn pair_of(node: u8) -> usize {
    ((node & 0x3F) - 0x10) as usize
}

fn board_off(run: &mut Run, node: u8) {
    let (d, _) = run.plant.slave(node);
    let i = dev_index(run, node);
    let now = run.now();
    run.plant.sim.power_off(d);
    run.timeline.devs[i].off.start(now);
}

fn board_on(run: &mut Run, node: u8) {
    let i = dev_index(run, node);
    let t = run.now();
    if run.plant.sim.is_powered(run.plant.slave(node).0) {
        return;
    }
    run.plant.reboot_slave(node);
    run.timeline.devs[i].off.end(t);
    run.timeline.devs[i].reboots.push(t);
    run.plant.oracle.borrow_mut().rebuilt[i] = Some(t);
    run.settle_from[pair_of(node)] = t;
}

/// xorshift: the campaign's own generator, so that a seed means the same schedule everywhere.
pub struct Rng(pub u64);

impl Rng {
    pub fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
    pub fn below(&mut self, n: u64) -> u64 {
        self.next() % n.max(1)
    }
    pub fn ms(&mut self, lo: u64, hi: u64) -> Duration {
        Duration::from_millis(lo + self.below(hi - lo))
    }
}

/// A random fault of the first `kinds` kinds for a plant of `pairs` pairs.
pub fn random(rng: &mut Rng, pairs: u8, connectivity_free: bool, kinds: usize) -> Fault {
    loop {
        let k = rng.below(kinds as u64) as usize;
        let f = draw(rng, pairs, k);
        if connectivity_free || !f.connectivity() {
            return f;
        }
    }
}

/// The transmit delays of a port whose writer task drifts from its twin's over `[from, to)`
/// (see [`Fault::TxDrift`]): from when each holds, a step a millisecond. Bursts follow each
/// other: a delay that grows to its top (1 to 80 ms) and shrinks back, over 10 to 300 ms each
/// way; a hold of 5 to 80 ms (each frame handed over meanwhile waits until its end: the burst
/// goes out at once); a calm of 5 to 200 ms (on time).
pub fn drift_profile(load: u64, from: Instant, to: Instant) -> Vec<(Instant, Duration)> {
    let mut rng = Rng(load | 1);
    let (mut v, mut t) = (vec![], from);
    let ms = Duration::from_millis;
    while t < to {
        match rng.below(3) {
            0 => {
                let top = [
                    1_000u64, 3_000, 6_000, 10_000, 20_000, 40_000, 60_000, 80_000,
                ][rng.below(8) as usize];
                let rise = 10 + rng.below(290);
                for k in 0..2 * rise {
                    let up = if k <= rise { k } else { 2 * rise - k };
                    v.push((t + ms(k), Duration::from_micros(top * up / rise)));
                }
                t += ms(2 * rise);
            }
            1 => {
                let hold = 5 + rng.below(75);
                for k in 0..hold {
                    v.push((t + ms(k), ms(hold - k)));
                }
                t += ms(hold);
            }
            _ => {
                v.push((t, Duration::ZERO));
                t += ms(5 + rng.below(195));
            }
        }
    }
    v.retain(|(at, _)| *at < to);
    v
}

/// How many kinds of fault the campaign draws from (every class that holds, some in two
/// shapes).
pub const KINDS: usize = 34;

/// The kinds with a bridge loop between the buses (kind [`BRIDGE`]), which the layers do not
/// hold yet (the "known and not fixed yet" of the user guide's redundant-master chapter: they
/// deliver the bridge's copies as new frames), so the budget and the sweeps leave it out
/// unless `CAMPAIGN_KINDS=35` (or `CAMPAIGN_DRIFT=1`) asks for it.
pub const KINDS_WITH_BRIDGE: usize = KINDS + 1;
/// The bridge loop's kind.
pub const BRIDGE: usize = KINDS;

/// Every kind [`draw`] knows: also receive clocks that drift apart (kind [`DRIFT`], always the
/// last), which still fail combined with others (the "known and not fixed yet" of the user
/// guide's redundant-master chapter), so the budget and the sweeps leave it out unless
/// `CAMPAIGN_DRIFT=1` asks for it (with the bridge loop).
pub const KINDS_WITH_DRIFT: usize = KINDS_WITH_BRIDGE + 1;
/// The drift's kind.
pub const DRIFT: usize = KINDS_WITH_BRIDGE;

/// The kinds the campaign knew before a bridge loop between the buses: the seeds in
/// `REGRESSIONS_ERROR_PASSIVE` draw from these (all it holds, while the bridge is left out).
pub const KINDS_BEFORE_BRIDGE: usize = 34;

/// The kinds the campaign knew before a controller stuck error passive: the seeds in
/// `REGRESSIONS_EVERY_KIND` draw from these.
pub const KINDS_BEFORE_ERROR_PASSIVE: usize = 33;

/// The kinds the campaign knew before long frames lost on one bus: the seeds in
/// `REGRESSIONS_PRODUCER_TIME` draw from these.
pub const KINDS_BEFORE_LONG_FRAMES: usize = 32;

/// The kinds the campaign knew before a producer time changed at run time: the seeds in
/// `REGRESSIONS_GROUND_SHIFT` draw from these.
pub const KINDS_BEFORE_PRODUCER_TIME: usize = 31;

/// The kinds the campaign knew before a ground shift at one sender: the seeds in
/// `REGRESSIONS_DEGRADING` draw from these.
pub const KINDS_BEFORE_GROUND_SHIFT: usize = 30;

/// The kinds the campaign knew before a degrading bus: the seeds in `REGRESSIONS_TX_DRIFT`
/// draw from these.
pub const KINDS_BEFORE_DEGRADING: usize = 29;

/// The kinds the campaign knew before a sender whose port writes drift apart: the seeds in
/// `REGRESSIONS_TX_DEAD` draw from these.
pub const KINDS_BEFORE_TX_DRIFT: usize = 28;

/// The kinds the campaign knew before a transceiver that cannot send: the seeds in
/// `REGRESSIONS_CLOCK_RATE` draw from these.
pub const KINDS_BEFORE_TX_DEAD: usize = 27;

/// The kinds the campaign knew before a clock at a wrong rate: the seeds in
/// `REGRESSIONS_MASTER_BOOT_LOOP` draw from these.
pub const KINDS_BEFORE_CLOCK_RATE: usize = 26;

/// The kinds the campaign knew before a master in a boot loop: the seeds in
/// `REGRESSIONS_BOOT_LOOP` draw from these.
pub const KINDS_BEFORE_MASTER_BOOT_LOOP: usize = 25;

/// The kinds the campaign knew before a board in a boot loop: the seeds in
/// `REGRESSIONS_OTHER_DUPLICATES` draw from these.
pub const KINDS_BEFORE_BOOT_LOOP: usize = 24;

/// The kinds the campaign knew before a duplicate that beats another state (pre-operational,
/// stopped) or at twice the period: the seeds in `REGRESSIONS_WRONG_RATE` draw from these.
pub const KINDS_BEFORE_OTHER_DUPLICATES: usize = 23;

/// The kinds the campaign knew before a node at the wrong bit rate: the seeds in
/// `REGRESSIONS_DUPLICATE` draw from these.
pub const KINDS_BEFORE_WRONG_RATE: usize = 22;

/// A controller at the wrong bit rate destroys every frame for this long (error-active: some
/// 16 frames at 1 Mbit/s, then its own garbled attempts) ...
pub const WRONG_RATE_BURST: Duration = Duration::from_millis(3);
/// ... once in this (bus-off, its recovery after 128 × 11 recessive bits, error-active again).
pub const WRONG_RATE_CYCLE: Duration = Duration::from_millis(5);

/// The kinds the campaign knew before a live board's duplicate: the seeds in
/// `REGRESSIONS_SLOW_TX` draw from these.
pub const KINDS_BEFORE_DUPLICATE: usize = 21;

/// The kinds the campaign knew before slow transmitters: the seeds in `REGRESSIONS_ALL_KINDS`
/// and `REGRESSIONS_QUIET` draw from these.
pub const KINDS_BEFORE_SLOW_TX: usize = 20;

/// The kinds the campaign knew before noise and overruns: the seeds in `REGRESSIONS` draw from
/// these, so that each still plays the schedule it once failed with.
pub const KINDS_BEFORE_NOISE: usize = 18;

/// A fault of kind `k` (below [`KINDS`]), its parameters drawn from `rng`.
pub fn draw(rng: &mut Rng, pairs: u8, k: usize) -> Fault {
    let board = |rng: &mut Rng| {
        let i = rng.below(pairs as u64) as u8;
        if rng.below(2) == 0 {
            a(i)
        } else {
            b(i)
        }
    };
    let any_node = |rng: &mut Rng| match rng.below(4) {
        0 => [STRONG, WEAK][rng.below(2) as usize],
        1 => OBSERVER,
        _ => board(rng),
    };
    {
        match k {
            0 => Fault::Cut {
                bus: rng.below(2) as usize,
                dur: rng.ms(200, 4_000),
            },
            1 | 16 | 17 => Fault::Sequence {
                first: rng.below(2) as usize,
                dur: rng.ms(300, 4_000),
                overlap: match k {
                    1 => 0,
                    16 => 30,
                    _ => -40,
                },
                second: rng.ms(300, 3_000),
            },
            2 => Fault::Flap {
                bus: rng.below(2) as usize,
                half: Duration::from_millis([1, 5, 50][rng.below(3) as usize]),
                dur: rng.ms(200, 1_500),
            },
            3 => Fault::Lag {
                node: any_node(rng),
                port: rng.below(2) as usize,
                lag: rng.ms(5, 75),
                dur: rng.ms(500, 4_000),
            },
            4 => Fault::GrowingLag {
                node: any_node(rng),
                port: rng.below(2) as usize,
                top: 5 + rng.below(66),
                step: rng.ms(10, 60),
            },
            5 => Fault::SwitchingLag {
                node: any_node(rng),
                port: rng.below(2) as usize,
                lag: rng.ms(10, 60),
                every: rng.ms(50, 300),
                times: 2 + rng.below(10) as u32,
            },
            6 => Fault::Babble {
                node: board(rng),
                port: rng.below(2) as usize,
                dur: rng.ms(100, 800),
            },
            7 => Fault::Unplug {
                node: any_node(rng),
                port: rng.below(2) as usize,
                dur: rng.ms(200, 3_000),
            },
            8 => Fault::Impostor {
                node: board(rng),
                bus: rng.below(2) as usize,
                dur: rng.ms(300, 2_000),
            },
            9 => Fault::Stops {
                node: board(rng),
                state: if rng.below(2) == 0 {
                    NmtState::PreOperational
                } else {
                    NmtState::Stopped
                },
            },
            10 => Fault::BoardDies {
                node: board(rng),
                dur: rng.ms(100, 3_000),
            },
            11 => Fault::MasterDies {
                id: [STRONG, WEAK][rng.below(2) as usize],
                dur: rng.ms(200, 3_000),
            },
            12 => Fault::StepBack {
                id: [STRONG, WEAK][rng.below(2) as usize],
                by: Duration::from_millis([1, 50, 1_000, 3_600_000][rng.below(4) as usize]),
            },
            13 => Fault::JumpAhead {
                id: [STRONG, WEAK][rng.below(2) as usize],
                by: Duration::from_millis([70, 1_000, 60_000, 3_600_000][rng.below(4) as usize]),
            },
            18 => Fault::Noise {
                bus: rng.below(2) as usize,
                permille: [10, 100, 300][rng.below(3) as usize],
                dur: rng.ms(200, 3_000),
            },
            19 => Fault::Overrun {
                node: any_node(rng),
                port: rng.below(2) as usize,
                permille: [10, 100, 500][rng.below(3) as usize],
                dur: rng.ms(200, 3_000),
            },
            20 => {
                // Any node, or the one that is not duocan: its copies this late are within
                // the skew window, as the network's configuration must keep them (further
                // apart, they are two frames to every receiver: the promise table says so).
                let (node, delays): (u8, &[u64]) = match rng.below(5) {
                    0 => (FOREIGN, &[500, 1_000, 2_000, 3_000]),
                    // Within the layer's transmit stall time (half the window) and beyond.
                    _ => (any_node(rng), &[500, 2_000, 4_000, 10_000, 40_000]),
                };
                Fault::SlowTx {
                    node,
                    port: rng.below(2) as usize,
                    delay: Duration::from_micros(delays[rng.below(delays.len() as u64) as usize]),
                    dur: rng.ms(200, 3_000),
                }
            }
            21 => Fault::Duplicate {
                node: board(rng),
                dur: rng.ms(300, 2_000),
                state: NmtState::Operational,
                period: SLAVE_HB,
            },
            23 => Fault::Duplicate {
                node: board(rng),
                dur: rng.ms(300, 2_000),
                state: [NmtState::PreOperational, NmtState::Stopped][rng.below(2) as usize],
                period: SLAVE_HB.saturating_mul(1 + rng.below(2)),
            },
            24 => Fault::BootLoop {
                node: board(rng),
                every: rng.ms(100, 300),
                // Reset held for a few ms to most of the period.
                off: rng.ms(2, 80),
                times: 2 + rng.below(20) as u32,
            },
            25 => Fault::MasterBootLoop {
                id: [STRONG, WEAK][rng.below(2) as usize],
                every: rng.ms(100, 300),
                off: rng.ms(2, 80),
                times: 2 + rng.below(20) as u32,
            },
            26 => Fault::ClockRate {
                node: match rng.below(2) {
                    0 => [STRONG, WEAK][rng.below(2) as usize],
                    _ => board(rng),
                },
                // A crystal (±100 ppm) to a throttled virtual machine (±10 %).
                ppm: [
                    -100_000, -50_000, -20_000, -100, 100, 20_000, 50_000, 100_000,
                ][rng.below(8) as usize],
                dur: rng.ms(1_000, 6_000),
            },
            27 => Fault::TxDead {
                node: match rng.below(2) {
                    0 => [STRONG, WEAK][rng.below(2) as usize],
                    _ => board(rng),
                },
                port: rng.below(2) as usize,
                dur: rng.ms(500, 8_000),
            },
            28 => Fault::TxDrift {
                // Any node: a board, a master, the observer, or the one that is not duocan
                // (no layer of its own: its copies further apart than the window are two
                // frames to every receiver, as the promise table says).
                node: match rng.below(5) {
                    0 => FOREIGN,
                    _ => any_node(rng),
                },
                port: rng.below(2) as usize,
                dur: rng.ms(500, 8_000),
                load: rng.next(),
            },
            29 => Fault::Degrading {
                bus: rng.below(2) as usize,
                permille: [100, 300, 700][rng.below(3) as usize],
                ramp: rng.ms(500, 5_000),
                hold: rng.ms(200, 3_000),
            },
            30 => Fault::GroundShift {
                node: match rng.below(5) {
                    0 => FOREIGN,
                    _ => any_node(rng),
                },
                port: rng.below(2) as usize,
                permille: [100, 300, 700][rng.below(3) as usize],
                every: rng.ms(30, 300),
                dur: rng.ms(300, 5_000),
            },
            31 => Fault::ProducerTime {
                node: board(rng),
                ms: [10, 15, 25][rng.below(3) as usize],
            },
            32 => Fault::LongFrames {
                bus: rng.below(2) as usize,
                permille: [300, 700, 1000][rng.below(3) as usize],
                // An eight-byte frame (SDO, the campaign's PDOs) is hit from 5; from 2 a
                // two-byte NMT command too; a heartbeat never.
                from: [2, 5, 8][rng.below(3) as usize],
                dur: rng.ms(200, 4_000),
            },
            33 => Fault::ErrorPassive {
                node: match rng.below(2) {
                    0 => [STRONG, WEAK][rng.below(2) as usize],
                    _ => board(rng),
                },
                port: rng.below(2) as usize,
                // Just passive (a frame sent after the repair makes it active again), or
                // far up (a hundred frames or more before it is).
                tec: [128, 180, 250][rng.below(3) as usize],
                dur: rng.ms(200, 4_000),
            },
            BRIDGE => Fault::Bridge {
                way: rng.below(3) as u8,
                delay: Duration::from_micros(500 + rng.below(9_501)),
                // Everything, or the process data, or the heartbeats, or SYNC and EMCY.
                ids: [
                    None,
                    None,
                    Some((0x180, 0x4FF)),
                    Some((0x700, 0x77F)),
                    Some((0x080, 0x0FF)),
                ][rng.below(5) as usize],
                queue: [8, 32, 256][rng.below(3) as usize],
                dur: rng.ms(200, 4_000),
            },
            DRIFT => Fault::Drift {
                node: any_node(rng),
                port: rng.below(2) as usize,
                ppm: [-8_000, -3_000, -1_000, 1_000, 3_000, 8_000][rng.below(6) as usize],
                dur: rng.ms(500, 4_000),
            },
            22 => Fault::WrongBitRate {
                node: any_node(rng),
                port: rng.below(2) as usize,
                dur: rng.ms(200, 3_000),
            },
            14 => Fault::Lag {
                node: any_node(rng),
                port: rng.below(2) as usize,
                lag: rng.ms(20, 60),
                dur: rng.ms(50, 200),
            },
            _ => Fault::Cut {
                bus: rng.below(2) as usize,
                dur: rng.ms(20, 300),
            },
        }
    }
}

/// Which classes ran, alone and together with which others.
#[derive(Default, Debug)]
pub struct Coverage {
    pub classes: BTreeMap<&'static str, u32>,
    /// Of those, how many took effect ([`crate::effects`]).
    pub effective: BTreeMap<&'static str, u32>,
    pub pairs: BTreeMap<(&'static str, &'static str), u32>,
}

impl Coverage {
    pub fn add(&mut self, f: &Fault, overlapping: &[&'static str]) {
        *self.classes.entry(f.class()).or_default() += 1;
        for o in overlapping {
            let (x, y) = if f.class() <= *o {
                (f.class(), *o)
            } else {
                (*o, f.class())
            };
            *self.pairs.entry((x, y)).or_default() += 1;
        }
    }
    pub fn merge(&mut self, other: &Coverage) {
        for (k, v) in &other.classes {
            *self.classes.entry(k).or_default() += v;
        }
        for (k, v) in &other.effective {
            *self.effective.entry(k).or_default() += v;
        }
        for (k, v) in &other.pairs {
            *self.pairs.entry(*k).or_default() += v;
        }
    }
}

/// Composes random faults on `run` until `end`: one every 0.3 to 3 s, at most one taking a
/// connection away at a time (two buses in sequence with overlap aside), any number of the
/// others overlapping; the first of kind `lead` if given; drawn from the first `kinds` kinds.
/// Returns the coverage.
pub fn compose(
    run: &mut Run,
    rng: &mut Rng,
    start: Instant,
    end: Instant,
    lead: Option<usize>,
    kinds: usize,
) -> Coverage {
    let mut cov = Coverage::default();
    let mut active: Vec<(Instant, Fault)> = vec![];
    let mut t = start;
    let mut lead = lead;
    while t < end {
        run.run_until(t);
        active.retain(|(until, _)| *until > t);
        let free = !active.iter().any(|(_, f)| f.connectivity());
        let f = match lead.take() {
            Some(k) => draw(rng, run.plant.p.pairs, k),
            None => random(rng, run.plant.p.pairs, free, kinds),
        };
        let classes: Vec<&'static str> = active.iter().map(|(_, f)| f.class()).collect();
        cov.add(&f, &classes);
        if std::env::var("CAMPAIGN_VERBOSE").is_ok() {
            eprintln!("{t}: {f:?}");
        }
        // A fault's effects (a board rebooting, a master negotiating) outlast it a little.
        active.push((t + f.span() + Duration::from_millis(300), f));
        crate::effects::watch(run, f);
        apply(run, f);
        t += rng.ms(300, 3_000);
    }
    cov
}
