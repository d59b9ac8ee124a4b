//! The plausibility table's tests: the rig that drives it, and what concerns the table as a
//! whole (the clock, a full machine queue, its bounds); each rule's tests in its own file.

use super::*;
use crate::link::events::{LinkEvent, LinkEventKind, Suspicion};
use crate::link::health::{Health, HealthConfig, PortState, RxOutcome};
use crate::link::outbox::{Outbox, MACHINE_QUEUE};
use duocan_core::frame::instant::TimeWatch;
use duocan_core::machine::{ErrorCause, LinkRequest, PortStatus};
use duocan_core::{Frame, Id};
use std::vec::Vec;

const T: Duration = Duration::from_millis(12);
const W: Duration = Duration::from_millis(36);

fn us(x: u64) -> Instant {
    Instant::from_micros(x)
}
fn ms(x: u64) -> Instant {
    Instant::from_millis(x)
}
fn hb(node: u8, state: u8) -> Frame {
    Frame::from_array(Id::Standard(0x700 + node as u16), [state])
}
fn n(x: u8) -> NodeId {
    NodeId::must(x)
}

struct Rig {
    p: Plausibility,
    health: Health,
    out: Outbox,
    /// What the layer does for its parts: notices the clock stepping back.
    clock: TimeWatch,
}

impl Rig {
    fn new() -> Rig {
        let mut p = Plausibility::new(Some(W));
        for node in [0x10, 0x50] {
            assert!(p.watch(n(node), T));
        }
        Rig {
            p,
            health: Health::new(HealthConfig::default(), Duration::from_millis(10)),
            out: Outbox::new(),
            clock: TimeWatch::new(),
        }
    }
    fn notice(&mut self, now: Instant) {
        if let Some(by) = self.clock.step_back(now) {
            self.p.step_back(by);
        }
    }
    /// Runs the deadlines up to `t`, then hands the heartbeat over; true if dropped.
    fn beat(&mut self, t: Instant, port: usize, node: u8, state: u8) -> bool {
        self.run(t);
        self.notice(t);
        self.p.on_heartbeat(
            t,
            port,
            n(node),
            &hb(node, state),
            &self.health,
            &mut self.out,
        )
    }
    /// The layer handed a frame to `port` (port health counts it waiting).
    fn handed(&mut self, t: Instant, port: usize) {
        self.health.count_tx(t, port, 0);
        self.p.on_handed(t, port);
    }
    /// The driver reported `status` for `port`'s oldest waiting frame.
    fn confirmed(&mut self, t: Instant, port: usize, status: PortStatus) {
        self.health.on_status(t, port, status, &mut self.out);
        self.p.on_status(t, port, status, &self.health);
    }
    fn run(&mut self, until: Instant) {
        while let Some(d) = self.p.poll_timeout().filter(|d| *d <= until) {
            self.notice(d);
            self.p.handle_timeout(d, &self.health, &mut self.out);
        }
    }
    fn requests(&mut self) -> Vec<(u8, bool)> {
        core::iter::from_fn(|| self.out.machine.pop())
            .map(|r| match r {
                LinkRequest::NodeSuspect { node, suspect, .. } => (node.raw(), suspect),
                other => panic!("{other:?}"),
            })
            .collect()
    }
    fn events(&mut self) -> Vec<LinkEvent> {
        core::iter::from_fn(|| self.out.events.pop()).collect()
    }
}

#[test]
fn a_clock_step_back_is_no_burst() {
    let mut r = Rig::new();
    let mut t = 1_000;
    for _ in 0..10 {
        r.beat(ms(t), 0, 0x10, 5);
        t += 12;
    }
    // The clock steps back by more than a second; the heartbeats go on at their pace: without
    // the bucket moving back with the clock they would look a second too early.
    let mut t = 5;
    for _ in 0..10 {
        assert!(!r.beat(ms(t), 0, 0x10, 5));
        t += 12;
    }
    assert!(r.requests().is_empty());
}

#[test]
fn a_full_machine_queue_delays_the_verdict_to_the_next_input_never_loses_it() {
    let mut r = Rig::new();
    for _ in 0..MACHINE_QUEUE {
        r.out.machine(LinkRequest::EnterPreOperational);
    }
    for k in 0..6 {
        r.beat(us(100_000 + k * 10), 0, 0x10, 5);
    }
    assert_eq!(r.out.machine.len(), MACHINE_QUEUE);
    while r.out.machine.pop().is_some() {}
    r.beat(us(100_100), 1, 0x50, 0x7F);
    assert_eq!(r.requests(), [(0x10, true)]);
}

#[test]
fn the_table_is_bounded_and_watches_can_end() {
    let mut p = Plausibility::new(None);
    assert!(p.is_empty());
    for k in 1..=127u8 {
        assert!(p.watch(n(k), T));
    }
    assert!(
        p.watch(n(5), T.saturating_mul(2)),
        "a new period for a watched node"
    );
    assert_eq!(p.refused(), 0);
    assert_eq!(p.iter().count(), 127);
    assert!(p.watch(n(5), Duration::ZERO));
    assert_eq!(p.is_suspect(n(5)), None);
    assert_eq!(p.is_suspect(n(6)), Some(false));
    assert_eq!(p.iter().count(), 126);
}

#[test]
fn a_table_sized_for_a_few_members_takes_them_and_refuses_one_more() {
    let mut p = Plausibility::with_capacity(None, 2);
    assert!(p.watch(n(0x10), T) && p.watch(n(0x50), T));
    assert!(
        p.watch(n(0x10), T.saturating_mul(2)),
        "a new period is no new entry"
    );
    assert!(!p.watch(n(0x11), T));
    assert_eq!(p.refused(), 1);
    assert_eq!(p.iter().count(), 2);
    // A watch that ends frees its room.
    assert!(p.watch(n(0x50), Duration::ZERO));
    assert!(p.watch(n(0x11), T));
    assert_eq!(p.refused(), 1);
}

mod rule_one;
mod rule_two;
