//! Heartbeats that lie (issue 13, section 2), on the simulated dual bus with the supervised
//! network of `net.rs` (slaves beat every 20 ms, consumer time 50 ms, reachability window
//! 60 ms, 1 Mbit/s): a babbling controller repeating the active member's heartbeat, an impostor
//! beating it on one bus only, a second device with the same node-ID, a rogue NMT start-all.
//! Before the fix the first three left the pair with no running board for as long as the
//! impostor lasted, and the last left both boards running for ever when the standby's
//! heartbeat came after the master's command suspension.
//!
//! Every instant is exact: the verdicts are recomputed here from the frames on the wire with
//! the rules as `link::plausible` states them.

use crate::net::*;
use duocan::machine::StationEvent;
use duocan::sim::{BusId, DevId, TraceRecord, TxOutcome};
use duocan::{Device, Duration, Frame, Id, Instant, NmtCommand, NmtState, PortStatus};
use duocan_redundancy::supervisor::flying_master::FlyingEvent;
use duocan_redundancy::supervisor::pairs::{LossReason, PairsEvent, Phase, RoleReason};
use duocan_redundancy::{LinkEvent, LinkEventKind, Member, PairId, SupervisorEvent, Suspicion};

const ONE_MS: Duration = Duration::from_millis(1);
const PERIOD: Duration = Duration::from_millis(20);
/// The reachability window of the masters' layers: 3 × the 20 ms heartbeat.
const WINDOW: Duration = Duration::from_millis(60);
const DETECTION_TIMEOUT: Duration = Duration::from_millis(100);

fn ms(x: u64) -> Instant {
    Instant::from_millis(x)
}

/// Sends `frame` on every port, every `period` from `start` (once if `period` is zero).
pub(crate) struct Injector {
    ports: usize,
    frame: Frame,
    next: Option<Instant>,
    period: Duration,
    out: Vec<(usize, Frame)>,
}

impl Device for Injector {
    type Event = ();
    fn port_count(&self) -> usize {
        self.ports
    }
    fn handle_rx(&mut self, _: Instant, _: usize, _: &Frame) {}
    fn handle_port_status(&mut self, _: Instant, _: usize, _: PortStatus) {}
    fn handle_timeout(&mut self, now: Instant) {
        while let Some(t) = self.next.filter(|t| *t <= now) {
            for p in 0..self.ports {
                self.out.push((p, self.frame));
            }
            self.next = (!self.period.is_zero()).then_some(t + self.period);
        }
    }
    fn poll_transmit(&mut self) -> Option<(usize, Frame)> {
        self.out.pop()
    }
    fn poll_timeout(&self) -> Option<Instant> {
        self.next
    }
    fn poll_event(&mut self) -> Option<()> {
        None
    }
}

pub(crate) fn inject(
    n: &mut SupNet,
    buses: &[BusId],
    frame: Frame,
    start: Option<Instant>,
    period: Duration,
) -> DevId<Injector> {
    let dev = injector(buses.len(), frame, start, period);
    n.sim.add_device("impostor", dev, buses).unwrap()
}

/// An [`Injector`] on `ports` ports.
pub(crate) fn injector(
    ports: usize,
    frame: Frame,
    start: Option<Instant>,
    period: Duration,
) -> Injector {
    Injector {
        ports,
        frame,
        next: start,
        period,
        out: vec![],
    }
}

pub(crate) fn heartbeat(node: u8, state: u8) -> Frame {
    Frame::from_array(Id::Standard(0x700 + node as u16), [state])
}

fn running(n: &SupNet, id: u8) -> bool {
    n.sim.is_powered(n.slave(id))
        && n.sim.device(n.slave(id)).machine.nmt_state() == NmtState::Operational
}

/// Ends of the frames with identifier `id` delivered on bus `bus` (whoever sent them, babbling
/// controllers included): when each reached the masters.
pub(crate) fn arrivals(n: &SupNet, bus: usize, id: u16) -> Vec<Instant> {
    n.sim
        .trace()
        .iter()
        .filter_map(|r| match r {
            TraceRecord::Tx(x)
                if x.bus == n.buses[bus]
                    && x.frame.id() == Id::Standard(id)
                    && matches!(x.outcome, TxOutcome::Delivered { .. }) =>
            {
                Some(x.end)
            }
            _ => None,
        })
        .collect()
}

