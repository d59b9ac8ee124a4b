//! The clock contract in the dual-bus layer (`duocan::frame::instant`), driven sans-IO: a step
//! back of the caller's clock, noticed on the next input, moves every time the layer holds back
//! by the step, so that no timer gains or loses remaining time; a jump ahead is time that passed;
//! at `Instant::MAX` nothing stays due.
//!
//! Each test runs traffic an hour into the clock, steps it back by an hour (the driver says so
//! once, with `handle_timeout`) and checks the instants that follow in the new time line, which
//! are exact: what was due 90 ms after the step's old time is due 90 ms after its new time.

use duocan::machine::{BusLink, LinkRequest, PortRequest, PortStatus};
use duocan::{Duration, Frame, Id, Instant, NodeId};
use duocan_redundancy::{
    DualBus, DualBusConfig, LinkEvent, LinkEventKind, Member, PortReason, PortState,
};

pub(crate) const HOUR: Duration = Duration::from_secs(3600);

pub(crate) fn ms(x: u64) -> Instant {
    Instant::from_millis(x)
}
pub(crate) fn us(x: u64) -> Instant {
    Instant::from_micros(x)
}
pub(crate) fn d(x: u64) -> Duration {
    Duration::from_millis(x)
}
pub(crate) fn tpdo(node: u16, v: u8) -> Frame {
    Frame::from_array(Id::Standard(0x180 + node), [v])
}
pub(crate) fn heartbeat(node: u16, state: u8) -> Frame {
    Frame::from_array(Id::Standard(0x700 + node), [state])
}

/// A dual-bus layer driven as a driver drives it: deadlines handled when due (each at its own
/// instant), everything it queues drained after every input.
pub(crate) struct Rig {
    pub(crate) l: DualBus,
    pub(crate) events: Vec<LinkEvent>,
    pub(crate) requests: Vec<(usize, PortRequest)>,
    pub(crate) machine: Vec<LinkRequest>,
    pub(crate) tx: Vec<(usize, Frame)>,
    /// The latest time the layer was given: deadlines found late are handled then, not before
    /// (that would be a step back).
    latest: Instant,
}

impl Rig {
    pub(crate) fn new(cfg: DualBusConfig) -> Rig {
        Rig {
            l: DualBus::new(cfg),
            events: vec![],
            requests: vec![],
            machine: vec![],
            tx: vec![],
            latest: Instant::ZERO,
        }
    }
    pub(crate) fn drain(&mut self) {
        while let Some(f) = self.l.poll_transmit() {
            self.tx.push(f);
        }
        while let Some(r) = self.l.poll_port_request() {
            self.requests.push(r);
        }
        while let Some(r) = self.l.poll_machine_request() {
            self.machine.push(r);
        }
        while let Some(e) = self.l.poll_event() {
            self.events.push(e);
        }
    }
    /// Handles every deadline up to `now`, each at its instant. A deadline that stays due is a
    /// livelock.
    pub(crate) fn run(&mut self, now: Instant) {
        for _ in 0..64 {
            match self.l.poll_timeout() {
                Some(t) if t <= now => {
                    self.latest = self.latest.max(t);
                    self.l.handle_timeout(self.latest);
                }
                _ => return,
            }
            self.drain();
        }
        panic!("deadline {:?} still due at {now:?}", self.l.poll_timeout());
    }
    /// A frame arrives on `port` at `now`; true if it was delivered upward.
    pub(crate) fn rx(&mut self, now: Instant, port: usize, f: Frame) -> bool {
        self.run(now);
        self.latest = now;
        let up = self.l.handle_rx(now, port, &f).is_some();
        self.drain();
        up
    }
    /// The node sends `f` at `now`; the driver takes it at once.
    pub(crate) fn send(&mut self, now: Instant, f: Frame) {
        self.run(now);
        self.latest = now;
        self.l.send(now, &f);
        self.drain();
    }
    pub(crate) fn status(&mut self, now: Instant, port: usize, s: PortStatus) {
        self.run(now);
        self.latest = now;
        self.l.handle_port_status(now, port, s);
        self.drain();
    }
    /// The driver wakes up at `from`, then its clock steps back to `to`; it says so once (the
    /// contract). The layer measures the step from the latest time it was given: `from`.
    pub(crate) fn step(&mut self, from: Instant, to: Instant) {
        self.run(from);
        self.l.handle_timeout(from);
        self.l.handle_timeout(to);
        self.latest = to;
        self.drain();
    }
    /// Port events of `port`: (instant, to, reason).
    pub(crate) fn port_events(&self, port: u8) -> Vec<(Instant, PortState, PortReason)> {
        self.events
            .iter()
            .filter_map(|e| match e.kind {
                LinkEventKind::Port {
                    port: p,
                    to,
                    reason,
                    ..
                } if p == port => Some((e.at, to, reason)),
                _ => None,
            })
            .collect()
    }
    pub(crate) fn kinds(&self) -> Vec<(Instant, LinkEventKind)> {
        self.kinds_where(|_| true)
    }
    /// The events whose kind `which` picks.
    pub(crate) fn kinds_where(
        &self,
        which: impl Fn(&LinkEventKind) -> bool,
    ) -> Vec<(Instant, LinkEventKind)> {
        self.events
            .iter()
            .filter(|e| which(&e.kind))
            .map(|e| (e.at, e.kind))
            .collect()
    }
}

