//! Strong/weak master failover on the simulated dual bus: 20 pairs running, SYNC every 10 ms,
//! masters beat every 20 ms with a 50 ms master-heartbeat timeout.

use crate::net::*;
use duocan::time_stamp::TimeOfDay;
use duocan::{Duration, Id, Instant, NmtCommand};
use duocan_redundancy::supervisor::flying_master::{MasterReason, MasterRole};
use duocan_redundancy::supervisor::pairs::RoleReason;
use duocan_redundancy::Member;

const TIMEOUT: Duration = Duration::from_millis(50);
const SYNC: Duration = Duration::from_millis(10);
const ONE_MS: Duration = Duration::from_millis(1);
const KILL: Instant = Instant::from_millis(1503);

fn ms(x: u64) -> Instant {
    Instant::from_millis(x)
}

fn params() -> Params {
    Params {
        pairs: 20,
        ..Params::default()
    }
}

fn net(p: Params) -> SupNet {
    let mut n = SupNet::new(p);
    let m = n.master(STRONG);
    n.sim.device_mut(m).sup_mut().set_time(
        Instant::ZERO,
        TimeOfDay {
            days: 14_000,
            ms: 3_600_000,
        },
    );
    n
}

/// TIME frames (first copies): (end, sender, ms since 1984 minus the simulated ms).
fn time_offsets(n: &SupNet) -> Vec<(Instant, u8, i64)> {
    let mut v: Vec<(Instant, u8, i64)> = vec![];
    for (t, _, s, f) in n.delivered() {
        if f.id() != Id::Standard(0x100) {
            continue;
        }
        if v.last()
            .is_some_and(|l| t.saturating_since(l.0) < Duration::from_millis(2))
        {
            continue;
        }
        let tod = TimeOfDay::from_bytes(f.data()).unwrap();
        v.push((t, s, tod.total_ms() as i64 - (t.as_micros() / 1000) as i64));
    }
    v
}

/// The weak master took over exactly at the strong one's last heartbeat + the timeout.
fn assert_takeover(n: &SupNet) -> Instant {
    let last = n.last_heartbeat(STRONG, KILL);
    let t = last + TIMEOUT;
    let r = n.master_roles(WEAK);
    let take = r
        .iter()
        .find(|r| r.to == MasterRole::Active)
        .expect("takeover");
    assert_eq!(take.at, t);
    assert_eq!(
        take.reason,
        MasterReason::HeartbeatLost {
            master: duocan::NodeId::must(STRONG),
            last
        }
    );
    // Announced on the bus within 1 ms.
    let ann = n
        .delivered()
        .into_iter()
        .find(|(e, _, s, f)| *s == WEAK && *e >= t && f.id() == Id::Standard(0x71))
        .unwrap();
    assert!(ann.0 <= t + ONE_MS, "{ann:?}");
    t
}

#[test]
fn strong_master_killed_weak_takes_over_without_resets_or_sync_gap_and_supervises() {
    strong_master_killed(params());
}

/// The same on CAN FD buses (1 Mbit/s nominal, 5 Mbit/s data), the members of pairs 0 to 5
/// sending a 64-byte FD frame on every SYNC: the same takeover instant and bounds, and the
/// process data of the active members delivered once at the weak master across the takeover
/// and across pair 5's switch after it.
#[test]
fn on_fd_buses_strong_master_killed_weak_takes_over_and_fd_process_data_flows_once() {
    strong_master_killed(params().on_fd(5_000_000, 6));
}