/// Rule 1 restated: the first arrival that ends a span `s` holding more than `5 + 4s/(3T)`
/// heartbeats, the span starting no earlier than the last boot-up that began a new life (one
/// that came at least two periods after the previous such instant, as a leaky bucket of its
/// own reckons it).
fn too_fast_at(beats: &[(Instant, bool)], period: Duration) -> Option<Instant> {
    let t = period.as_micros() as i128;
    let d = 2 * t;
    let (mut boots, mut life) = (0i128, 0usize);
    (0..beats.len()).find_map(|j| {
        let (at, boot_up) = (beats[j].0.as_micros() as i128, beats[j].1);
        if boot_up {
            let next = boots.max(at) + d;
            if next - at <= d {
                life = j;
            }
            boots = next.min(at + 2 * d);
        }
        (j.saturating_sub(200).max(life)..=j)
            .any(|i| {
                let count = (j - i + 1) as i128;
                let span = (beats[j].0 - beats[i].0).as_micros() as i128;
                3 * t * (count - 5) > 4 * span
            })
            .then_some(beats[j].0)
    })
}

/// The heartbeats of identifier `id` on `bus`: when each ended, and whether it was a boot-up.
fn heartbeats(n: &SupNet, bus: usize, id: u16) -> Vec<(Instant, bool)> {
    n.sim
        .trace()
        .iter()
        .filter_map(|r| match r {
            TraceRecord::Tx(x)
                if x.bus == n.buses[bus]
                    && x.frame.id() == Id::Standard(id)
                    && matches!(x.outcome, TxOutcome::Delivered { .. }) =>
            {
                Some((x.end, x.frame.data().first() == Some(&0)))
            }
            _ => None,
        })
        .collect()
}

/// Heartbeats per second measured over the period from a verdict at `v`, `[v, v + T)`.
fn rate_after(arrivals: &[Instant], v: Instant) -> u32 {
    let count = arrivals
        .iter()
        .filter(|t| **t >= v && **t < v + PERIOD)
        .count() as u32;
    count * 50
}

pub(crate) fn link_events(n: &SupNet, id: u8) -> Vec<LinkEvent> {
    n.sim
        .events(n.master(id))
        .iter()
        .filter_map(|(_, e)| match e {
            StationEvent::Link(l) => Some(*l),
            _ => None,
        })
        .collect()
}

/// The layer's verdicts on node `node` at master `id`: (when, why).
pub(crate) fn suspects_of(n: &SupNet, id: u8, node: u8) -> Vec<(Instant, Suspicion)> {
    link_events(n, id)
        .into_iter()
        .filter_map(|e| match e.kind {
            LinkEventKind::Suspect { node: s, why } if s.raw() == node => Some((e.at, why)),
            _ => None,
        })
        .collect()
}

pub(crate) fn suspects(n: &SupNet, id: u8) -> Vec<(Instant, Suspicion)> {
    suspects_of(n, id, a(0))
}

/// Rule 1's verdict when both buses carry two devices' heartbeats, found too fast at `v[0]`
/// and `v[1]`: the node is suspect once neither bus speaks for it, at the later of the two
/// (the suspicion names that bus). Returns that instant.
fn assert_too_fast_on_both(n: &SupNet, v: &[Instant]) -> Instant {
    let at = v[0].max(v[1]);
    let first = suspects(n, STRONG)[0];
    assert!(
        matches!(first, (t, Suspicion::TooFast { port }) if t == at && v[port as usize] == at),
        "{first:?} vs {v:?}"
    );
    at
}

/// NMT commands (first copies) from the strong master after `from`: (end, command, target).
fn nmt_after(n: &SupNet, from: Instant) -> Vec<(Instant, NmtCommand, u8)> {
    n.nmt_first_copies()
        .into_iter()
        .filter(|x| x.0 > from && x.1 == STRONG)
        .map(|(t, _, c, node)| (t, c, node))
        .collect()
}

/// The failover of pair 0 at `v`: the role change, B's start on the wire within a frame, A
/// reset after it, A out of the table as suspect.
fn assert_failover_at(n: &SupNet, v: Instant) {
    assert_failover_then(n, v, NmtCommand::ResetNode);
}