/// Node 5's TPDO every 10 ms from `from` (counter `k0` on), on bus 1 and, 0.2 ms later, on bus 2
/// while `bus2`; returns the next counter.
pub(crate) fn traffic(r: &mut Rig, from: Instant, n: u64, k0: u8, bus2: bool) -> u8 {
    let mut k = k0;
    for i in 0..n {
        let t = from + d(10 * i);
        assert!(r.rx(t, 0, tpdo(5, k)), "{t:?}: frame {k} delivered");
        if bus2 {
            assert!(!r.rx(t + Duration::from_micros(200), 1, tpdo(5, k)), "twin");
        }
        k = k.wrapping_add(1);
    }
    k
}

#[test]
fn a_bus_that_dies_right_after_a_step_back_fails_at_the_silence_limit_in_the_new_time() {
    // Default timing: silence limit 300 ms, suspect after 100 ms, reachability 300 ms.
    let mut r = Rig::new(DualBusConfig::default());
    let t0 = Instant::ZERO + HOUR;
    // Both buses from 1 h to 1 h + 990 ms; bus 2's last frame at 1 h + 990.2 ms.
    let k = traffic(&mut r, t0, 100, 0, true);
    // 1 h + 1 s: bus 2 is dead from here on. At 1 h + 1.005 s the clock steps back an hour.
    let k = traffic(&mut r, t0 + d(1000), 1, k, false);
    r.step(t0 + d(1005), ms(1005));
    traffic(&mut r, ms(1010), 60, k, false);
    r.run(ms(1700));
    // Bus 2's last frame was at 990.2 ms in the new time line.
    let last = us(990_200);
    assert_eq!(
        r.port_events(1),
        [
            (
                last + d(100),
                PortState::Suspect,
                PortReason::Silence { silent: d(100) }
            ),
            (
                last + d(300),
                PortState::Failed,
                PortReason::Silence { silent: d(300) }
            ),
            // Re-initialised after the 100 ms back-off, failed again a silence limit later.
            (
                last + d(400),
                PortState::Recovering,
                PortReason::Reinit { attempt: 1 }
            ),
            (
                last + d(700),
                PortState::Failed,
                PortReason::Silence { silent: d(300) }
            ),
        ]
    );
    let reach = r.kinds_where(|k| matches!(k, LinkEventKind::Reach { .. }));
    assert_eq!(
        reach.last(),
        Some(&(
            last + d(300),
            LinkEventKind::Reach {
                node: NodeId::must(5),
                heard: [true, false]
            }
        )),
        "node 5 unreachable on bus 2 exactly the timeout after its last frame there"
    );
    assert!(r.port_events(0).is_empty(), "bus 1 untouched");
}

