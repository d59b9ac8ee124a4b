//! What the faults did to the wiring, over time: the oracle's answer to "could this frame have
//! arrived?" ([`crate::oracle::Wiring`]).

use crate::oracle::Wiring;
use crate::plant::SLAVE_HB;
use duocan::{Duration, Frame, Id, Instant};
use duocan_redundancy::link::plausible::CALM_BEATS;

/// Around a change of the wiring, frames are not judged lost: what was on the wire or queued at
/// the cut, and the copies a sender put on a bus in the instant before it learnt it was cut.
pub const MARGIN: Duration = Duration::from_millis(20);

/// A receive lag up to this keeps a device's timing: a heartbeat consumer (50 ms for a 20 ms
/// producer) still sees the heartbeats in time when the lag appears on its only working bus.
/// Beyond it, the device's view of time-critical traffic is late (as on any single bus): the
/// redundancy cannot hand over a frame before the port's reader does.
pub const LAG_SLACK: Duration = Duration::from_millis(25);

/// Intervals `[from, to)` during which something held (`to` = `Instant::MAX`: still holds).
#[derive(Clone, Debug, Default)]
pub struct Spans(pub Vec<(Instant, Instant)>);

impl Spans {
    pub fn start(&mut self, t: Instant) {
        if self.0.last().is_none_or(|s| s.1 != Instant::MAX) {
            self.0.push((t, Instant::MAX));
        }
    }
    pub fn end(&mut self, t: Instant) {
        if let Some(s) = self.0.last_mut().filter(|s| s.1 == Instant::MAX) {
            s.1 = t;
        }
    }
    /// Starts (`on`) or ends a span at `t`.
    pub fn set(&mut self, t: Instant, on: bool) {
        if on {
            self.start(t);
        } else {
            self.end(t);
        }
    }
    /// Holds at any time of `[from, to]`.
    pub fn any(&self, from: Instant, to: Instant) -> bool {
        self.0.iter().any(|s| s.0 <= to && s.1 > from)
    }
    /// Holds at every time of `[from, to]`.
    pub fn all(&self, from: Instant, to: Instant) -> bool {
        self.0.iter().any(|s| s.0 <= from && s.1 > to)
    }
    pub fn at(&self, t: Instant) -> bool {
        self.any(t, t)
    }
}

/// One device as the timeline knows it: its oracle node, node-ID, and what happened to it.
#[derive(Clone, Debug, Default)]
pub struct Dev {
    pub node_id: u8,
    /// Cabled crossed: its port 0 on bus 2, its port 1 on bus 1 (the per-port spans below
    /// are by its ports; [`Dev::port`] maps a bus to one).
    pub swapped: bool,
    /// Per port: unplugged.
    pub unplugged: [Spans; 2],
    /// Per port: failed for a transmit stall behind a babble that has ended, until its next
    /// heartbeat (a probe: confirmed in time, the port is back) or its re-initialisation,
    /// whichever comes first. Such a port sends nothing else meanwhile: the bus carries
    /// nothing of this device's but that probe; a cut of the other bus meanwhile is an
    /// outage.
    pub stalled: [Spans; 2],
    /// Per port: its receive lag exceeds [`LAG_SLACK`].
    pub slow: [Spans; 2],
    /// Per port: every receive lag it was given, from when.
    pub lags: [Vec<(Instant, Duration)>; 2],
    /// Per port: its controller sends late (a slow transmitter); the layer may fail the port
    /// for a transmit stall meanwhile, so the bus need not carry this device's frames.
    pub slow_tx: [Spans; 2],
    /// Per port: its transceiver cannot send (nothing it sends reaches that bus; it receives,
    /// but not while its controller is bus-off).
    pub tx_dead: [Spans; 2],
    /// Per port: its controller overruns (misses frames now and then).
    pub overrun: [Spans; 2],
    /// Per port: a ground shift destroys frames it sends (see `Fault::GroundShift`).
    pub shifted: [Spans; 2],
    pub off: Spans,
    /// Its NMT state one in which its SDO server does not answer (stopped, or booting), as
    /// the run sees it every millisecond.
    pub stopped: Spans,
    /// Its clock's jumps ahead: when, and by how much.
    pub jumps: Vec<(Instant, Duration)>,
    /// Instants it was rebuilt (rebooted).
    pub reboots: Vec<Instant>,
    /// Its timer clock's rate, from when (parts per million fast; negative: slow).
    pub rates: Vec<(Instant, i32)>,
}

impl Dev {
    /// Its port on bus `bus`.
    pub fn port(&self, bus: usize) -> usize {
        bus ^ usize::from(self.swapped)
    }
    /// The slowest its timer clock ran at some time of `[from, to]` (ppm, at most zero): its
    /// timeouts and periods took that much longer on the simulated time line.
    pub fn slowest(&self, from: Instant, to: Instant) -> i32 {
        let start = self
            .rates
            .iter()
            .rposition(|(t, _)| *t <= from)
            .unwrap_or(0);
        let rates = self.rates.get(start..).unwrap_or_default();
        rates
            .iter()
            .filter(|(t, _)| *t <= to)
            .map(|(_, ppm)| *ppm)
            .min()
            .unwrap_or(0)
            .min(0)
    }
    /// The largest receive lag any of its ports had at some time of `[from, to]`.
    pub fn lag(&self, from: Instant, to: Instant) -> Duration {
        let mut worst = Duration::ZERO;
        for lags in &self.lags {
            // The lag in force at `from`, and every one given after it until `to`.
            let start = lags.iter().rposition(|(t, _)| *t <= from).unwrap_or(0);
            for (t, l) in &lags[start..] {
                if *t <= to {
                    worst = worst.max(*l);
                }
            }
        }
        worst
    }
}

