//! Property of the clock contract in the dual-bus layer: a step back of the clock changes
//! nothing but the time line.
//!
//! Random traffic on both buses (frames on both, on one only, with skew and lag; repeats; pair
//! members that disagree; a watched heartbeat, bursts of it; the redundancy master's heartbeat;
//! outages of a bus; sends with transmit outcomes late, early or never; controller reports) is
//! run twice, driven sans-IO in each mode: once on a clock that only goes forward, and once with
//! random steps back inserted (from a microsecond to two hours; the driver says so once, at the
//! step, as the contract asks). Everything the layer does — each delivery, each frame for the
//! ports, each request, each event with every instant it carries, and its next deadline after
//! every input — is the same in both runs, the instants of the second run earlier by the steps
//! taken so far. Exactly, as long as no time the layer holds is older than the steps (the runs
//! start ten hours into the clock); a held time older than the step would land on the origin.

use crate::time_line::{same_time_line, step_size};
use duocan::machine::{BusLink, ErrorCause, LinkRequest, PortRequest, PortStatus};
use duocan::{Duration, Frame, Id, Instant, NodeId};
use duocan_redundancy::{
    Cia3026Config, DualBus, DualBusConfig, EcssConfig, LinkEvent, LinkEventKind, LinkMode, Member,
};
use proptest::prelude::*;

const MS: u64 = 1_000;
/// Where both runs start: later than all steps together.
const T0: u64 = 10 * 3600 * 1_000_000;

#[derive(Clone, Copy, Debug)]
enum Input {
    Rx(usize, Frame),
    Send(Frame),
    Status(usize, PortStatus),
}

/// One thing the traffic does, `gap` µs after the previous one.
#[derive(Clone, Copy, Debug)]
enum Op {
    /// A frame of `kind` (see [`frame`]) on bus 1 (`Some(0)`), bus 2 (`Some(1)`) or both
    /// (`None`), the second copy `skew` µs later, bus 2's copy `lag` µs late.
    Frame {
        kind: u8,
        v: u8,
        only: Option<usize>,
        first: usize,
        skew: u64,
        lag: u64,
    },
    /// Six heartbeats of the watched node 0.1 ms apart on one bus.
    Burst(usize),
    /// The node sends; each port's driver confirms after its delay, or never.
    Send {
        heartbeat: bool,
        v: u8,
        ok: [Option<u64>; 2],
    },
    /// A bus carries nothing for a while.
    Outage(usize, u64),
    /// A controller report.
    Report(usize, u8),
}

fn frame(kind: u8, v: u8) -> Frame {
    let std = |id, d: &[u8]| Frame::new(Id::Standard(id), d).unwrap();
    match kind % 7 {
        // Three senders' TPDOs: a value that may repeat.
        k @ 0..=2 => std(0x181 + u16::from(k), &[v]),
        // Pair members A (0x10) and B (0x11), TPDO 1: equal or not.
        3 => std(0x190, &[v % 2]),
        4 => std(0x191, &[v % 3]),
        // The watched node's heartbeat, and the redundancy master's.
        5 => std(0x710, &[5]),
        _ => std(0x701, &[5]),
    }
}

fn op() -> impl Strategy<Value = (u64, Op)> {
    let gap = prop_oneof![8 => 0..15 * MS, 1 => 100 * MS..500 * MS];
    let fr = (
        any::<u8>(),
        any::<u8>(),
        prop_oneof![6 => Just(None), 1 => Just(Some(0)), 1 => Just(Some(1))],
        0..2usize,
        0..300u64,
        prop_oneof![6 => Just(0), 1 => Just(12 * MS), 1 => Just(25 * MS), 1 => Just(60 * MS)],
    )
        .prop_map(|(kind, v, only, first, skew, lag)| Op::Frame {
            kind,
            v,
            only,
            first,
            skew,
            lag,
        });
    let delay = prop_oneof![4 => (0..30 * MS).prop_map(Some), 1 => Just(None)];
    let send = (any::<bool>(), any::<u8>(), [delay.clone(), delay])
        .prop_map(|(heartbeat, v, ok)| Op::Send { heartbeat, v, ok });
    let what = prop_oneof![
        12 => fr,
        1 => (0..2usize).prop_map(Op::Burst),
        3 => send,
        1 => (0..2usize, 100 * MS..800 * MS).prop_map(|(p, l)| Op::Outage(p, l)),
        1 => (0..2usize, any::<u8>()).prop_map(|(p, c)| Op::Report(p, c)),
    ];
    (gap, what)
}