#[test]
fn merge_records_move_back_with_the_clock() {
    let mut r = Rig::new(DualBusConfig::default());
    let t0 = Instant::ZERO + HOUR;
    // A frame bus 2 missed, at 1 h; another one at 1 h + 4 ms whose twin comes after the step.
    assert!(r.rx(t0, 0, tpdo(5, 1)));
    assert!(r.rx(t0 + d(4), 0, tpdo(5, 2)));
    r.step(t0 + d(5), ms(5));
    // The twin 2 ms after its copy in the new time line: a duplicate, dropped once.
    assert!(!r.rx(ms(6), 1, tpdo(5, 2)));
    // The first frame again, 20 ms after its copy (beyond the 5 ms window) and on bus 2 only
    // (bus 1 missed this one): a new occurrence. Had its old record stayed an hour in the
    // future, it would never have expired and this frame would be lost as its twin.
    assert!(r.rx(ms(20), 1, tpdo(5, 1)));
    // Its twin on bus 1 within the window: dropped; a third copy of frame 2 comes again.
    assert!(!r.rx(ms(21), 0, tpdo(5, 1)));
    assert!(r.rx(ms(30), 0, tpdo(5, 2)));
    assert!(!r.rx(ms(31), 1, tpdo(5, 2)));
    assert_eq!(r.l.stats().delivered, 4);
}

#[test]
fn the_transmit_stall_rule_keeps_its_time_after_a_step_back() {
    let mut r = Rig::new(DualBusConfig::default());
    let t0 = Instant::ZERO + HOUR;
    let f = |v| Frame::from_array(Id::Standard(0x201), [v]);
    // Both drivers confirm a frame an hour into the clock: they report outcomes.
    r.send(t0, f(0));
    r.status(t0 + d(1), 0, PortStatus::TxOk);
    r.status(t0 + d(1), 1, PortStatus::TxOk);
    r.step(t0 + d(2), ms(2));
    // Both buses busy alike: a frame handed over at 10 ms waits 30 ms on both. No stall: its
    // twins still match. (Had the frames confirmed an hour ahead stayed there, each port would
    // have looked overtaken at once and both would be flushed at 20 ms.)
    r.send(ms(10), f(1));
    r.status(ms(40), 0, PortStatus::TxOk);
    r.status(ms(41), 1, PortStatus::TxOk);
    r.run(ms(100));
    assert!(r.port_events(0).is_empty() && r.port_events(1).is_empty());
    // A real stall: bus 1 sends two frames, bus 2 neither. Overtaken at bus 1's first outcome
    // (102 ms: the twin of bus 2's oldest frame is out), flushed and failed the stall time
    // (2.5 ms, half the window) later.
    r.send(ms(100), f(2));
    r.send(ms(101), f(3));
    r.status(ms(102), 0, PortStatus::TxOk);
    r.status(ms(103), 0, PortStatus::TxOk);
    r.run(ms(200));
    assert_eq!(
        r.port_events(1),
        [(
            ms(102) + Duration::from_micros(3_000),
            PortState::Failed,
            PortReason::TxStalled {
                waited: Duration::from_micros(3_000)
            }
        )]
    );
    assert_eq!(r.requests, [(1, PortRequest::Reinit)]);
}

/// Node 5's TPDO every 10 ms on both buses from `from` for `n` frames, bus 2's copy `lag` later
/// (arrivals in time order).
pub(crate) fn lagging(r: &mut Rig, from: Instant, n: u64, k0: u8, lag: Duration) -> u8 {
    let mut arrivals = vec![];
    for i in 0..n {
        let t = from + d(10 * i);
        let k = k0.wrapping_add(i as u8);
        arrivals.push((t, 0, tpdo(5, k)));
        arrivals.push((t + lag, 1, tpdo(5, k)));
    }
    arrivals.sort_by_key(|a| (a.0, a.1));
    for (t, p, f) in arrivals {
        r.rx(t, p, f);
    }
    k0.wrapping_add(n as u8)
}

/// Bus 2 hands its frames over 15 ms late without timestamps: corrected. The clock steps back
/// an hour, then bus 2 keeps pace: its corrected copies come 14.8 ms early, and the second fresh
/// frame that shows it (a counter at 280 ms in the new time line) undoes the correction.
#[test]
fn a_correction_survives_a_step_back_and_is_undone_by_what_follows() {
    let mut r = Rig::new(DualBusConfig::default());
    let t0 = Instant::ZERO + HOUR;
    r.run(t0);
    let k = lagging(&mut r, t0, 25, 0, d(15));
    assert_eq!(r.l.lag().lag(1), d(15));
    r.step(t0 + d(260), ms(260));
    assert_eq!(r.l.lag().lag(1), d(15));
    lagging(&mut r, ms(270), 60, k, Duration::from_micros(200));
    r.run(ms(1000));
    let lag = r.kinds_where(|k| {
        matches!(
            k,
            LinkEventKind::Lag { .. } | LinkEventKind::LagCleared { .. }
        )
    });
    assert_eq!(
        lag.last(),
        Some(&(us(280_200), LinkEventKind::LagCleared { port: 1 })),
        "{lag:?}"
    );
    assert_eq!(r.l.lag().window(), d(5));
}

