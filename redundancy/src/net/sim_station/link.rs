//! The station inside the network that a tool opens on it: [`StationLink`], the network's
//! dual-bus layer on the station's [`Backplane`], with the station's script and the connector
//! of the network's bus-1 port.
//!
//! The network runs its link in its own task, under its own lock; so does everything here: the
//! network's two ports, the station's buses and devices, the script. Nothing in between is
//! carried by a task of its own, so no copy of a frame can fall behind its twin on the way.
//! The network's runtime gets two [`StationPort`]s, which carry nothing: they are there for
//! their names and counters, which the link keeps as a port's driver would.

use super::backplane::Backplane;
use super::{active_member, master, new_board, Net, SIM_PAIRS};
use super::{
    B_POWERED, SIM_FAULT_BUS_BACK, SIM_FAULT_BUS_CUT, SIM_FAULT_MASTER_BACK,
    SIM_FAULT_MASTER_STOPS, SIM_FAULT_MEMBER_BACK, SIM_FAULT_MEMBER_STOPS, SIM_FAULT_PERIOD,
};
use crate::net::dual_link::DualLink;
use alloc::collections::VecDeque;
use alloc::sync::Arc;
use core::convert::Infallible;
use duocan::capture::recorder::{Tap, TapDirection, TapPoint};
use duocan::machine::{BusLink, ErrorCause, PortRequest, PortStatus};
use duocan::net::{HeardOn, NetEvent, NetLink};
use duocan::port::{Port, PortCounters, PortError, PortInput};
use duocan::{Duration, Frame, Instant, NodeId};

/// What the station's script does, at an instant of the network's clock.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Step {
    /// The B members are powered (they boot later than A, so that A is configured first and
    /// is the active member).
    PowerB,
    /// The network's connection to bus 1 is cut.
    Cut,
    /// It is plugged back in.
    PlugIn,
    /// The active member of the first pair stops.
    MemberStops,
    /// The boards that are off are powered again.
    MemberBack,
    /// The active master stops.
    MasterStops,
    /// The masters that are off are powered again.
    MasterBack,
}

/// One period of the fault script.
const PERIOD: [(Duration, Step); 6] = [
    (SIM_FAULT_BUS_CUT, Step::Cut),
    (SIM_FAULT_BUS_BACK, Step::PlugIn),
    (SIM_FAULT_MEMBER_STOPS, Step::MemberStops),
    (SIM_FAULT_MEMBER_BACK, Step::MemberBack),
    (SIM_FAULT_MASTER_STOPS, Step::MasterStops),
    (SIM_FAULT_MASTER_BACK, Step::MasterBack),
];

/// Where the script is: the B members not powered yet, or the next step of a period.
#[derive(Clone, Copy, Debug)]
pub(super) struct Script {
    faults: bool,
    b_powered: bool,
    base: Duration,
    step: usize,
}

impl Script {
    /// The script with the fault periods (`faults`) or without.
    pub(super) fn new(faults: bool) -> Self {
        Script {
            faults,
            b_powered: false,
            base: Duration::ZERO,
            step: 0,
        }
    }
    /// The next step and its instant, if any.
    fn next(&self) -> Option<(Instant, Step)> {
        if !self.b_powered {
            return Some((Instant::ZERO + B_POWERED, Step::PowerB));
        }
        let (at, step) = PERIOD.get(self.step).filter(|_| self.faults)?;
        Some((Instant::ZERO + self.base + *at, *step))
    }
    /// Past the step [`Script::next`] gave.
    fn done(&mut self) {
        if !self.b_powered {
            self.b_powered = true;
        } else {
            self.step += 1;
            if self.step == PERIOD.len() {
                self.step = 0;
                self.base = self.base + SIM_FAULT_PERIOD;
            }
        }
    }
}

/// A port of the network on the station: it carries nothing itself (the [`StationLink`] does,
/// in the network's own task) and keeps the counters the link updates.
#[derive(Debug)]
pub(super) struct StationPort {
    name: &'static str,
    counters: PortCounters,
}

impl StationPort {
    pub(super) fn new(name: &'static str) -> Self {
        StationPort {
            name,
            counters: PortCounters::new(),
        }
    }
}

impl Port for StationPort {
    fn name(&self) -> &str {
        self.name
    }
    fn counters(&self) -> PortCounters {
        self.counters.clone()
    }
    async fn recv(&mut self) -> Result<PortInput, PortError> {
        core::future::pending().await
    }
    async fn send(&mut self, _: &Frame) -> Result<(), PortError> {
        Ok(())
    }
    async fn reopen(&mut self) -> Result<(), PortError> {
        Ok(())
    }
}

/// The network's dual-bus layer on the station (see the module docs).
pub(super) struct StationLink<L> {
    link: L,
    station: Backplane,
    script: Script,
    /// The network's connection to bus 1 is cut.
    cut: bool,
    /// The counters of the network's two [`StationPort`]s.
    counters: [PortCounters; 2],
    /// What the ports read and reported, for the network ([`NetLink::poll_input`]): frames
    /// stamped with the instant their bus took them.
    inputs: VecDeque<(usize, PortInput<Instant>)>,
    /// Told of every frame the ports carry, as the runtime tells it of real ports' frames.
    tap: Option<Arc<dyn Tap>>,
    now: Instant,
}