/// The inputs of a traffic, in time order (µs after the start).
fn inputs(ops: &[(u64, Op)]) -> Vec<(u64, Input)> {
    let mut t = 0;
    let mut dead_until = [0u64; 2];
    let mut v = vec![];
    let arrive = |v: &mut Vec<(u64, Input)>, dead_until: &[u64; 2], at: u64, p: usize, f| {
        if at >= dead_until[p] {
            v.push((at, Input::Rx(p, f)));
        }
    };
    for &(gap, op) in ops {
        t += gap;
        match op {
            Op::Frame {
                kind,
                v: val,
                only,
                first,
                skew,
                lag,
            } => {
                let f = frame(kind, val);
                for p in 0..2 {
                    if only.is_some_and(|o| o != p) {
                        continue;
                    }
                    let at = t + if p == first { 0 } else { skew } + if p == 1 { lag } else { 0 };
                    arrive(&mut v, &dead_until, at, p, f);
                }
            }
            Op::Burst(p) => {
                for k in 0..6 {
                    arrive(&mut v, &dead_until, t + k * 100, p, frame(5, 0));
                }
            }
            Op::Send {
                heartbeat,
                v: val,
                ok,
            } => {
                let f = if heartbeat {
                    Frame::from_array(Id::Standard(0x705), [5])
                } else {
                    Frame::from_array(Id::Standard(0x205), [val])
                };
                v.push((t, Input::Send(f)));
                for (p, d) in ok.iter().enumerate() {
                    if let Some(d) = d {
                        v.push((t + d, Input::Status(p, PortStatus::TxOk)));
                    }
                }
            }
            Op::Outage(p, len) => dead_until[p] = t + len,
            Op::Report(p, c) => {
                let s = match c % 4 {
                    0 => PortStatus::Error(ErrorCause::ErrorPassive),
                    1 => PortStatus::Down(ErrorCause::InterfaceDown),
                    2 => PortStatus::Up,
                    _ => PortStatus::TxFailed(ErrorCause::NoAck),
                };
                v.push((t, Input::Status(p, s)));
            }
        }
    }
    // Stable: inputs at one instant keep the order they were made in.
    v.sort_by_key(|(t, _)| *t);
    v
}

/// What the layer did, its instants moved onto the reference time line.
#[derive(Clone, Debug, PartialEq)]
enum Seen {
    Up(bool),
    Tx(usize, Frame),
    Request(usize, PortRequest),
    Machine(LinkRequest),
    Event(LinkEvent),
    Due(Option<Instant>),
}

fn config(mode: u8) -> DualBusConfig {
    let mode = match mode % 3 {
        0 => LinkMode::ActiveActive,
        1 => {
            LinkMode::Cia302_6(Cia3026Config::default().with_max_tx_delay(Duration::from_millis(5)))
        }
        _ => LinkMode::EcssToggle(EcssConfig::slave(
            NodeId::must(1),
            Duration::from_millis(50),
        )),
    };
    DualBusConfig::default().with_mode(mode)
}

/// `e` with every instant it carries `by` later.
fn later(mut e: LinkEvent, by: Duration) -> LinkEvent {
    e.at += by;
    match &mut e.kind {
        LinkEventKind::Babbling { since, .. } | LinkEventKind::DuplicateNode { since, .. } => {
            *since += by
        }
        _ => {}
    }
    e
}

struct Driver {
    l: DualBus,
    /// The steps taken so far: this run's time line is that much earlier.
    shift: Duration,
    latest: Instant,
    seen: Vec<Seen>,
}

