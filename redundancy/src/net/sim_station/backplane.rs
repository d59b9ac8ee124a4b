//! The simulated station's devices on its two buses: [`Backplane`].
//!
//! # The rule
//!
//! A frame sent on bus `p` — by a member on its port `p`, or from outside ([`Backplane::send`])
//! — waits for the bus (frames in the order they were sent), and when it takes the bus it
//! reaches the port `p` of every member but its sender; if a member sent it, the outside gets it
//! too ([`Backplane::poll_out`]). The bus is then busy for the frame's exact wire time at the
//! station's bit rate, so frames come no faster than the bus carries them. (Received as it
//! takes the bus rather than as it ends: one frame time early, which no device here can tell.)
//! That instant is each copy's receive timestamp: the members get it with the frame
//! ([`Device::handle_rx_at`]), and so does the outside.
//!
//! Everything runs in the caller's task, on the caller's clock. So the two copies of a frame a
//! member sends on both buses take them at the same instant and reach every other member together,
//! whatever the machine's load: a dual-bus layer on the station sees every twin at once, as it
//! would on two real buses. Devices that each ran in a runtime of their own, their two ports
//! read by two tasks, saw the copies as far apart as a loaded machine scheduled those tasks
//! (hundreds of milliseconds on two busy cores), past any merge window: twins delivered twice,
//! an SDO block acknowledgement taken twice, a transfer broken.
//!
//! # Time
//!
//! Each member has the clock of a device powered on when it joined: it sees the backplane's
//! time minus its power-on instant, as a runtime of its own would have shown it. The backplane
//! handles everything due in time order (the frames taking the buses, then the members'
//! deadlines, at each instant), so no member's clock steps back.
//!
//! It runs up to [`LEAD`] ahead of its caller's clock ([`Backplane::advance`], and
//! [`Backplane::wake_at`] for when to call it), as a CAN controller's queue lets a sender run
//! ahead of the wire: a request and its answer, a bus time apart, are carried in one call, not
//! each at the caller's next timer tick (tokio's is a millisecond: ten frames). A machine too
//! slow to keep up (a debug build carrying a full 1 Mbit/s bus to a dozen devices) falls behind
//! the caller's clock and catches up [`TURN_WORK`] deliveries and deadlines a call, due again at
//! once meanwhile: the caller's lock is never held for long.
//!
//! # Memory and overflow
//!
//! Each bus queues at most [`BUS_QUEUE`] frames waiting for the wire: beyond that a frame is
//! dropped and counted ([`BackplaneStats::dropped`]), never stored. What goes out is at most
//! one call's deliveries. What the members report (events, port requests) is drained and
//! dropped: the station's devices are watched over the buses, not through their own logs.
//!
//! ```text
//!  member A ──port 0──┐                 ┌── bus 0 (busy a wire time) ──> every other member's
//!           ──port 1──┼─> queue per bus ┤                       port 0, and poll_out (0, frame)
//!  send(p, …) ────────┘                 └── bus 1 (busy a wire time) ──> … port 1, (1, frame)
//! ```

use alloc::boxed::Box;
use alloc::collections::VecDeque;
use alloc::vec::Vec;
use core::any::Any;
use duocan::frame::instant::earliest_of;
use duocan::machine::Device;
use duocan::sim::timing::frame_duration;
use duocan::{Duration, Frame, Instant};

/// Most frames waiting for one bus: a sub-block of an SDO block transfer (127 segments) from
/// each of several senders, with room to spare.
pub(super) const BUS_QUEUE: usize = 1024;
/// Most deliveries and deadlines handled in one call to [`Backplane::advance`].
pub(super) const TURN_WORK: u32 = 64;
/// How far ahead of the caller's clock the backplane runs (see the module docs, "Time").
pub(super) const LEAD: Duration = Duration::from_millis(2);
/// The sender of a frame from outside.
const OUTSIDE: u32 = 0;

/// A device on the backplane: [`Device`] without its event type.
pub(super) trait Member: Send {
    /// A frame that took bus `port` at `now`: stamped with that instant.
    fn handle_rx_at(&mut self, now: Instant, port: usize, frame: &Frame);
    fn handle_timeout(&mut self, now: Instant);
    fn poll_transmit(&mut self) -> Option<(usize, Frame)>;
    fn poll_timeout(&self) -> Option<Instant>;
    /// Drops what the device reports: its events and its requests to port drivers.
    fn drain(&mut self);
    fn as_any_mut(&mut self) -> &mut dyn Any;
}