impl<L: NetLink> StationLink<L> {
    /// An input's instant: what the network's frames are routed out with until the next.
    fn mark(&mut self, now: Instant) {
        self.now = now;
    }
    /// `link` on `station`, with the counters of the network's `ports` and the network's
    /// `tap`.
    pub(super) fn new(
        link: L,
        station: Backplane,
        script: Script,
        ports: &[StationPort; 2],
        tap: Option<Arc<dyn Tap>>,
    ) -> Self {
        StationLink {
            link,
            station,
            script,
            cut: false,
            counters: [ports[0].counters(), ports[1].counters()],
            inputs: VecDeque::new(),
            tap,
            now: Instant::ZERO,
        }
    }

    fn tap(&self, now: Instant, port: usize, dir: TapDirection, f: &Frame) {
        if let Some(t) = &self.tap {
            t.frame(now, TapPoint::Port(port), dir, f);
        }
    }

    /// The network's frames to the station's buses; on bus 1 while it is cut, dropped.
    fn route_out(&mut self, now: Instant) {
        while let Some((p, f)) = self.link.poll_transmit() {
            let Some(c) = self.counters.get(p) else {
                continue;
            };
            if p == 0 && self.cut {
                c.tx_dropped();
            } else {
                c.tx_frames();
                self.tap(now, p, TapDirection::Tx, &f);
                self.station.send(p, f, now);
            }
        }
    }

    /// The link's requests to the ports' drivers, answered as a driver does: a re-opened port
    /// is up; while its connector is pulled it stays down (the driver keeps trying) and is up
    /// once it is plugged in again.
    fn serve_requests(&mut self) {
        while let Some((p, PortRequest::Reinit)) = self.link.poll_port_request() {
            if p != 0 || !self.cut {
                self.inputs
                    .push_back((p, PortInput::Status(PortStatus::Up)));
            }
        }
    }

    /// The script's steps due by `now`.
    fn play(&mut self, now: Instant) {
        while let Some((at, step)) = self.script.next().filter(|(at, _)| *at <= now) {
            self.station.advance(at);
            self.script.done();
            self.step(step);
        }
    }

    fn step(&mut self, step: Step) {
        let s = &mut self.station;
        let boards = SIM_PAIRS.iter().flat_map(|&(a, b)| [a, b]);
        match step {
            Step::PowerB => power_boards(s, SIM_PAIRS.iter().map(|p| p.1)),
            Step::Cut => {
                self.cut = true;
                let down = PortStatus::Down(ErrorCause::InterfaceDown);
                self.inputs.push_back((0, PortInput::Status(down)));
            }
            Step::PlugIn => {
                self.cut = false;
                self.counters[0].reopened();
                self.inputs
                    .push_back((0, PortInput::Status(PortStatus::Up)));
            }
            Step::MemberStops => {
                if let Some(member) = active_member(s) {
                    s.power_off(member);
                }
            }
            Step::MemberBack => power_boards(s, boards),
            Step::MasterStops => {
                for id in s.find::<Net>(|n| n.role().is_active()) {
                    s.power_off(id);
                }
            }
            Step::MasterBack => {
                for id in [1, 2] {
                    if !s.is_on(id) {
                        if let Ok(m) = master(id) {
                            s.power_on(id, m);
                        }
                    }
                }
            }
        }
    }
}

/// Powers on the boards of `members` that are off, new and booting.
fn power_boards(station: &mut Backplane, members: impl Iterator<Item = u8>) {
    for id in members {
        if !station.is_on(id) {
            station.power_on(id, new_board(id));
        }
    }
}

impl<L: NetLink> BusLink for StationLink<L> {
    type Event = NetEvent;
    type Command = Infallible;
    fn port_count(&self) -> usize {
        2
    }
    // A frame this link handed to the network (poll_input), back on its way up; a status.
    duocan::forward_bus_link!(link, before = mark; handle_rx, handle_rx_at, handle_port_status);
    fn send(&mut self, now: Instant, frame: &Frame) {
        self.now = now;
        self.link.send(now, frame);
        self.route_out(now);
    }
    fn poll_transmit(&mut self) -> Option<(usize, Frame)> {
        // Nothing for the runtime's ports: the network's frames go to the station's buses.
        self.route_out(self.now);
        None
    }
    fn poll_port_request(&mut self) -> Option<(usize, PortRequest)> {
        self.serve_requests();
        None
    }
    fn handle_timeout(&mut self, now: Instant) {
        self.now = now;
        self.link.handle_timeout(now);
        self.play(now);
        self.station.advance(now);
        while let Some((p, f, wire)) = self.station.poll_out() {
            if p == 0 && self.cut {
                continue;
            }
            if let Some(c) = self.counters.get(p) {
                c.rx_frames();
                // The backplane runs up to its lead ahead: a frame is not received before now.
                let at = wire.min(now);
                self.tap(at, p, TapDirection::Rx, &f);
                self.inputs.push_back((p, PortInput::Frame(f, Some(at))));
            }
        }
        self.route_out(now);
        self.serve_requests();
    }
    fn poll_timeout(&self) -> Option<Instant> {
        let inputs = (!self.inputs.is_empty()).then_some(self.now);
        let script = self.script.next().map(|(at, _)| at);
        duocan::frame::instant::earliest_of([
            self.link.poll_timeout(),
            self.station.wake_at(),
            script,
            inputs,
        ])
    }
    duocan::forward_bus_link!(link; poll_event, poll_machine_request);
}

impl<L: NetLink> NetLink for StationLink<L> {
    fn port_state(&self, port: usize) -> Option<crate::PortState> {
        self.link.port_state(port)
    }
    fn heard_on(&self, node: NodeId) -> Option<HeardOn> {
        self.link.heard_on(node)
    }
    fn poll_input(&mut self) -> Option<(usize, PortInput<Instant>)> {
        self.inputs.pop_front()
    }
}

/// The station's link as the network's.
pub(super) type SimLink = StationLink<DualLink>;
