//! The flying master as a pure machine: several devices on a zero-latency wire, each beating
//! every 20 ms, with exact instants for negotiation, takeover and conflict resolution.

use duocan::{Duration, Frame, Id, Instant, NodeId};
use duocan_redundancy::supervisor::flying_master::{
    FlyingEvent, FlyingMaster, FlyingMasterConfig, MasterReason, MasterRole, Rank,
};

const HB: Duration = Duration::from_millis(20);
const TIMEOUT: Duration = Duration::from_millis(50);

fn ms(x: u64) -> Instant {
    Instant::from_millis(x)
}

struct Dev {
    fm: FlyingMaster,
    alive: bool,
    /// Heard by the devices of the same group only (partition).
    group: u8,
    next_hb: Instant,
    roles: Vec<(Instant, MasterRole, MasterReason)>,
}

struct Wire {
    devs: Vec<Dev>,
    now: Instant,
    log: Vec<(Instant, usize, Frame)>,
}

impl Wire {
    fn new(ranks: &[(u8, u8)], cfg: impl Fn(FlyingMasterConfig) -> FlyingMasterConfig) -> Wire {
        let mut devs = vec![];
        for &(prio, node) in ranks {
            let mut fm = FlyingMaster::new(cfg(FlyingMasterConfig::new(
                prio,
                NodeId::must(node),
                TIMEOUT,
            )));
            for &(p2, n2) in ranks.iter().filter(|r| r.1 != node) {
                fm.add_peer(Rank::new(p2, NodeId::must(n2))).unwrap();
            }
            devs.push(Dev {
                fm,
                alive: false,
                group: 0,
                next_hb: Instant::ZERO,
                roles: vec![],
            });
        }
        Wire {
            devs,
            now: Instant::ZERO,
            log: vec![],
        }
    }
    fn start(&mut self, i: usize, t: Instant) {
        self.devs[i].alive = true;
        self.devs[i].fm.start(t);
        self.devs[i].next_hb = t;
        self.flush(i);
    }
    /// Delivers what device `i` sent to every device that hears it, recursively.
    fn flush(&mut self, i: usize) {
        for f in take(self, i) {
            self.log.push((self.now, i, f));
            for j in 0..self.devs.len() {
                if j != i && self.devs[j].alive && self.devs[j].group == self.devs[i].group {
                    self.devs[j].fm.handle_frame(self.now, &f);
                    self.flush(j);
                }
            }
        }
    }
    fn beat(&mut self, i: usize) {
        let node = self.devs[i].fm.rank().node;
        for j in 0..self.devs.len() {
            if j != i && self.devs[j].alive && self.devs[j].group == self.devs[i].group {
                self.devs[j].fm.heartbeat(self.now, node, false);
                self.flush(j);
            }
        }
    }
    fn run_until(&mut self, end: Instant) {
        loop {
            let mut next: Option<Instant> = None;
            for d in self.devs.iter().filter(|d| d.alive) {
                for t in [d.fm.poll_timeout(), Some(d.next_hb)].into_iter().flatten() {
                    next = Some(next.map_or(t, |n: Instant| n.min(t)));
                }
            }
            let Some(t) = next.filter(|t| *t <= end) else {
                self.now = end;
                return;
            };
            self.now = t;
            for i in 0..self.devs.len() {
                if !self.devs[i].alive {
                    continue;
                }
                if self.devs[i].next_hb <= t {
                    self.devs[i].next_hb = t + HB;
                    self.beat(i);
                }
                if self.devs[i].fm.poll_timeout().is_some_and(|x| x <= t) {
                    self.devs[i].fm.handle_timeout(t);
                    self.flush(i);
                }
            }
        }
    }
    fn actives(&self) -> Vec<usize> {
        (0..self.devs.len())
            .filter(|i| self.devs[*i].alive && self.devs[*i].fm.is_active())
            .collect()
    }
    fn sent(&self, id: u16) -> Vec<(Instant, usize, Vec<u8>)> {
        self.log
            .iter()
            .filter(|(_, _, f)| f.id() == Id::Standard(id))
            .map(|(t, i, f)| (*t, *i, f.data().to_vec()))
            .collect()
    }
}