impl<D: Device + Send + 'static> Member for D {
    fn handle_rx_at(&mut self, now: Instant, port: usize, frame: &Frame) {
        Device::handle_rx_at(self, now, port, frame, now);
    }
    fn handle_timeout(&mut self, now: Instant) {
        Device::handle_timeout(self, now);
    }
    fn poll_transmit(&mut self) -> Option<(usize, Frame)> {
        Device::poll_transmit(self)
    }
    fn poll_timeout(&self) -> Option<Instant> {
        Device::poll_timeout(self)
    }
    fn drain(&mut self) {
        while self.poll_event().is_some() {}
        while self.poll_port_request().is_some() {}
    }
    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }
}

/// A powered member: its tag (the node-ID the station knows it by), when it was powered on,
/// and a serial that tells it from a member powered on later with the same tag.
struct Slot {
    tag: u8,
    serial: u32,
    origin: Instant,
    dev: Box<dyn Member>,
    /// The device's deadline on the backplane's clock, as it gave it after its last input:
    /// asked once an input, not at every instant.
    due: Option<Instant>,
}

impl Slot {
    /// The member's own time at the backplane's `t` (see the module docs, "Time").
    fn local(&self, t: Instant) -> Instant {
        Instant::ZERO + t.saturating_since(self.origin)
    }
}

/// A frame for a bus: its sender's serial ([`OUTSIDE`] for the outside) and the instant it
/// was sent, before which it cannot take the wire.
#[derive(Clone, Copy)]
struct Sent {
    from: u32,
    at: Instant,
    frame: Frame,
}

/// One bus: when it is free again, and the frames waiting for it.
#[derive(Default)]
struct Bus {
    free: Instant,
    waiting: VecDeque<Sent>,
}

impl Bus {
    /// When the first waiting frame takes the bus: once the bus is free and the frame sent.
    fn next_start(&self) -> Option<Instant> {
        self.waiting.front().map(|s| self.free.max(s.at))
    }
}

/// What a backplane has counted.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) struct BackplaneStats {
    /// Frames carried by a bus (each bus counts its own).
    pub(super) carried: u64,
    /// Frames dropped because their bus's queue was full.
    pub(super) dropped: u64,
    /// Calls to [`Backplane::advance`] that ended at [`TURN_WORK`] with more due: the
    /// backplane was behind its caller's clock.
    pub(super) behind: u64,
}

/// The station's members on two buses (see the module docs).
pub(super) struct Backplane {
    members: Vec<Slot>,
    next_serial: u32,
    bit_rate: u32,
    buses: [Bus; 2],
    /// Frames members sent that a bus carried, for the outside, with the instant the bus took
    /// each.
    out: VecDeque<(usize, Frame, Instant)>,
    /// The instant handled last: no member is given an earlier one.
    t: Instant,
    stats: BackplaneStats,
}

impl Backplane {
    /// An empty backplane whose buses run at `bit_rate` bit/s.
    pub(super) fn new(bit_rate: u32) -> Self {
        Backplane {
            members: Vec::new(),
            next_serial: OUTSIDE,
            bit_rate: bit_rate.max(1),
            buses: [Bus::default(), Bus::default()],
            out: VecDeque::new(),
            t: Instant::ZERO,
            stats: BackplaneStats::default(),
        }
    }

    /// Powers `dev` on as member `tag`, at the instant handled last: its clock starts then.
    pub(super) fn power_on(&mut self, tag: u8, dev: Box<dyn Member>) {
        self.next_serial = self.next_serial.wrapping_add(1).max(OUTSIDE + 1);
        self.members.push(Slot {
            tag,
            serial: self.next_serial,
            origin: self.t,
            dev,
            due: None,
        });
        self.sent_by(self.members.len() - 1);
    }

    /// Powers the members tagged `tag` off; what they queued still goes out, as a
    /// controller's last frames do.
    pub(super) fn power_off(&mut self, tag: u8) {
        self.members.retain(|m| m.tag != tag);
    }

    /// Whether a member `tag` is powered.
    pub(super) fn is_on(&self, tag: u8) -> bool {
        self.members.iter().any(|m| m.tag == tag)
    }

