//! Property of the clock contract in the supervisor: a step back of the clock changes nothing
//! but the time line.
//!
//! A supervisor (CiA 302-2 master, one pair 0x10/0x11, a declared peer master, node 2) is driven
//! sans-IO with random traffic: the members' boot-ups and heartbeats in every state, the peer's
//! heartbeat and boot-up, flying-master frames from better and worse ranks, foreign SYNCs and NMT
//! commands, the dual-bus layer's verdicts on the members' heartbeats, and members that answer
//! the master's SDO requests (so that they join) or stay mute. It runs twice: once on a clock
//! that only goes forward, and once with random steps back inserted (from a microsecond to two
//! hours; the driver says so once, at the step, as the contract asks). Every frame it sends, every
//! command to the layer, every event with every instant it carries, and its next deadline after
//! every input are the same in both runs, the instants of the second run earlier by the steps
//! taken so far. Exactly, as long as no time held is older than the steps (the runs start ten
//! hours into the clock).

use crate::time_line::{same_time_line, step_size};
use duocan::machine::{LinkRequest, Machine};
use duocan::master::{objects, Master, MasterConfig};
use duocan::od::{comm, DynamicDictionary};
use duocan::{Duration, Frame, Id, Instant, NodeId};
use duocan_redundancy::{LinkCommand, PairSpec, Supervisor, SupervisorConfig};
use proptest::prelude::*;

const MS: u64 = 1_000;
/// Where both runs start: later than all steps together.
const T0: u64 = 10 * 3600 * 1_000_000;

#[derive(Clone, Copy, Debug)]
enum Input {
    Rx(Frame),
    Verdict(u8, bool, bool),
    /// Member 0x10 + i answers the master's SDO requests from now on (or not).
    Answer(usize, bool),
}

fn std(id: u16, d: &[u8]) -> Frame {
    Frame::new(Id::Standard(id), d).unwrap()
}

/// A frame of `kind`, `v` choosing the variant.
fn frame(kind: u8, v: u8) -> Frame {
    const STATES: [u8; 4] = [0x00, 0x05, 0x7F, 0x04];
    match kind % 6 {
        // A member's boot-up or heartbeat.
        0 | 1 => std(0x710 + u16::from(v & 1), &[STATES[usize::from(v >> 1) % 4]]),
        // The peer master's.
        2 => std(0x702, &[STATES[usize::from(v) % 3]]),
        // A flying-master frame, ranked better or worse than this master, or from the peer.
        3 => {
            let id = 0x71 + u16::from(v % 6);
            std(id, &[(v >> 3) % 3, [2, 3][usize::from(v >> 5) & 1]])
        }
        // A foreign SYNC.
        4 => std(0x80, &[]),
        // An NMT command from another master.
        _ => std(
            0x000,
            &[[0x01, 0x80, 0x81][usize::from(v) % 3], 0x10 + (v & 1)],
        ),
    }
}

fn op() -> impl Strategy<Value = (u64, Input)> {
    let gap = prop_oneof![8 => 0..15 * MS, 1 => 30 * MS..300 * MS];
    let what = prop_oneof![
        12 => (any::<u8>(), any::<u8>()).prop_map(|(k, v)| Input::Rx(frame(k, v))),
        1 => (0u8..2, any::<bool>(), any::<bool>())
            .prop_map(|(n, s, d)| Input::Verdict(0x10 + n, s, s && d)),
        1 => (0usize..2, prop::bool::weighted(0.8)).prop_map(|(m, a)| Input::Answer(m, a)),
    ];
    (gap, what)
}

/// What the supervisor did, its instants moved onto the reference time line.
#[derive(Clone, Debug, PartialEq)]
enum Seen {
    Tx(Frame),
    Link(LinkCommand),
    /// The event's `Debug` text, every instant in it moved.
    Event(String),
    Due(Option<Instant>),
}

/// `text` with every instant in it (`Display`: seconds with six decimals) `by` later.
fn later(text: &str, by: Duration) -> String {
    let b = text.as_bytes();
    let mut out = String::new();
    let mut i = 0;
    while i < b.len() {
        let start = i;
        while i < b.len() && b[i].is_ascii_digit() {
            i += 1;
        }
        let whole = i > start && (start == 0 || !b[start - 1].is_ascii_alphanumeric());
        let frac = i + 8 <= b.len()
            && b[i] == b'.'
            && b[i + 1..i + 7].iter().all(u8::is_ascii_digit)
            && b[i + 7] == b's'
            && b.get(i + 8).is_none_or(|c| !c.is_ascii_alphanumeric());
        if whole && frac {
            let us: u64 = format!("{}{}", &text[start..i], &text[i + 1..i + 7])
                .parse()
                .unwrap();
            out.push_str(&(Instant::from_micros(us) + by).to_string());
            i += 8;
        } else if i > start {
            out.push_str(&text[start..i]);
        } else {
            out.push(b[i] as char);
            i += 1;
        }
    }
    out
}

struct Driver {
    s: Supervisor<DynamicDictionary>,
    /// The steps taken so far: this run's time line is that much earlier.
    shift: Duration,
    latest: Instant,
    answering: [bool; 2],
    seen: Vec<Seen>,
}