#[test]
fn power_on_negotiation_the_best_rank_announces_first() {
    let mut w = Wire::new(&[(1, 2), (0, 1)], |c| c);
    w.start(0, ms(0));
    w.start(1, ms(0));
    w.run_until(ms(3000));
    // Detection 100 ms, then negotiation: 500 + 0 × 1500 + 1 × 10 ms for node 1.
    assert_eq!(
        w.devs[1].roles,
        [
            (ms(0), MasterRole::Detecting, MasterReason::PowerOn),
            // Node 2's request (handled first at 100 ms) starts node 1's negotiation.
            (
                ms(100),
                MasterRole::Negotiating,
                MasterReason::NegotiationRequested
            ),
            (ms(610), MasterRole::Active, MasterReason::NegotiationWon),
        ]
    );
    let strong = Rank::new(0, NodeId::must(1));
    assert_eq!(
        w.devs[0].roles.last(),
        Some(&(
            ms(610),
            MasterRole::Standby(Some(strong)),
            MasterReason::ActiveMasterFound(strong)
        ))
    );
    assert_eq!(w.sent(0x71)[0], (ms(610), 1, vec![0, 1]));
    assert_eq!(w.actives(), [1]);
    // The active master sends 0x76 every detect cycle.
    w.run_until(ms(9000));
    let detects: Vec<_> = w.sent(0x76).iter().map(|x| x.0).collect();
    assert_eq!(detects, [ms(4610), ms(8610)]);
    assert_eq!(w.actives(), [1]);
}

#[test]
fn a_late_master_finds_the_active_one_and_stays_standby() {
    let mut w = Wire::new(&[(0, 1), (1, 2)], |c| c);
    w.start(1, ms(0));
    // Alone: 100 ms detection, then 500 + 1 × 1500 + 2 × 10 ms.
    w.run_until(ms(2119));
    assert_eq!(w.actives(), []);
    w.run_until(ms(2120));
    assert_eq!(w.actives(), [1]);
    // The strong master boots later: it asks, the weak one answers, it stays standby.
    w.start(0, ms(3000));
    w.run_until(ms(6000));
    assert_eq!(w.actives(), [1]);
    assert_eq!(
        w.devs[0].roles.last().map(|r| r.1),
        Some(MasterRole::Standby(Some(Rank::new(1, NodeId::must(2)))))
    );
}

#[test]
fn takeover_exactly_at_the_heartbeat_timeout_without_negotiation() {
    let mut w = Wire::new(&[(0, 1), (1, 2)], |c| c);
    w.start(0, ms(0));
    w.start(1, ms(0));
    w.run_until(ms(1000));
    assert_eq!(w.actives(), [0]);
    // Beats at 0, 20, …; the last before the kill at 1005 is at 1000.
    w.run_until(ms(1005));
    w.devs[0].alive = false;
    w.run_until(ms(2000));
    assert_eq!(
        w.devs[1].roles.last(),
        Some(&(
            ms(1050),
            MasterRole::Active,
            MasterReason::HeartbeatLost {
                master: NodeId::must(1),
                last: ms(1000)
            }
        ))
    );
    assert_eq!(w.sent(0x71).last().unwrap(), &(ms(1050), 1, vec![1, 2]));
}