/// [`assert_failover_at`] with `then` sent to A after B's start.
fn assert_failover_then(n: &SupNet, v: Instant, then: NmtCommand) {
    let roles = n.pair_roles(STRONG, 0);
    let last = roles.last().unwrap();
    assert_eq!(
        (last.at, last.from, last.to, last.reason),
        (
            v,
            Some(Member::A),
            Some(Member::B),
            RoleReason::ActiveSuspect
        ),
        "{roles:?}"
    );
    let nmt = nmt_after(n, v - ONE_MS);
    assert_eq!((nmt[0].1, nmt[0].2), (NmtCommand::Start, b(0)), "{nmt:?}");
    assert!(nmt[0].0 > v && nmt[0].0 <= v + ONE_MS, "{nmt:?} vs {v}");
    assert_eq!((nmt[1].1, nmt[1].2), (then, a(0)), "{nmt:?}");
    let lost = n.sup_events(STRONG).into_iter().any(|e| {
        matches!(e, SupervisorEvent::Pairs(PairsEvent::Lost { at, node, reason: LossReason::Suspect, .. })
            if at == v && node.raw() == a(0))
    });
    assert!(lost);
    // The weak master followed from the commands on the wire.
    assert_eq!(n.active_member(WEAK, 0), Some(Member::B));
}

#[test]
fn babbling_impostor_heartbeat_is_dropped_at_its_sixth_frame_and_the_standby_starts_once_bus_2_is_silent(
) {
    // The case: a controller on bus 1 repeats 0x710 [05] back to back from 1000 ms;
    // the real 0x10, the active member of pair 0, loses power at 1003 ms.
    let mut n = SupNet::new(Params::default());
    let hb = heartbeat(a(0), 5);
    let bus1 = [n.buses[0]];
    let dev = inject(&mut n, &bus1, hb, None, Duration::ZERO);
    n.sim
        .at(ms(1000), move |sim| sim.babble(dev.port(0), Some(hb)));
    n.kill_slave_at(a(0), ms(1003));
    n.sim.run_until(ms(1500));

    let on_bus1 = heartbeats(&n, 0, 0x710);
    let v = too_fast_at(&on_bus1, PERIOD).unwrap();
    let babble: Vec<Instant> = n
        .sim
        .trace()
        .iter()
        .filter_map(|r| match r {
            TraceRecord::Tx(x) if x.babble => Some(x.end),
            _ => None,
        })
        .collect();
    // The stated bound: bus 1 too fast for 0x10 at the sixth babbled frame at the latest (here
    // the fifth: the real heartbeat 7.5 ms earlier still weighed in the bucket), 0.46 ms after
    // the babble began; from then its frames there are dropped.
    assert!(v <= babble[5], "{v} vs {:?}", &babble[..6]);
    assert_eq!(v, babble[4]);
    // Bus 2 still speaks for the board (the real one beats there until 1003 ms): no verdict
    // yet. 1.5 periods (30 ms) after its last heartbeat there, nothing does: suspect. A
    // window after it, the babbler is also the only one heard: the second reason.
    let h = *arrivals(&n, 1, 0x710)
        .iter()
        .rfind(|t| **t < ms(1003))
        .unwrap();
    let silent = h + Duration::from_micros(30_001);
    assert!(v < h + PERIOD && silent < h + Duration::from_millis(50));
    assert_eq!(
        suspects(&n, STRONG),
        [
            (silent, Suspicion::TooFast { port: 0 }),
            (h + WINDOW, Suspicion::OneBus { heard: 0 })
        ]
    );
    assert_failover_at(&n, silent);
    // The babbling identifier is reported with its bus and its rate, one period later.
    let report = link_events(&n, STRONG)
        .into_iter()
        .find_map(|e| match e.kind {
            LinkEventKind::Babbling {
                node,
                id,
                port,
                rate,
                allowed,
                since,
            } => Some((e.at, node.raw(), id, port, rate, allowed, since)),
            _ => None,
        })
        .expect("a babbling report");
    let rate = rate_after(&on_bus1.iter().map(|b| b.0).collect::<Vec<_>>(), v);
    assert_eq!(
        report,
        (v + PERIOD, a(0), Id::Standard(0x710), 0, rate, 50, v)
    );
    assert!(rate > 16_000, "{rate}");
    // Its frames no longer reach the stack (counted); the bus stays in use for the others.
    let st = n.sim.device(n.master(STRONG));
    assert!(st.link.stats().implausible > 8_000);
    assert_eq!(st.link.port_state(0), duocan_redundancy::PortState::Ok);
    // Exactly one running board, and the trail says why.
    assert!(running(&n, b(0)) && !n.sim.is_powered(n.slave(a(0))));
    let mut text = String::new();
    n.sup(STRONG).audit().write_text(&mut text).unwrap();
    assert!(
        text.contains("identifier 0x710 (node 0x10's heartbeat) babbling on bus 1"),
        "{text}"
    );
    assert!(
        text.contains("active A -> B: active member's heartbeats implausible"),
        "{text}"
    );
}

