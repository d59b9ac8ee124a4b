//! A CAN-to-CAN bridge between two buses (a misconfigured gateway or diagnostic repeater): a
//! device with a port on each bus that copies what it receives on one onto the other, some
//! time later.

use super::device::Slot;
use super::ids::{BusId, DevId, PortRef};
use super::SimNetwork;
use crate::frame::instant::{Duration, Instant};
use crate::frame::Frame;
use crate::machine::{Device, PortStatus};
use std::collections::VecDeque;

/// Which way a bridge copies frames (see [`SimNetwork::set_bridge`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BridgeDirection {
    /// From the first bus onto the second.
    FirstToSecond,
    /// From the second bus onto the first.
    SecondToFirst,
    /// Both ways.
    Both,
}

/// How a bridge behaves (see [`SimNetwork::set_bridge`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BridgeConfig {
    /// Which way it copies.
    pub direction: BridgeDirection,
    /// How long after a frame ended on one bus its copy may compete for the other.
    pub delay: Duration,
    /// The identifiers it copies (raw values, both ends included; extended and base frames
    /// alike); `None`: every frame.
    pub ids: Option<(u32, u32)>,
    /// Most frames it holds at once (waiting out the delay or for the other bus); a frame it
    /// receives while full is dropped and counted ([`BridgeStats::overflow`]).
    pub queue: usize,
}

impl BridgeConfig {
    /// Every frame, `direction`, `delay` late, a queue of 32 frames.
    pub fn new(direction: BridgeDirection, delay: Duration) -> Self {
        BridgeConfig {
            direction,
            delay,
            ids: None,
            queue: 32,
        }
    }
}

/// What a bridge did since it was first set (see [`SimNetwork::bridge_stats`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BridgeStats {
    /// Frames its ports received.
    pub heard: u64,
    /// Frames it took to copy.
    pub taken: u64,
    /// Frames it received while its queue was full: not copied.
    pub overflow: u64,
    /// Copies it sent (acknowledged on the other bus).
    pub sent: u64,
}

/// Where a copy a bridge sent came from ([`RxNote::bridged`](super::RxNote::bridged)).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Bridged {
    /// The port that sent the frame the bridge copied.
    pub sender: PortRef,
    /// That frame's serial among its sender's (`None`: a babbling controller's).
    pub serial: Option<u64>,
    /// When it ended on the bus the bridge heard it on.
    pub wire: Instant,
}

/// Copies whose origin is remembered (the bridge's newest ones, by serial).
const ORIGINS: usize = 4096;

/// The bridge device: port 0 on the first bus, port 1 on the second.
pub struct Bridge {
    config: BridgeConfig,
    /// Frames waiting out the delay: (due, port to send on, frame, origin).
    waiting: VecDeque<(Instant, usize, Frame, Bridged)>,
    /// Frames handed to the simulator and not reported sent or failed yet, per port.
    outstanding: [usize; 2],
    /// The origin of each copy handed to the simulator, by serial from `base`.
    origins: VecDeque<Bridged>,
    base: u64,
    /// Frames due, to hand over.
    due: VecDeque<(usize, Frame, Bridged)>,
    stats: BridgeStats,
}

impl Bridge {
    fn new(config: BridgeConfig) -> Self {
        Bridge {
            config,
            waiting: VecDeque::new(),
            outstanding: [0; 2],
            origins: VecDeque::new(),
            base: 0,
            due: VecDeque::new(),
            stats: BridgeStats::default(),
        }
    }

    fn held(&self) -> usize {
        self.waiting.len() + self.due.len() + self.outstanding[0] + self.outstanding[1]
    }

    /// Port `port` received `frame` at `now` from `origin`.
    fn heard(&mut self, now: Instant, port: usize, frame: &Frame, origin: Bridged) {
        self.stats.heard += 1;
        let copies = match self.config.direction {
            BridgeDirection::FirstToSecond => port == 0,
            BridgeDirection::SecondToFirst => port == 1,
            BridgeDirection::Both => true,
        };
        let raw = frame.id().raw();
        let wanted = self
            .config
            .ids
            .is_none_or(|(lo, hi)| lo <= raw && raw <= hi);
        if !copies || !wanted {
            return;
        }
        if self.held() >= self.config.queue {
            self.stats.overflow += 1;
            return;
        }
        self.stats.taken += 1;
        self.waiting
            .push_back((now + self.config.delay, 1 - port, *frame, origin));
    }

    /// The origin of the copy with simulator serial `serial`, if remembered.
    fn origin(&self, serial: u64) -> Option<Bridged> {
        let k = serial.checked_sub(self.base)?;
        self.origins.get(k as usize).copied()
    }
}