impl Driver {
    fn new() -> Driver {
        let t0 = Instant::from_micros(T0);
        let ms = Duration::from_millis;
        let od = objects::master_dictionary(1, comm::Identity::default());
        let master = Master::new(NodeId::must(1), od, MasterConfig::new()).unwrap();
        let cfg = SupervisorConfig::new(0, NodeId::must(1), ms(20), ms(50), ms(10))
            .with_peer(1, NodeId::must(2));
        let mut s = Supervisor::new(master, cfg, t0);
        s.add_pair(
            t0,
            PairSpec::new(NodeId::must(0x10), NodeId::must(0x11), ms(20), ms(50)),
        )
        .unwrap();
        let mut d = Driver {
            s,
            shift: Duration::ZERO,
            latest: t0,
            answering: [true; 2],
            seen: vec![],
        };
        d.drain(t0);
        d
    }
    fn local(&self, t: u64) -> Instant {
        Instant::from_micros(t) - self.shift
    }
    /// Everything the supervisor queued; a member that answers confirms each expedited SDO
    /// request at once (an upload reads 0).
    fn drain(&mut self, now: Instant) {
        loop {
            let mut answers = vec![];
            while let Some(f) = self.s.poll_transmit() {
                self.seen.push(Seen::Tx(f));
                let Id::Standard(id) = f.id() else { continue };
                let m = usize::from(id.wrapping_sub(0x610));
                if m < 2 && self.answering[m] && f.dlc() == 8 {
                    let d = f.data();
                    let cs = if d[0] & 0xE0 == 0x40 { 0x43 } else { 0x60 };
                    answers.push(std(0x590 + m as u16, &[cs, d[1], d[2], d[3], 0, 0, 0, 0]));
                }
            }
            while let Some(c) = self.s.poll_link_command() {
                self.seen.push(Seen::Link(c));
            }
            while let Some(e) = self.s.poll_event() {
                self.seen
                    .push(Seen::Event(later(&format!("{e:?}"), self.shift)));
            }
            if answers.is_empty() {
                return;
            }
            for f in answers {
                self.s.handle_frame(now, &f);
            }
        }
    }
    /// A driver's loop up to `now`: each deadline when due (never before the latest time given).
    fn timers(&mut self, now: Instant) {
        for _ in 0..256 {
            match self.s.poll_timeout() {
                Some(d) if d <= now => {
                    self.latest = self.latest.max(d);
                    self.s.handle_timeout(self.latest);
                    self.drain(self.latest);
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
        self.s.handle_timeout(before);
        self.drain(before);
        self.shift = self.shift + by;
        self.latest = self.local(t);
        self.s.handle_timeout(self.latest);
        self.drain(self.latest);
    }
    fn input(&mut self, t: u64, input: Input) {
        let now = self.local(t);
        self.timers(now);
        self.latest = now;
        match input {
            Input::Rx(f) => self.s.handle_frame(now, &f),
            Input::Verdict(node, suspect, duplicated) => {
                let node = NodeId::must(node);
                let req = LinkRequest::NodeSuspect {
                    node,
                    suspect,
                    duplicated,
                };
                self.s.handle_link_request(now, req);
            }
            Input::Answer(m, on) => self.answering[m] = on,
        }
        self.drain(now);
        let due = self.s.poll_timeout().map(|d| d + self.shift);
        self.seen.push(Seen::Due(due));
    }
}

/// Runs the traffic; `steps` are (input index, size): the clock steps back before that input.
fn run(ops: &[(u64, Input)], steps: &[(usize, Duration)]) -> Vec<Seen> {
    let mut d = Driver::new();
    let mut t = T0;
    for (i, &(gap, input)) in ops.iter().enumerate() {
        t += gap;
        for &(_, by) in steps.iter().filter(|(at, _)| *at == i) {
            // Both runs wake up here; only this one's clock steps.
            d.step(t, by);
        }
        d.input(t, input);
    }
    d.seen
}

#[test]
fn instants_in_event_text_move() {
    assert_eq!(
        later(
            "at: 1.500000s, d: 2.500ms, x3.000000s",
            Duration::from_secs(1)
        ),
        "at: 2.500000s, d: 2.500ms, x3.000000s"
    );
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    // What this property found, each fixed: the SDO client took a transfer's first deadline
    // for one of the old time line after sitting idle through a step; the supervisor showed the
    // master a step with `handle_timeout`, which ran its timers one extra time; cached lower
    // bounds (the pair table's, the master's slots', the heartbeat consumer's) were recomputed
    // instead of moved, so the stepped run woke at other times than the reference.
    #[test]
    fn a_step_back_changes_nothing_but_the_time_line(
        ops in prop::collection::vec(op(), 20..300),
        steps in prop::collection::vec((any::<prop::sample::Index>(), step_size()), 1..5),
    ) {
        let steps: Vec<_> = steps.iter().map(|(i, by)| (i.index(ops.len()), *by)).collect();
        // The reference wakes up where the other run steps, too.
        let wake_ups: Vec<_> = steps.iter().map(|(i, _)| (*i, Duration::ZERO)).collect();
        let reference = run(&ops, &wake_ups);
        let stepped = run(&ops, &steps);
        same_time_line(&reference, &stepped)?;
    }
}