#[test]
fn babble_beginning_after_the_power_loss_cuts_the_silence_short() {
    // The board dies first; the babble begins before its consumer time has run out, when
    // bus 2 no longer speaks for it (its last heartbeat there more than 1.5 periods old): the
    // standby is started at the babble's verdict, earlier than the silence would have done.
    let mut n = SupNet::new(Params::default());
    let hb = heartbeat(a(0), 5);
    let bus1 = [n.buses[0]];
    let dev = inject(&mut n, &bus1, hb, None, Duration::ZERO);
    n.kill_slave_at(a(0), ms(1003));
    n.sim
        .at(ms(1030), move |sim| sim.babble(dev.port(0), Some(hb)));
    n.sim.run_until(ms(1500));
    let silent_at = n.last_heartbeat(a(0), ms(1003)) + Duration::from_millis(50);
    let v = too_fast_at(&heartbeats(&n, 0, 0x710), PERIOD).unwrap();
    assert!(v > ms(1030) && v < silent_at, "{v} vs {silent_at}");
    assert_failover_at(&n, v);
}

#[test]
fn impostor_on_one_bus_only_is_suspect_one_window_after_the_other_bus_lost_the_node() {
    // A device on bus 1 only beats 0x710 [05] every 20 ms from 1001 ms; the real 0x10 dies at
    // 1003 ms. Before, the impostor kept it "alive" for ever.
    let mut n = SupNet::new(Params::default());
    let bus1 = [n.buses[0]];
    inject(&mut n, &bus1, heartbeat(a(0), 5), Some(ms(1001)), PERIOD);
    n.kill_slave_at(a(0), ms(1003));
    n.sim.run_until(ms(1500));
    // The last heartbeat of the real board on bus 2, plus the reachability window: bus 2 heard
    // B (0x750, lower priority) all along, so it is healthy for 0x10.
    let h = *arrivals(&n, 1, 0x710)
        .iter()
        .rfind(|t| **t < ms(1003))
        .unwrap();
    let v = h + WINDOW;
    assert_eq!(suspects(&n, STRONG), [(v, Suspicion::OneBus { heard: 0 })]);
    assert_failover_at(&n, v);
    // Within consumer time + 1 ms + the detection bound (window − consumer time = 10 ms) of
    // the board's last heartbeat.
    let last = n.last_heartbeat(a(0), ms(1003));
    assert!(v <= last + Duration::from_millis(50) + ONE_MS + Duration::from_millis(10));
    // The impostor goes on: A is not adopted on its word, and the status says so.
    let pair = *n.sup(STRONG).pair_supervisor().pair(PairId(0)).unwrap();
    assert_eq!(pair.member(Member::A).phase(), Phase::Waiting);
    assert!(n.sup(STRONG).pair_supervisor().is_suspect(pair.spec.a));
    let status = n.sim.device(n.master(STRONG)).status(ms(1500)).to_string();
    assert!(
        status.contains("0x10    operational      suspect"),
        "{status}"
    );
    assert!(running(&n, b(0)));
}