#[test]
fn a_master_that_reboots_within_the_timeout_is_replaced_at_its_boot_up() {
    let mut w = Wire::new(&[(0, 1), (1, 2)], |c| c);
    w.start(0, ms(0));
    w.start(1, ms(0));
    w.run_until(ms(1000));
    // Node 1 reboots at 1010 (no heartbeat gap long enough for a timeout): its boot-up.
    w.run_until(ms(1010));
    w.devs[0].fm = FlyingMaster::new(FlyingMasterConfig::new(0, NodeId::must(1), TIMEOUT));
    w.devs[0]
        .fm
        .add_peer(Rank::new(1, NodeId::must(2)))
        .unwrap();
    w.devs[1].fm.heartbeat(ms(1010), NodeId::must(1), true);
    w.flush(1);
    w.start(0, ms(1010));
    w.run_until(ms(3000));
    assert_eq!(w.actives(), [1]);
    assert_eq!(
        w.devs[1].roles.last(),
        Some(&(
            ms(1010),
            MasterRole::Active,
            MasterReason::MasterRebooted(NodeId::must(1))
        ))
    );
    assert!(matches!(w.devs[0].fm.role(), MasterRole::Standby(Some(r)) if r.node.raw() == 2));
}

#[test]
fn with_three_masters_the_best_live_one_takes_over_first() {
    let mut w = Wire::new(&[(0, 1), (1, 2), (2, 3)], |c| c);
    for i in 0..3 {
        w.start(i, ms(0));
    }
    w.run_until(ms(1000));
    assert_eq!(w.actives(), [0]);
    w.devs[0].alive = false;
    w.run_until(ms(2000));
    assert_eq!(w.actives(), [1]);
    // Node 3 waited one device slot for the better node 2 and then followed it.
    assert!(w.devs[2].roles.iter().all(|r| r.1 != MasterRole::Active));
    assert_eq!(w.devs[1].roles.last().unwrap().0, ms(1050));
    // Both die: node 3 takes over at its own deadline.
    w.devs[1].alive = false;
    w.run_until(ms(3000));
    assert_eq!(w.actives(), [2]);
}

#[test]
fn healed_partition_the_worse_active_master_demotes_at_once() {
    let mut w = Wire::new(&[(0, 1), (1, 2)], |c| c);
    w.start(0, ms(0));
    w.start(1, ms(0));
    w.run_until(ms(1000));
    w.devs[1].group = 1;
    w.run_until(ms(1500));
    assert_eq!(w.actives(), [0, 1]);
    assert_eq!(w.devs[1].roles.last().unwrap().0, ms(1050));
    // Heal at 2001: the first heartbeat across (2020) reveals the conflict; the weak one demotes
    // in the same instant; the strong one was suspended for the detection timeout.
    w.run_until(ms(2001));
    w.devs[1].group = 0;
    w.run_until(ms(2100));
    assert_eq!(w.actives(), [0]);
    let strong = Rank::new(0, NodeId::must(1));
    assert_eq!(
        w.devs[1].roles.last(),
        Some(&(
            ms(2020),
            MasterRole::Standby(Some(strong)),
            MasterReason::ConflictLost(strong)
        ))
    );
    // The strong one heard the weak one's heartbeat return (2020) while active: it suspended its
    // commands for the detection timeout.
    assert!(!w.devs[0].fm.may_command(ms(2100)));
    assert!(w.devs[0].fm.may_command(ms(2120)));
}

#[test]
fn periodic_detection_finds_two_actives_that_never_lost_each_other() {
    // Two devices that both think they are active without ever hearing each other before (a
    // configuration where neither knew the other): 0x76 of the next detect cycle resolves it.
    let mut w = Wire::new(&[(0, 1), (1, 2)], |c| c);
    w.devs[1].group = 1;
    w.start(0, ms(0));
    w.start(1, ms(0));
    w.run_until(ms(2500));
    assert_eq!(w.actives(), [0, 1]);
    w.devs[1].group = 0;
    // Heartbeats cross from 2520 on: both had lost each other (never heard) → suspicion.
    w.run_until(ms(7000));
    assert_eq!(w.actives(), [0]);
}

