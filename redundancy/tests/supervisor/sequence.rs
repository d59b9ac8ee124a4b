//! Both buses failing one after the other, on a supervised network: bus 2 is down for a while,
//! and the instant it is repaired bus 1 is cut (a maintainer repairs one cable, then works on
//! the other). Traffic on the repaired bus is evidence that it works: every station sends and
//! merges on it at once, whatever its port's re-initialisation back-off says. So the strong
//! master stays the one active master (its heartbeats reach the weak one on bus 2 from the
//! first), SYNC goes on without a gap beyond the frame lost at the cut, no pair switches over
//! and no board is reset.
//!
//! (A layer that waited for the back-off — 100 ms doubling to 10 s — sent nothing on bus 2
//! for up to that long: the weak master took over while the strong one was alive, and the
//! network had two active masters and no SYNC for seconds.)

use super::net::*;
use duocan::{Duration, Instant};
use duocan_redundancy::supervisor::flying_master::MasterRole;

fn ms(x: u64) -> Instant {
    Instant::from_millis(x)
}

/// Bus 2 down from 1 s for `first`; at its repair bus 1 is cut, for good.
fn hand_over(first: Duration) {
    let mut n = SupNet::new(Params::default());
    let (cut1, cut2) = (n.buses[0], n.buses[1]);
    let down = ms(1000);
    let swap = down + first;
    let end = swap + Duration::from_millis(3000);
    n.sim.at(down, move |sim| sim.bus_down(cut2));
    n.sim.at(swap, move |sim| {
        sim.bus_up(cut2);
        sim.bus_down(cut1);
    });
    n.sim.run_until(end);

    // One active master all along: the weak one never took over.
    let weak: Vec<_> = n
        .master_roles(WEAK)
        .into_iter()
        .filter(|r| r.at >= down)
        .collect();
    assert!(weak.is_empty(), "{weak:?}");
    assert!(n
        .master_roles(STRONG)
        .iter()
        .all(|r| r.at < down || r.to == MasterRole::Active));
    assert_eq!(n.role(STRONG), MasterRole::Active);
    assert_ne!(n.role(WEAK), MasterRole::Active);
    // SYNC every 10 ms on whichever bus works: at the swap, at most the SYNC on the wire of
    // bus 1 at the cut is lost (a gap of two periods and a frame).
    let gap = n.max_sync_gap(down - Duration::from_millis(100), end);
    assert!(gap <= Duration::from_micros(20_200), "SYNC gap {gap}");
    // No pair switched over, no board was reset.
    for i in 0..n.p.pairs {
        let moved: Vec<_> = n
            .pair_roles(STRONG, i)
            .into_iter()
            .filter(|r| r.at >= down)
            .collect();
        assert!(moved.is_empty(), "pair {i}: {moved:?}");
    }
    assert!(
        n.resets_in(down, end).is_empty(),
        "{:?}",
        n.resets_in(down, end)
    );
}

#[test]
fn bus_2_repaired_as_bus_1_is_cut_after_1_s_one_master_and_sync_go_on() {
    hand_over(Duration::from_millis(1000));
}

#[test]
fn bus_2_repaired_as_bus_1_is_cut_after_3_s_one_master_and_sync_go_on() {
    hand_over(Duration::from_millis(3000));
}

#[test]
fn bus_2_repaired_as_bus_1_is_cut_after_19_s_one_master_and_sync_go_on() {
    hand_over(Duration::from_millis(19_000));
}