#[test]
fn two_devices_sharing_a_node_id_are_reported_and_the_standby_takes_over() {
    // A second device beats 0x710 [05] (operational, as the real board does) every 20 ms on
    // both buses from 1007 ms to 2000 ms, between the real board's heartbeats. (One saying
    // another state is the active member not running, replaced at that heartbeat:
    // `not_operational.rs`.)
    let mut n = SupNet::new(Params::default());
    let buses = n.buses;
    let dup = inject(
        &mut n,
        &buses,
        heartbeat(a(0), 0x05),
        Some(ms(1007)),
        PERIOD,
    );
    n.sim.at(ms(2000), move |sim| sim.power_off(dup));
    n.sim.run_until(ms(2000));
    let per_bus: Vec<Vec<Instant>> = (0..2).map(|b| arrivals(&n, b, 0x710)).collect();
    let v: Vec<Instant> = (0..2)
        .map(|b| too_fast_at(&heartbeats(&n, b, 0x710), PERIOD).unwrap())
        .collect();
    // Within 8 periods of both beating.
    assert!(
        v.iter().all(|t| *t <= ms(1007) + PERIOD.saturating_mul(8)),
        "{v:?}"
    );
    let first = assert_too_fast_on_both(&n, &v);
    // Not reset: its board may be the one running, and a reset would reach both devices.
    assert_failover_then(&n, first, NmtCommand::EnterPreOperational);
    // Reported as a duplicate node-ID on each bus, with the measured rate.
    let dups: Vec<_> = link_events(&n, STRONG)
        .into_iter()
        .filter_map(|e| match e.kind {
            LinkEventKind::DuplicateNode {
                node,
                port,
                rate,
                allowed,
                since,
            } => Some((e.at, node.raw(), port, rate, allowed, since)),
            _ => None,
        })
        .collect();
    let mut want: Vec<_> = (0..2)
        .map(|p| {
            let r = rate_after(&per_bus[p], v[p]);
            (v[p] + PERIOD, a(0), p as u8, r, 50, v[p])
        })
        .collect();
    want.sort_by_key(|x| x.0);
    assert_eq!(dups[..2], want);
    assert!(dups[..2].iter().all(|d| d.3 == 100), "{dups:?}");
    assert!(
        dups.iter().all(|d| d.3 <= 4 * d.4),
        "never taken for a babble: {dups:?}"
    );
    // Suspect for as long as the other device beats: one verdict, one report per bus.
    assert_eq!(dups.len(), 2, "{dups:?}");
    assert!(!link_events(&n, STRONG).iter().any(|e| matches!(
        e.kind,
        LinkEventKind::Babbling { .. } | LinkEventKind::Trusted { .. }
    )));
    let mut text = String::new();
    n.sup(STRONG).audit().write_text(&mut text).unwrap();
    assert!(
        text.contains("devices share its node-ID"),
        "an audit record: {text}"
    );
    // The real board was stopped, not reset, and is not joined while its identifier is
    // shared: exactly one running board.
    assert!(running(&n, b(0)) && !running(&n, a(0)));
    let member_a = |n: &SupNet| {
        *n.sup(STRONG)
            .pair_supervisor()
            .pair(PairId(0))
            .unwrap()
            .member(Member::A)
    };
    assert!(!member_a(&n).joined());
    // The other device gone, the board alone is trusted after two whole periods with one
    // heartbeat each (at its third heartbeat at most: the drain alone would take 18 periods),
    // and its heartbeats adopt it again after the hold-off: joined without a reboot, never
    // reset.
    n.sim.run_until(ms(3000));
    let trusted: Vec<Instant> = link_events(&n, STRONG)
        .into_iter()
        .filter(|e| matches!(e.kind, LinkEventKind::Trusted { .. }))
        .map(|e| e.at)
        .collect();
    assert!(
        trusted.len() == 1
            && trusted[0] > ms(2000)
            && trusted[0] <= ms(2000) + PERIOD.saturating_mul(4),
        "{trusted:?}"
    );
    assert!(member_a(&n).joined());
    assert!(nmt_after(&n, ms(1000))
        .iter()
        .all(|x| !(x.1 == NmtCommand::ResetNode && x.2 == a(0))));
    assert_eq!(
        n.sim.device(n.slave(a(0))).machine.nmt_state(),
        NmtState::PreOperational
    );
}

/// A rogue device on bus 1 sends NMT start-all (0x000 [01 00]) at `at`.
fn rogue_start_all(n: &mut SupNet, at: Instant) {
    let bus1 = [n.buses[0]];
    let start_all = Frame::from_array(Id::Standard(0), [0x01, 0x00]);
    inject(n, &bus1, start_all, Some(at), Duration::ZERO);
}

/// The strong master's command suspension after the rogue frame: (from, until).
fn suspension(n: &SupNet) -> (Instant, Instant) {
    n.sup_events(STRONG)
        .into_iter()
        .find_map(|e| match e {
            SupervisorEvent::FlyingMaster(FlyingEvent::Suspended { at, until }) => {
                Some((at, until))
            }
            _ => None,
        })
        .expect("a foreign NMT command suspends the active master's commands")
}