#[test]
fn planned_hand_over_and_manual_take_over() {
    let mut w = Wire::new(&[(0, 1), (1, 2)], |c| c);
    w.start(0, ms(0));
    w.start(1, ms(0));
    w.run_until(ms(1000));
    let to = w.devs[0].fm.hand_over(ms(1000), None).unwrap();
    assert_eq!(to, Rank::new(1, NodeId::must(2)));
    w.flush(0);
    assert_eq!(w.actives(), [1]);
    assert_eq!(w.devs[1].roles.last().unwrap().2, MasterReason::Appointed);
    // The strong (better) standby takes it back by hand.
    w.run_until(ms(1200));
    w.devs[0].fm.take_over(ms(1200)).unwrap();
    w.flush(0);
    assert_eq!(w.actives(), [0]);
    // A standby's manual take-over from a better active master that heard it all along works
    // too (planned), while a hand-over with nobody alive is refused.
    w.run_until(ms(1400));
    w.devs[1].fm.take_over(ms(1400)).unwrap();
    w.flush(1);
    assert_eq!(w.actives(), [1]);
    w.devs[0].alive = false;
    w.run_until(ms(1600));
    assert!(w.devs[1].fm.hand_over(ms(1600), None).is_err());
    assert!(w.devs[1].fm.take_over(ms(1600)).is_err());
}

#[test]
fn revertive_asks_for_a_hand_back_once_the_better_master_is_heard_long_enough() {
    let mut w = Wire::new(&[(0, 1), (1, 2)], |c| c.with_revertive(true));
    w.start(1, ms(0));
    w.run_until(ms(3000));
    assert_eq!(w.actives(), [1]);
    assert_eq!(w.devs[1].fm.take_handback(), None);
    w.start(0, ms(3000));
    w.run_until(ms(3999));
    assert_eq!(w.devs[1].fm.take_handback(), None);
    // The strong master's first heartbeat at 3000 + hand-back delay 1 s.
    w.run_until(ms(4000));
    assert_eq!(
        w.devs[1].fm.take_handback(),
        Some(Rank::new(0, NodeId::must(1)))
    );
}

#[test]
fn malformed_and_foreign_frames_change_nothing() {
    let mut fm = FlyingMaster::new(FlyingMasterConfig::new(0, NodeId::must(1), TIMEOUT));
    fm.start(ms(0));
    while fm.poll_transmit().is_some() {}
    for f in [
        Frame::new(Id::Standard(0x71), &[0]).unwrap(),
        Frame::new(Id::Standard(0x71), &[0, 0]).unwrap(),
        Frame::new(Id::Standard(0x76), &[1, 200]).unwrap(),
        Frame::remote(Id::Standard(0x73), 0).unwrap(),
        Frame::new(Id::Extended(0x71), &[0, 2]).unwrap(),
    ] {
        fm.handle_frame(ms(1), &f);
    }
    assert_eq!(fm.role(), MasterRole::Detecting);
    assert!(!fm.handle_frame(ms(1), &Frame::new(Id::Standard(0x181), &[1]).unwrap()));
    // Master-capable request: everyone answers with its rank.
    fm.handle_frame(ms(2), &Frame::new(Id::Standard(0x75), &[]).unwrap());
    assert_eq!(fm.poll_transmit().unwrap().data(), &[0, 1]);
}

#[test]
fn a_clock_jump_sends_one_detection_request_not_one_per_missed_cycle() {
    let mut w = Wire::new(&[(0, 1)], |c| c);
    w.start(0, ms(0));
    w.run_until(ms(3000));
    assert_eq!(w.actives(), [0]);
    let before = w.sent(0x76).len();
    // An hour ahead: 900 detect cycles were missed. One request goes out, and the next one
    // is a cycle after the new time, not at the next missed grid point (which would be due
    // at once, again and again: a driver loop spinning through the hour).
    let t = Instant::from_secs(3600);
    w.now = t;
    assert!(w.devs[0].fm.poll_timeout().is_some_and(|d| d <= t));
    w.devs[0].fm.handle_timeout(t);
    w.flush(0);
    assert_eq!(w.sent(0x76).len(), before + 1);
    assert_eq!(
        w.devs[0].fm.poll_timeout(),
        Some(t + Duration::from_millis(4000))
    );
    w.run_until(t + Duration::from_millis(4000));
    assert_eq!(w.sent(0x76).len(), before + 2);
}