fn strong_master_killed(p: Params) {
    let mut n = net(p);
    n.sim.run_until(ms(1500));
    assert_eq!(n.role(STRONG), MasterRole::Active);
    n.kill_master_at(STRONG, KILL);
    // Right after the takeover (at most 50 ms after the kill), pair 5's active member dies.
    n.kill_slave_at(a(5), ms(1560));
    n.sim.run_until(ms(3000));
    let t = assert_takeover(&n);
    assert!(t < ms(1560));

    // No slave reset but the failed one; no slave rebooted.
    assert_eq!(n.resets_in(KILL, ms(3000)), [a(5)]);
    assert!(n.boot_ups_in(KILL, ms(3000)).is_empty());
    // SYNC: the gap across the takeover is at most the timeout + one period, and the weak
    // master keeps the period.
    assert!(n.max_sync_gap(ms(1000), ms(3000)) <= TIMEOUT + SYNC);
    let weak: Vec<Instant> = n
        .syncs()
        .into_iter()
        .filter(|s| s.1 == WEAK)
        .map(|s| s.0)
        .collect();
    assert!(
        weak[0] <= t + ONE_MS,
        "first SYNC at once: {} vs {t}",
        weak[0]
    );
    for w in weak[1..].windows(2) {
        let d = w[1] - w[0];
        assert!(
            d >= SYNC - Duration::from_micros(200) && d <= SYNC + Duration::from_micros(200),
            "{w:?}"
        );
    }
    // TIME continues the strong master's time base: no jump beyond the 1 ms resolution.
    let offs = time_offsets(&n);
    assert!(offs.iter().any(|o| o.1 == STRONG) && offs.iter().any(|o| o.1 == WEAK));
    let base = offs[0].2;
    assert!(offs.iter().all(|o| (o.2 - base).abs() <= 1), "{offs:?}");

    // Pair supervision continues: B of pair 5 started by the weak master on time.
    let last_a = n.last_heartbeat(a(5), ms(1560));
    let start = n
        .nmt_first_copies()
        .into_iter()
        .find(|x| x.2 == NmtCommand::Start && x.3 == b(5))
        .unwrap();
    assert_eq!(start.1, WEAK);
    assert!(
        start.0 > last_a + Duration::from_millis(50)
            && start.0 <= last_a + Duration::from_millis(51)
    );
    let r = n.pair_roles(WEAK, 5);
    assert_eq!(
        r.last().unwrap().reason,
        RoleReason::ActiveSilent { last: last_a }
    );
    for i in 0..20 {
        let want = if i == 5 { Member::B } else { Member::A };
        assert_eq!(n.active_member(WEAK, i), Some(want), "pair {i}");
    }
    // FD process data: the strong master's while it ran, the weak one's all along (A's of
    // pair 0 through the takeover; pair 5's A until it died, B's from its start at about
    // 1.61 s to the end, about 139 cycles).
    let strong = [0, 5].map(|i| n.assert_fd_exactly_once(STRONG, i, KILL));
    let weak = [0, 5].map(|i| n.assert_fd_exactly_once(WEAK, i, ms(3000)));
    if p.fd.is_some() {
        assert!(strong.iter().all(|c| c[0] > 80 && c[1] == 0), "{strong:?}");
        assert!(weak[0][0] > 230 && weak[0][1] == 0, "{weak:?}");
        assert!(weak[1][0] > 80 && weak[1][1] > 130, "{weak:?}");
    } else {
        assert_eq!([strong, weak], [[[0; 2]; 2]; 2]);
    }
}

#[test]
fn strong_master_returns_and_stays_standby_non_revertive() {
    let mut n = net(params());
    n.kill_master_at(STRONG, KILL);
    n.revive_master_at(STRONG, ms(2500));
    n.sim.run_until(ms(6000));
    assert_takeover(&n);
    assert_eq!(n.role(WEAK), MasterRole::Active);
    assert!(matches!(n.role(STRONG), MasterRole::Standby(Some(r)) if r.node.raw() == WEAK));
    assert!(n.resets_in(KILL, ms(6000)).is_empty());
    assert!(n.max_sync_gap(ms(1000), ms(6000)) <= TIMEOUT + SYNC);
    // The returned master shadows the table.
    for i in 0..20 {
        assert_eq!(n.active_member(STRONG, i), Some(Member::A), "pair {i}");
    }
    assert!(n.syncs().iter().all(|s| s.0 < ms(2500) || s.1 == WEAK));
}

#[test]
fn revertive_planned_hand_back_without_sync_gap() {
    let mut n = net(Params {
        revertive_master: true,
        ..params()
    });
    n.kill_master_at(STRONG, KILL);
    n.revive_master_at(STRONG, ms(2500));
    n.sim.run_until(ms(6000));
    assert_takeover(&n);
    assert_eq!(n.role(STRONG), MasterRole::Active);
    let back = n
        .master_roles(STRONG)
        .into_iter()
        .rfind(|r| r.to == MasterRole::Active)
        .unwrap();
    assert_eq!(back.reason, MasterReason::Appointed);
    assert!(back.at > ms(3500) && back.at < ms(3600), "{}", back.at);
    assert!(n.resets_in(KILL, ms(6000)).is_empty());
    // Across the hand-back SYNC keeps its period: no gap, no doubled SYNC.
    let around: Vec<_> = n
        .syncs()
        .into_iter()
        .filter(|s| {
            s.0 > back.at - Duration::from_millis(100) && s.0 < back.at + Duration::from_millis(100)
        })
        .collect();
    assert!(around.iter().any(|s| s.1 == WEAK) && around.iter().any(|s| s.1 == STRONG));
    for w in around.windows(2) {
        let d = w[1].0 - w[0].0;
        assert!(
            d >= SYNC - Duration::from_micros(300) && d <= SYNC + Duration::from_micros(300),
            "{w:?}"
        );
    }
}