#[test]
fn rogue_start_all_one_running_board_again_at_the_detection_timeout() {
    let mut n = SupNet::new(Params::default());
    rogue_start_all(&mut n, ms(1001));
    n.sim.run_until(ms(1500));
    let rogue = arrivals(&n, 0, 0)
        .into_iter()
        .find(|t| *t > ms(1001))
        .unwrap();
    let (from, until) = suspension(&n);
    assert_eq!((from, until), (rogue, rogue + DETECTION_TIMEOUT));
    // Every B was started by the rogue frame and heard operational within its period; at the
    // end of the suspension the master sends each back to pre-operational.
    let nmt = nmt_after(&n, rogue);
    assert_eq!(
        nmt.iter().map(|x| (x.1, x.2)).collect::<Vec<_>>(),
        (0..4)
            .map(|i| (NmtCommand::EnterPreOperational, b(i)))
            .collect::<Vec<_>>()
    );
    assert!(
        nmt.iter().all(|x| x.0 > until && x.0 <= until + ONE_MS),
        "{nmt:?} vs {until}"
    );
    for i in 0..4 {
        assert!(running(&n, a(i)) && !running(&n, b(i)), "pair {i}");
        assert_eq!(n.active_member(STRONG, i), Some(Member::A));
        assert_eq!(n.active_member(WEAK, i), Some(Member::A));
        assert_eq!(n.pair_roles(STRONG, i).len(), 1, "no switch-over");
    }
}

#[test]
fn rogue_start_all_with_a_slow_standby_heartbeat_is_undone_at_the_suspension_end() {
    // Heartbeats every 200 ms: a started standby still beats at once on its state change (CiA
    // 301's heartbeat on every NMT transition), so the master knows before its suspension ends
    // and sends every standby back at that end, not a slow period later.
    let p = Params {
        slave_hb: Duration::from_millis(200),
        consumer: Duration::from_millis(500),
        ..Params::default()
    };
    let mut n = SupNet::new(p);
    rogue_start_all(&mut n, ms(1050));
    n.sim.run_until(ms(2000));
    let (_, until) = suspension(&n);
    let nmt = nmt_after(&n, ms(1050));
    assert_eq!(nmt.len(), 4, "{nmt:?}");
    for i in 0..4 {
        let seen_running = arrivals(&n, 0, 0x700 + b(i) as u16)
            .into_iter()
            .chain(arrivals(&n, 1, 0x700 + b(i) as u16))
            .filter(|t| *t > ms(1050))
            .min()
            .unwrap();
        let back = nmt.iter().find(|x| x.2 == b(i)).unwrap();
        assert_eq!(back.1, NmtCommand::EnterPreOperational);
        // The bound: the later of the suspension's end and the standby's next heartbeat, plus
        // one frame.
        let due = until.max(seen_running);
        assert!(back.0 > due && back.0 <= due + ONE_MS, "{back:?} vs {due}");
        assert!(running(&n, a(i)) && !running(&n, b(i)), "pair {i}");
    }
    assert!(
        nmt.iter().all(|x| x.0 > until && x.0 <= until + ONE_MS),
        "{nmt:?} vs {until}"
    );
}