#[test]
fn a_discrepancy_keeps_its_time_after_a_step_back() {
    let mut r = Rig::new(DualBusConfig::default());
    let (a, b) = (NodeId::must(0x10), NodeId::must(0x11));
    let pair = r.l.add_pair(a, b, Some(Member::A)).unwrap();
    let t0 = Instant::ZERO + HOUR;
    // A and B disagree from 1 h on; the clock steps back an hour 50 ms later.
    r.rx(t0, 0, tpdo(0x10, 1));
    r.rx(t0, 0, tpdo(0x11, 2));
    r.step(t0 + d(50), ms(50));
    r.run(ms(500));
    let raised = r.kinds_where(|k| matches!(k, LinkEventKind::Discrepancy { .. }));
    assert_eq!(
        raised,
        [(
            ms(100),
            LinkEventKind::Discrepancy {
                pair,
                function: 1,
                a: tpdo(0x10, 1),
                b: tpdo(0x11, 2),
            }
        )]
    );
}

#[test]
fn a_watched_heartbeat_at_its_pace_across_a_step_back_stays_plausible() {
    let mut r = Rig::new(DualBusConfig::default());
    assert!(r.l.watch(NodeId::must(0x10), d(100)));
    let t0 = Instant::ZERO + HOUR;
    let mut delivered = 0;
    for i in 0..10 {
        for p in 0..2 {
            delivered += r.rx(
                t0 + d(100 * i) + Duration::from_micros(100 * p as u64),
                p,
                heartbeat(0x10, 5),
            ) as u32;
        }
    }
    r.step(t0 + d(950), ms(950));
    for i in 0..10 {
        for p in 0..2 {
            delivered += r.rx(
                ms(1000 + 100 * i) + Duration::from_micros(100 * p as u64),
                p,
                heartbeat(0x10, 5),
            ) as u32;
        }
    }
    assert_eq!(delivered, 20);
    assert_eq!(r.l.stats().implausible, 0);
    assert_eq!(
        r.l.plausibility().is_suspect(NodeId::must(0x10)),
        Some(false)
    );
}

#[test]
fn a_jump_ahead_is_time_that_passed_once() {
    // Bus 2 lags (lag samples held), then one `handle_timeout` an hour ahead: what fell due in
    // between comes once, each at its own instant, exactly as if the deadlines had been handled
    // one by one; the driver's loop ends at once.
    let scenario = |r: &mut Rig| {
        let t0 = Instant::ZERO + HOUR;
        r.run(t0);
        lagging(r, t0, 25, 0, d(15));
        // Bus 2 dies: a PDO every 50 ms on bus 1 only.
        for k in 0..9 {
            r.rx(t0 + d(300 + 50 * k), 0, tpdo(5, 99));
        }
    };
    let mut jumped = Rig::new(DualBusConfig::default());
    scenario(&mut jumped);
    let ahead = Instant::ZERO + HOUR + HOUR;
    jumped.l.handle_timeout(ahead);
    jumped.drain();
    let due = jumped.l.poll_timeout();
    assert!(due.is_none_or(|t| t > ahead), "still due: {due:?}");
    let mut stepped = Rig::new(DualBusConfig::default());
    scenario(&mut stepped);
    stepped.run(ahead);
    // One call reports each part's changes in turn: the same changes at the same instants.
    let in_time = |r: &Rig| {
        let mut k = r.kinds();
        k.sort_by_key(|(at, kind)| (*at, format!("{kind:?}")));
        k
    };
    assert_eq!(in_time(&jumped), in_time(&stepped));
    assert!(jumped
        .port_events(1)
        .iter()
        .any(|(_, to, _)| *to == PortState::Failed));
}