#[test]
fn a_zero_detect_cycle_means_no_periodic_detection() {
    // 0x1F90 sub 6 = 0: a request due again at the instant it was sent would stop time.
    let mut w = Wire::new(&[(0, 1)], |c| c.with_detect_cycle(Duration::ZERO));
    w.start(0, ms(0));
    w.run_until(ms(20_000));
    assert_eq!(w.actives(), [0]);
    assert!(w.sent(0x76).is_empty());
    assert!(w.devs[0].fm.poll_timeout().is_none_or(|d| d > ms(20_000)));
}

/// Frames sent since the last call, by COB-ID.
fn sent_ids(fm: &mut FlyingMaster) -> Vec<u16> {
    let mut ids = vec![];
    while let Some(f) = fm.poll_transmit() {
        ids.push(f.id().raw() as u16);
    }
    ids
}

#[test]
fn a_restart_of_an_active_master_leaves_none_of_its_timers_behind() {
    // Alone: detection until 100, negotiation (500 + 0 × 1500 + 1 × 10 ms) until 610.
    let mut fm = FlyingMaster::new(FlyingMasterConfig::new(0, NodeId::must(1), TIMEOUT));
    fm.start(ms(0));
    fm.handle_timeout(ms(100));
    fm.handle_timeout(ms(610));
    assert!(fm.is_active());
    assert_eq!(fm.poll_timeout(), Some(ms(4610)), "the periodic detection");
    // A foreign SYNC suspends its commands until 4500; then it starts over at 4450.
    fm.foreign_activity(ms(4400));
    assert!(!fm.may_command(ms(4400)));
    assert_eq!(sent_ids(&mut fm), [0x73, 0x72, 0x71, 0x76]);
    fm.start(ms(4450));
    assert_eq!(fm.role(), MasterRole::Detecting);
    // Neither the suspension (4500) nor the detection cycle (4610) of the active role is a
    // deadline of the detecting one.
    assert_eq!(fm.poll_timeout(), Some(ms(4550)));
    fm.handle_timeout(ms(4550));
    assert_eq!(fm.role(), MasterRole::Negotiating);
    assert_eq!(fm.poll_timeout(), Some(ms(5060)));
    fm.handle_timeout(ms(5060));
    assert!(fm.is_active() && fm.may_command(ms(5060)));
    // No 0x76 while detecting or negotiating: a request, a negotiation, the announcement.
    assert_eq!(sent_ids(&mut fm), [0x73, 0x72, 0x71]);
    assert_eq!(fm.poll_timeout(), Some(ms(9060)));
}

#[test]
fn a_hand_back_that_became_due_is_not_given_after_the_role_is_gone() {
    // Node 2 (priority 1), revertive, active alone at 100 + 500 + 1500 + 20 = 2120; the better
    // node 1 heard from 2200 on: the hand-back is due at 3200.
    let due = || {
        let cfg = FlyingMasterConfig::new(1, NodeId::must(2), TIMEOUT).with_revertive(true);
        let mut fm = FlyingMaster::new(cfg);
        fm.add_peer(Rank::new(0, NodeId::must(1))).unwrap();
        fm.start(ms(0));
        fm.handle_timeout(ms(100));
        fm.handle_timeout(ms(2120));
        assert!(fm.is_active());
        for t in (2200..=3200).step_by(20) {
            fm.heartbeat(ms(t), NodeId::must(1), false);
            fm.handle_timeout(ms(t));
        }
        fm
    };
    assert_eq!(due().take_handback(), Some(Rank::new(0, NodeId::must(1))));
    let mut fm = due();
    fm.start(ms(3210));
    assert_eq!(fm.role(), MasterRole::Detecting);
    assert_eq!(fm.take_handback(), None);
}