#[test]
fn rogue_start_the_master_does_not_hear_is_undone_at_the_standbys_first_operational_heartbeat() {
    // Bus 1 is split: the rogue device and the B boards on one side, the masters and the A
    // boards on the other. The masters never see the start-all (no suspension); the B boards
    // announce their new state at once (a heartbeat on every state change), on bus 2 too.
    let mut n = SupNet::new(Params::default());
    let bus1 = [n.buses[0]];
    let start_all = Frame::from_array(Id::Standard(0), [0x01, 0x00]);
    let rogue = inject(&mut n, &bus1, start_all, Some(ms(1001)), Duration::ZERO);
    let mut side: Vec<duocan::sim::PortRef> = (0..4).map(|i| n.slave(b(i)).port(0)).collect();
    side.push(rogue.port(0));
    let bus = n.buses[0];
    n.sim
        .at(ms(1000), move |sim| sim.partition(bus, &[side.as_slice()]));
    n.sim.run_until(ms(1500));
    assert!(!n.sup_events(STRONG).iter().any(|e| matches!(
        e,
        SupervisorEvent::FlyingMaster(FlyingEvent::Suspended { .. })
    )));
    let nmt = nmt_after(&n, ms(1001));
    // Then each B board, heard on bus 2 only while bus 1 is idle between frames, is suspect
    // one window after its last heartbeat on bus 1 and reset: a board cut off one bus looks
    // as one an impostor beats for on the other (`impostor_idle.rs`). Nothing else is sent.
    assert_eq!(nmt.len(), 8, "{nmt:?}");
    for i in 0..4 {
        let h = n
            .delivered()
            .into_iter()
            .filter(|(t, bus, s, f)| {
                *t < ms(1000) && *bus == 0 && *s == b(i) && *f == heartbeat(b(i), 0x7F)
            })
            .map(|x| x.0)
            .max()
            .unwrap();
        let reset = nmt[4..].iter().find(|x| x.2 == b(i)).unwrap();
        assert_eq!(reset.1, NmtCommand::ResetNode);
        assert!(
            reset.0 > h + WINDOW && reset.0 <= h + WINDOW + ONE_MS,
            "{reset:?} vs {h}"
        );
    }
    for i in 0..4 {
        // Its first heartbeat saying operational, as the masters got it (bus 2).
        let seen_running = n
            .delivered()
            .into_iter()
            .filter(|(t, bus, _, f)| *t > ms(1001) && *bus == 1 && *f == heartbeat(b(i), 5))
            .map(|x| x.0)
            .min()
            .unwrap();
        let back = nmt.iter().find(|x| x.2 == b(i)).unwrap();
        assert_eq!(back.1, NmtCommand::EnterPreOperational);
        assert!(
            back.0 > seen_running && back.0 <= seen_running + ONE_MS,
            "{back:?} vs {seen_running}"
        );
        assert!(running(&n, a(i)) && !running(&n, b(i)), "pair {i}");
        assert_eq!(n.pair_roles(STRONG, i).len(), 1, "no switch-over");
    }
}

#[test]
fn a_second_board_set_to_the_same_node_id_is_reported_and_never_started() {
    // A spare board configured as 0x10 is plugged in at 1007 ms: its boot-up makes pair 0 fail
    // over (the active member "booted"), then both boards answer as 0x10 and beat.
    let mut n = SupNet::new(Params::default());
    let (p, buses) = (n.p, n.buses);
    n.sim.at(ms(1007), move |sim| {
        let second = slave_station(&p, a(0), ms(1007));
        sim.add_device("second 0x10", second, &buses).unwrap();
    });
    n.sim.run_until(ms(3000));
    let roles = n.pair_roles(STRONG, 0);
    let last = roles.last().unwrap();
    assert_eq!(
        (last.from, last.to, last.reason),
        (Some(Member::A), Some(Member::B), RoleReason::ActiveRebooted)
    );
    let v: Vec<Instant> = (0..2)
        .map(|b| too_fast_at(&heartbeats(&n, b, 0x710), PERIOD).unwrap())
        .collect();
    assert_too_fast_on_both(&n, &v);
    let dups: Vec<(Instant, u8)> = link_events(&n, STRONG)
        .into_iter()
        .filter_map(|e| match e.kind {
            LinkEventKind::DuplicateNode { port, since, .. } => Some((since, port)),
            _ => None,
        })
        .collect();
    assert!(
        dups.contains(&(v[0], 0)) && dups.contains(&(v[1], 1)),
        "{dups:?}"
    );
    // Neither board set to 0x10 is ever started again: B alone runs.
    assert!(!n
        .nmt_first_copies()
        .iter()
        .any(|x| x.0 > last.at && x.2 == NmtCommand::Start && (x.3 == a(0) || x.3 == 0)));
    assert!(running(&n, b(0)) && !running(&n, a(0)));
}