impl Driver {
    fn new(mode: u8) -> Driver {
        let mut l = DualBus::new(config(mode));
        l.add_pair(NodeId::must(0x10), NodeId::must(0x11), Some(Member::A))
            .unwrap();
        assert!(l.watch(NodeId::must(0x10), Duration::from_millis(100)));
        Driver {
            l,
            shift: Duration::ZERO,
            latest: Instant::ZERO,
            seen: vec![],
        }
    }
    fn local(&self, t: u64) -> Instant {
        Instant::from_micros(t) - self.shift
    }
    fn drain(&mut self) {
        while let Some((p, f)) = self.l.poll_transmit() {
            self.seen.push(Seen::Tx(p, f));
        }
        while let Some((p, r)) = self.l.poll_port_request() {
            self.seen.push(Seen::Request(p, r));
        }
        while let Some(r) = self.l.poll_machine_request() {
            self.seen.push(Seen::Machine(r));
        }
        while let Some(e) = self.l.poll_event() {
            self.seen.push(Seen::Event(later(e, self.shift)));
        }
    }
    /// A driver's loop up to `now`: each deadline when due (never before the latest time given).
    fn timers(&mut self, now: Instant) {
        for _ in 0..64 {
            match self.l.poll_timeout() {
                Some(d) if d <= now => {
                    self.latest = self.latest.max(d);
                    self.l.handle_timeout(self.latest);
                    self.drain();
                }
                _ => return,
            }
        }
        panic!("a deadline stays due at {now:?}");
    }
    /// The driver wakes up at `t` (reference µs), where its clock steps back `by`: it says so
    /// once.
    fn step(&mut self, t: u64, by: Duration) {
        let before = self.local(t);
        self.timers(before);
        self.l.handle_timeout(before);
        self.shift = self.shift + by;
        self.latest = self.local(t);
        self.l.handle_timeout(self.latest);
        self.drain();
    }
    fn input(&mut self, t: u64, input: Input) {
        let now = self.local(t);
        self.timers(now);
        self.latest = now;
        match input {
            Input::Rx(p, f) => {
                let up = self.l.handle_rx(now, p, &f).is_some();
                self.seen.push(Seen::Up(up));
            }
            Input::Send(f) => self.l.send(now, &f),
            Input::Status(p, s) => self.l.handle_port_status(now, p, s),
        }
        self.drain();
        let due = self.l.poll_timeout().map(|d| d + self.shift);
        self.seen.push(Seen::Due(due));
    }
}

/// Runs the traffic; `steps` are (input index, size): the clock steps back before that input.
fn run(mode: u8, inputs: &[(u64, Input)], steps: &[(usize, Duration)]) -> Vec<Seen> {
    let mut d = Driver::new(mode);
    d.l.handle_timeout(Instant::from_micros(T0));
    // The node boots (302-6 and ECSS start their windows and watches).
    d.input(T0, Input::Send(Frame::from_array(Id::Standard(0x705), [0])));
    for (i, &(t, input)) in inputs.iter().enumerate() {
        let t = T0 + t;
        for &(_, by) in steps.iter().filter(|(at, _)| *at == i) {
            // Both runs wake up here; only this one's clock steps.
            d.step(t, by);
        }
        d.input(t, input);
    }
    d.seen
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(192))]

    #[test]
    fn a_step_back_changes_nothing_but_the_time_line(
        mode in 0u8..3,
        ops in prop::collection::vec(op(), 20..250),
        steps in prop::collection::vec((any::<prop::sample::Index>(), step_size()), 1..5),
    ) {
        let inputs = inputs(&ops);
        prop_assume!(!inputs.is_empty());
        let steps: Vec<_> = steps.iter().map(|(i, by)| (i.index(inputs.len()), *by)).collect();
        // The reference wakes up where the other run steps, too (a wake-up with nothing due
        // changes nothing, but both drivers do the same).
        let wake_ups: Vec<_> = steps.iter().map(|(i, _)| (*i, Duration::ZERO)).collect();
        let reference = run(mode, &inputs, &wake_ups);
        let stepped = run(mode, &inputs, &steps);
        same_time_line(&reference, &stepped)?;
    }
}