#[derive(Clone, Debug, Default)]
pub struct Timeline {
    /// Per bus: cut.
    pub cut: [Spans; 2],
    /// Per bus: a babbling controller holds it.
    pub babbled: [Spans; 2],
    /// Per bus: noise hits frames (error frames, retransmissions).
    pub noisy: [Spans; 2],
    /// By oracle node.
    pub devs: Vec<Dev>,
    /// (target node-ID, span): an impostor beats for it.
    pub impostors: Vec<(u8, Spans)>,
}

impl Timeline {
    fn path(&self, s: usize, r: usize, bus: usize, from: Instant, to: Instant) -> (bool, bool) {
        let (ds, dr) = (&self.devs[s], &self.devs[r]);
        let (ps, pr) = (ds.port(bus), dr.port(bus));
        let broken = |f: Instant, t: Instant| {
            (
                self.cut[bus].any(f, t)
                    || self.babbled[bus].any(f, t)
                    || self.noisy[bus].any(f, t)
                    || dr.overrun[pr].any(f, t)
                    || ds.unplugged[ps].any(f, t)
                    || ds.stalled[ps].any(f, t)
                    || ds.slow_tx[ps].any(f, t)
                    || ds.shifted[ps].any(f, t)
                    || ds.tx_dead[ps].any(f, t)
                    || dr.tx_dead[pr].any(f, t)
                    || dr.unplugged[pr].any(f, t)
                    || ds.off.any(f, t)
                    || dr.off.any(f, t),
                self.cut[bus].all(f, t)
                    || self.babbled[bus].all(f, t)
                    || ds.unplugged[ps].all(f, t)
                    || ds.stalled[ps].all(f, t)
                    || ds.tx_dead[ps].all(f, t)
                    || dr.unplugged[pr].all(f, t)
                    || ds.off.all(f, t)
                    || dr.off.all(f, t),
            )
        };
        let (ever, always) = broken(from, to);
        (!ever, always)
    }
}

impl Timeline {
    /// Whether a bus connected the two devices both ways all through `[from, to]`: nothing
    /// the faults did broke it (cut, babbled, a port unplugged or left stalled by a babble,
    /// either device off).
    pub fn intact(&self, s: usize, r: usize, from: Instant, to: Instant) -> bool {
        (0..2).any(|b| self.path(s, r, b, from, to).0 && self.path(r, s, b, from, to).0)
    }
}

impl Wiring for Timeline {
    fn connected(&self, s: usize, r: usize, t: Instant) -> Option<bool> {
        let (from, to) = (t - MARGIN, t + MARGIN);
        let paths = [self.path(s, r, 0, from, to), self.path(s, r, 1, from, to)];
        if paths.iter().any(|p| p.0) {
            Some(true)
        } else if paths.iter().all(|p| p.1) {
            Some(false)
        } else {
            None
        }
    }

    fn jumped(&self, r: usize, from: Instant, to: Instant) -> bool {
        self.devs[r]
            .jumps
            .iter()
            .any(|(t, _)| *t > from && *t <= to)
    }

    fn excluded(
        &self,
        s: usize,
        r: usize,
        t: Instant,
        frame: &Frame,
        calm: &dyn Fn(u8, Instant) -> Instant,
    ) -> bool {
        let (from, to) = (t - MARGIN, t + crate::oracle::JUDGE_AFTER);
        // A device rebooted meanwhile: its two lives are not one receiver.
        let rebooted = |d: &Dev| d.reboots.iter().any(|b| *b >= from && *b <= to);
        if rebooted(&self.devs[r]) || rebooted(&self.devs[s]) {
            return true;
        }
        if self.devs[r].off.any(from, to) {
            return true;
        }
        // The heartbeats of a node an impostor beats for: the layer judges them implausible on
        // a bus and drops that bus's copies (as it must), up to the rule's tail after the
        // impostor's last heartbeat: the node's heartbeats until three at its pace in one
        // state (a heartbeat saying a new state counts neither way: a duplicated board the
        // master sent to pre-operational for its standby says so as the duplicate leaves, and
        // a master that starts and stops it by turns while another duplicate churns its pair
        // leaves one such heartbeat in two periods), and at least the time those take.
        if let Id::Standard(id @ 0x701..=0x77F) = frame.id() {
            let node = (id & 0x7F) as u8;
            let tail = SLAVE_HB.saturating_mul(CALM_BEATS as u64 + 1);
            return self.impostors.iter().any(|(n, sp)| {
                *n == node
                    && sp.0.iter().any(|&(from, end)| {
                        let until = if end == Instant::MAX {
                            end
                        } else {
                            (end + tail).max(calm(node, end))
                        };
                        from <= to && until.saturating_add(MARGIN) >= t
                    })
            });
        }
        false
    }
}