    /// The tags of the powered members of type `D` for which `f` holds. What `f` makes a
    /// member send goes to its buses, as after any input.
    pub(super) fn find<D: 'static>(&mut self, mut f: impl FnMut(&mut D) -> bool) -> Vec<u8> {
        let mut found = Vec::new();
        for i in 0..self.members.len() {
            let m = &mut self.members[i];
            if let Some(d) = m.dev.as_any_mut().downcast_mut::<D>() {
                if f(d) {
                    found.push(m.tag);
                }
                self.sent_by(i);
            }
        }
        found
    }

    /// `f` on the first member `tag`, if it is powered and a `D`; what `f` makes it send goes
    /// to its buses.
    pub(super) fn with<D: 'static, R>(
        &mut self,
        tag: u8,
        f: impl FnOnce(&mut D) -> R,
    ) -> Option<R> {
        let i = self.members.iter().position(|m| m.tag == tag)?;
        let r = self.members[i].dev.as_any_mut().downcast_mut::<D>().map(f);
        self.sent_by(i);
        r
    }

    /// What the backplane has counted (the tests' view: the station is watched over its buses).
    #[cfg(test)]
    pub(super) fn stats(&self) -> BackplaneStats {
        self.stats
    }

    /// Sends `frame` on bus `p` from outside at `now` (ports other than 0 and 1: ignored).
    pub(super) fn send(&mut self, p: usize, frame: Frame, now: Instant) {
        let at = now.max(self.t);
        self.queue(
            p,
            Sent {
                from: OUTSIDE,
                at,
                frame,
            },
        );
    }

    /// The next frame a member sent that a bus carried, with the bus and the instant it took
    /// the bus (on the caller's clock: up to [`LEAD`] ahead of it).
    pub(super) fn poll_out(&mut self) -> Option<(usize, Frame, Instant)> {
        self.out.pop_front()
    }

    /// The next instant with work, a frame taking a bus or a member's deadline; never before
    /// the instant handled last.
    fn next_due(&self) -> Option<Instant> {
        let starts = self.buses.iter().map(Bus::next_start);
        let members = self.members.iter().map(|m| m.due);
        earliest_of(starts.chain(members)).map(|d| d.max(self.t))
    }

    /// When the caller is to call [`Backplane::advance`] next: [`LEAD`] before the next
    /// instant with work.
    pub(super) fn wake_at(&self) -> Option<Instant> {
        self.next_due().map(|d| d.saturating_sub(LEAD))
    }

    /// Handles everything due up to [`LEAD`] after `now` in time order, at most [`TURN_WORK`]
    /// deliveries and deadlines (see the module docs, "Time").
    pub(super) fn advance(&mut self, now: Instant) {
        let mut work = 0;
        let until = now.saturating_add(LEAD);
        while let Some(t) = self.next_due().filter(|t| *t <= until) {
            if work >= TURN_WORK {
                self.stats.behind += 1;
                return;
            }
            self.t = t;
            for p in 0..2 {
                work += self.carry(p, t);
            }
            for i in 0..self.members.len() {
                if self.members[i].due.is_some_and(|d| d <= t) {
                    let local = self.members[i].local(t);
                    self.members[i].dev.handle_timeout(local);
                    self.sent_by(i);
                    work += 1;
                }
            }
        }
        self.t = self.t.max(now);
    }

    /// Queues `s` for bus `p` (dropped and counted when the queue is full).
    fn queue(&mut self, p: usize, s: Sent) {
        let Some(bus) = self.buses.get_mut(p) else {
            return;
        };
        if bus.waiting.len() >= BUS_QUEUE {
            self.stats.dropped += 1;
            return;
        }
        bus.waiting.push_back(s);
    }

    /// After an input to member `i`: its new deadline, and its frames to their buses (ports
    /// other than 0 and 1: dropped).
    fn sent_by(&mut self, i: usize) {
        let m = &mut self.members[i];
        m.due = m
            .dev
            .poll_timeout()
            .map(|d| m.origin.saturating_add(d.saturating_since(Instant::ZERO)));
        m.dev.drain();
        let from = m.serial;
        while let Some((p, frame)) = self.members[i].dev.poll_transmit() {
            let at = self.t;
            self.queue(p, Sent { from, at, frame });
        }
    }

    /// Puts bus `p`'s first waiting frame on the bus if it takes it at `t`: it reaches every
    /// member but its sender, and the outside if a member sent it, and the bus is busy for its
    /// wire time. 1 if a frame was carried.
    fn carry(&mut self, p: usize, t: Instant) -> u32 {
        let bus = &mut self.buses[p];
        if bus.next_start().is_none_or(|start| start > t) {
            return 0;
        }
        let Some(s) = bus.waiting.pop_front() else {
            return 0;
        };
        bus.free = t + frame_duration(&s.frame, self.bit_rate);
        self.stats.carried += 1;
        if s.from != OUTSIDE {
            self.out.push_back((p, s.frame, t));
        }
        for i in 0..self.members.len() {
            if self.members[i].serial != s.from {
                let local = self.members[i].local(t);
                self.members[i].dev.handle_rx_at(local, p, &s.frame);
                self.sent_by(i);
            }
        }
        1
    }
}