/// What device `i` sent (not delivered) and its role changes, recorded.
fn take(w: &mut Wire, i: usize) -> Vec<Frame> {
    let mut out = vec![];
    while let Some(f) = w.devs[i].fm.poll_transmit() {
        out.push(f);
    }
    while let Some(e) = w.devs[i].fm.poll_event() {
        if let FlyingEvent::Role(r) = e {
            w.devs[i].roles.push((r.at, r.to, r.reason));
        }
    }
    out
}

/// Two claims that cross: the weak master stops hearing the strong one (its only working port
/// runs behind, or both buses were down for a moment), takes over and announces itself; the
/// strong one, which heard it all along, steps down for it (a planned take-over, as far as it
/// can tell); the strong one's assertion, sent just before, reaches the weak one after it became
/// active, and it steps down too. Stepping down for a better master, the weak one hands the role
/// to it: the strong one is active again at once (appointed), the weak one follows. Before, each
/// followed the other; then each asked for the active master (nobody answered) and at the
/// detection timeout they negotiated: no active master for 100 + 510 ms (and before that, until
/// one of them died).
#[test]
fn claims_that_cross_leave_the_strong_master_active_at_once() {
    let mut w = Wire::new(&[(0, 1), (1, 2)], |c| c);
    w.start(0, ms(0));
    w.start(1, ms(0));
    w.run_until(ms(1000));
    assert_eq!(w.actives(), [0]);
    let (strong, weak) = (Rank::new(0, NodeId::must(1)), Rank::new(1, NodeId::must(2)));
    // From 1000 ms the weak master hears nothing of the strong one, which hears its heartbeats.
    let mut t = ms(1000);
    for k in 1.. {
        t = ms(1000 + k);
        if k % 20 == 0 {
            w.devs[0].fm.heartbeat(t, NodeId::must(2), false);
        }
        for i in 0..2 {
            if w.devs[i].fm.poll_timeout().is_some_and(|x| x <= t) {
                w.devs[i].fm.handle_timeout(t);
            }
        }
        take(&mut w, 0);
        if w.devs[1].fm.is_active() {
            break;
        }
        take(&mut w, 1);
    }
    let claim = take(&mut w, 1);
    w.devs[0].fm.foreign_activity(t);
    let assertion = take(&mut w, 0);
    assert!(!claim.is_empty() && !assertion.is_empty());
    for f in &claim {
        w.devs[0].fm.handle_frame(t, f);
    }
    let strong_asks = take(&mut w, 0);
    for f in &assertion {
        w.devs[1].fm.handle_frame(t, f);
    }
    let weak_asks = take(&mut w, 1);
    assert_eq!(
        w.devs[0].roles.last(),
        Some(&(
            t,
            MasterRole::Standby(Some(weak)),
            MasterReason::ConflictLost(weak)
        ))
    );
    assert_eq!(
        w.devs[1].roles.last(),
        Some(&(
            t,
            MasterRole::Standby(Some(strong)),
            MasterReason::ConflictLost(strong)
        ))
    );
    // The weak one handed the role to the strong one; the strong one asked who is active.
    assert!(weak_asks
        .iter()
        .any(|f| f.id() == Id::Standard(0x71) && f.data() == [0, 1]));
    for f in &weak_asks {
        w.devs[0].fm.handle_frame(t, f);
    }
    let announced = take(&mut w, 0);
    assert_eq!(
        w.devs[0].roles.last(),
        Some(&(t, MasterRole::Active, MasterReason::Appointed))
    );
    for f in strong_asks.iter().chain(&announced) {
        w.devs[1].fm.handle_frame(t, f);
    }
    assert_eq!(w.actives(), [0]);
    // From here the wire works both ways again: nothing changes.
    let changes = (w.devs[0].roles.len(), w.devs[1].roles.len());
    w.now = t;
    w.run_until(t + Duration::from_millis(2000));
    assert_eq!((w.devs[0].roles.len(), w.devs[1].roles.len()), changes);
    assert_eq!(w.actives(), [0]);
    assert_eq!(
        w.devs[1].fm.role(),
        MasterRole::Standby(Some(strong)),
        "the weak one follows"
    );
}