impl Device for Bridge {
    type Event = ();
    fn port_count(&self) -> usize {
        2
    }
    fn handle_rx(&mut self, _: Instant, _: usize, _: &Frame) {}
    fn handle_port_status(&mut self, _: Instant, port: usize, status: PortStatus) {
        if matches!(status, PortStatus::TxOk | PortStatus::TxFailed(_)) {
            if status == PortStatus::TxOk {
                self.stats.sent += 1;
            }
            self.outstanding[port & 1] = self.outstanding[port & 1].saturating_sub(1);
        }
    }
    fn handle_timeout(&mut self, now: Instant) {
        while self.waiting.front().is_some_and(|w| w.0 <= now) {
            if let Some((_, port, frame, origin)) = self.waiting.pop_front() {
                self.due.push_back((port, frame, origin));
            }
        }
    }
    fn poll_transmit(&mut self) -> Option<(usize, Frame)> {
        let (port, frame, origin) = self.due.pop_front()?;
        self.outstanding[port] += 1;
        self.origins.push_back(origin);
        if self.origins.len() > ORIGINS {
            self.origins.pop_front();
            self.base += 1;
        }
        Some((port, frame))
    }
    fn poll_timeout(&self) -> Option<Instant> {
        self.waiting.front().map(|w| w.0)
    }
    fn poll_event(&mut self) -> Option<()> {
        None
    }
}

impl SimNetwork {
    /// Puts a bridge between buses `first` and `second` (or reconfigures the one there): a
    /// device with a port on each that copies the frames it receives on one bus onto the other
    /// ([`BridgeConfig`]: which way, which identifiers, how late, how many it holds). It
    /// arbitrates and takes wire time like any node, acknowledges what it receives, and never
    /// copies a frame it sent itself (a port does not receive its own frames), so a bridge both
    /// ways does not loop a frame back. A copy competes for the other bus once the delay after
    /// its original ended is over; frames it receives while holding its queue's worth are
    /// dropped and counted. Its frames reach the receive hook with their origin
    /// ([`RxNote::bridged`](super::RxNote::bridged)). The bridge is the device added by the first
    /// call (named `bridge`); reconfigured, it starts empty.
    ///
    /// # Panics
    /// If a bridge already joins two other buses.
    pub fn set_bridge(
        &mut self,
        first: BusId,
        second: BusId,
        config: BridgeConfig,
    ) -> DevId<Bridge> {
        let id = match self.bridge {
            Some(d) => {
                let id = DevId::<Bridge>::new(d);
                let on = |s: &Self, p: usize| s.ports[s.port_index(id.port(p))].bus;
                assert!(
                    on(self, 0) == first.0 && on(self, 1) == second.0,
                    "the bridge joins other buses"
                );
                id
            }
            None => {
                let id = self
                    .add_device("bridge", Bridge::new(config), &[first, second])
                    .expect("a bridge's two buses");
                self.bridge = Some(id.index() as u32);
                id
            }
        };
        // Unplugged and plugged in again: what it held is gone.
        self.power_off(id);
        let stats = self.device(id).stats;
        let base = self.frames_taken(id);
        let b = self.device_mut(id);
        *b = Bridge::new(config);
        b.stats = stats;
        b.base = base;
        self.power_on(id);
        id
    }

    /// Unplugs the bridge ([`set_bridge`](Self::set_bridge)), if there is one: it receives,
    /// acknowledges and sends nothing more, and the frames it held are lost.
    pub fn clear_bridge(&mut self) {
        if let Some(d) = self.bridge {
            self.power_off(super::ids::DeviceRef(d));
        }
    }

    /// What the bridge did so far (`None`: no bridge was ever set).
    pub fn bridge_stats(&self) -> Option<BridgeStats> {
        let d = self.bridge?;
        Some(self.device(DevId::<Bridge>::new(d)).stats)
    }

    /// Whether device `d` is the bridge.
    pub(super) fn is_bridge(&self, d: usize) -> bool {
        self.bridge == Some(d as u32)
    }

    /// The bridge's port `r` (global index) received `frame`, which ended on its bus at `wire`
    /// and was sent by port `from` (global) as its serial.
    pub(super) fn bridge_heard(
        &mut self,
        r: usize,
        frame: &Frame,
        wire: Instant,
        from: (u32, Option<u64>),
    ) {
        let origin = Bridged {
            sender: self.port_ref(from.0 as usize),
            serial: from.1,
            wire,
        };
        let (d, local, now) = (
            self.ports[r].dev as usize,
            self.ports[r].local as usize,
            self.now,
        );
        if let Some(slot) = self.devices[d]
            .dev
            .as_any_mut()
            .downcast_mut::<Slot<Bridge>>()
        {
            slot.device.heard(now, local, frame, origin);
        }
        self.flush(d);
    }

    /// Where a frame the bridge sent (port `from`, global, and its serial) came from.
    pub(super) fn bridged_origin(&self, from: (u32, Option<u64>)) -> Option<Bridged> {
        let d = self.ports[from.0 as usize].dev as usize;
        if !self.is_bridge(d) {
            return None;
        }
        let slot = self.devices[d]
            .dev
            .as_any()
            .downcast_ref::<Slot<Bridge>>()?;
        slot.device.origin(from.1?)
    }
}