#[test]
fn a_live_standby_whose_heartbeat_a_second_device_sends_on_one_bus_takes_over_when_the_active_dies()
{
    // Campaign seed 3007: a device beats 0x750 [05] on bus 1 only, between the real standby's
    // heartbeats, from 1007 ms; the standby 0x50 is alive on both buses. The active 0x10 dies
    // at 1500 ms. Before, the duplicate made the standby suspect (taken out of the table, not
    // adopted until the device went away): the pair had no board to run.
    let mut n = SupNet::new(Params::default());
    let bus1 = [n.buses[0]];
    inject(&mut n, &bus1, heartbeat(b(0), 5), Some(ms(1007)), PERIOD);
    n.kill_slave_at(a(0), ms(1500));
    n.sim.run_until(ms(2500));
    // Bus 1 found too fast for 0x50 within 8 periods, reported as a duplicate node-ID there
    // (and only there); the standby itself never suspect.
    let v = too_fast_at(&heartbeats(&n, 0, 0x750), PERIOD).unwrap();
    assert!(v <= ms(1007) + PERIOD.saturating_mul(8), "{v}");
    let dups: Vec<(Instant, u8)> = link_events(&n, STRONG)
        .into_iter()
        .filter_map(|e| match e.kind {
            LinkEventKind::DuplicateNode {
                node, port, since, ..
            } if node.raw() == b(0) => Some((since, port)),
            _ => None,
        })
        .collect();
    assert_eq!(dups[0], (v, 0), "{dups:?}");
    assert!(dups.iter().all(|d| d.1 == 0), "{dups:?}");
    assert!(!link_events(&n, STRONG).iter().any(|e| matches!(
        e.kind,
        LinkEventKind::Suspect { node, .. } if node.raw() == b(0)
    )));
    assert!(!n
        .sup(STRONG)
        .pair_supervisor()
        .is_suspect(duocan::NodeId::must(b(0))));
    // The active member's silence: the standby started at its consumer time + 1 ms at most.
    let last_a = n.last_heartbeat(a(0), ms(1500));
    let roles = n.pair_roles(STRONG, 0);
    let fail = roles.last().unwrap();
    assert_eq!(
        (fail.from, fail.to, fail.reason),
        (
            Some(Member::A),
            Some(Member::B),
            RoleReason::ActiveSilent { last: last_a }
        ),
        "{roles:?}"
    );
    let start = n
        .nmt_first_copies()
        .into_iter()
        .find(|x| x.0 > ms(1500) && x.2 == NmtCommand::Start && x.3 == b(0))
        .unwrap();
    assert!(
        start.0 > last_a + Duration::from_millis(50)
            && start.0 <= last_a + Duration::from_millis(51),
        "{start:?} vs {last_a}"
    );
    // Never reset on the duplicate's account; it runs to the end.
    assert!(!n
        .nmt_first_copies()
        .iter()
        .any(|x| x.2 == NmtCommand::ResetNode && x.3 == b(0)));
    assert!(running(&n, b(0)));
}

#[test]
fn a_master_that_starts_while_an_impostor_beats_on_one_bus_judges_it_from_its_first_sight() {
    // Campaign seed 3986: the active 0x10 dies at 1003 ms while a device beats 0x710 [05] on
    // bus 1 only; the strong master catches it and starts B. The weak master, off from 900 ms,
    // starts again at 1200 ms: it never heard 0x10 on bus 2. At 1500 ms the strong master dies
    // and the weak one takes over. Before, the weak master took the impostor for the active
    // member, running, and sent the real running B back to pre-operational: no board ran.
    let mut n = SupNet::new(Params::default());
    let bus1 = [n.buses[0]];
    inject(&mut n, &bus1, heartbeat(a(0), 5), Some(ms(1001)), PERIOD);
    n.kill_slave_at(a(0), ms(1003));
    n.kill_master_at(WEAK, ms(900));
    n.revive_master_at(WEAK, ms(1200));
    n.kill_master_at(STRONG, ms(1500));
    n.sim.run_until(ms(2000));
    // The weak master finds 0x10 suspect one window after it first heard it, on bus 1 only
    // (bus 2 carrying 0x750, of lower priority, all along).
    let first = *arrivals(&n, 0, 0x710)
        .iter()
        .find(|t| **t > ms(1200))
        .unwrap();
    let weak: Vec<_> = suspects(&n, WEAK)
        .into_iter()
        .filter(|s| s.0 > ms(1200))
        .collect();
    assert_eq!(
        weak.first(),
        Some(&(first + WINDOW, Suspicion::OneBus { heard: 0 })),
        "{weak:?}"
    );
    // It takes over with B active and running; B is never sent back.
    assert_eq!(n.active_member(WEAK, 0), Some(Member::B));
    assert!(!n
        .nmt_first_copies()
        .iter()
        .any(|x| x.0 > ms(1200) && x.1 == WEAK && x.3 == b(0) && x.2 != NmtCommand::Start));
    assert!(running(&n, b(0)));
}
