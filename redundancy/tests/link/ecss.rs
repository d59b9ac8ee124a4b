//! ECSS bus-toggle mode on the simulated dual bus: slaves follow the redundancy master's
//! heartbeat, toggling every Ttoggle periods up to Ntoggle times, with the frames on the wire.

use crate::sim::*;
use duocan::od::ObjectDictionary;
use duocan::sim::{FaultRates, RxFault, TraceRecord, TxOutcome};
use duocan::{Duration, Frame, Id, Instant, NmtCommand, NmtState, NmtTarget, NodeId};
use duocan_redundancy::{DualBusConfig, EcssConfig, LinkEventKind, LinkMode, SwitchReason};
use std::cell::RefCell;
use std::rc::Rc;

const SLAVES: u8 = 6;
/// The slaves' consumer time for the master's heartbeat (3 × its 50 ms period): `P`.
const P: Duration = Duration::from_millis(150);
const M: NodeId = NodeId::must(MASTER);

fn cfg(node: u8) -> DualBusConfig {
    let ecss = if node == MASTER {
        EcssConfig::master()
    } else {
        EcssConfig::slave(M, P).with_ttoggle(2).with_ntoggle(4)
    };
    DualBusConfig::with_guard_period(
        LinkMode::EcssToggle(ecss),
        Duration::from_millis(HB_MS as u64),
    )
}

/// The toggle-related events of `node`.
fn toggles(net: &Net, node: u8) -> Vec<(Instant, LinkEventKind)> {
    net.link_events(node)
        .into_iter()
        .filter(|e| {
            matches!(
                e.kind,
                LinkEventKind::MasterLost { .. }
                    | LinkEventKind::Toggle { .. }
                    | LinkEventKind::NoMaster { .. }
                    | LinkEventKind::MasterFound { .. }
                    | LinkEventKind::Channel { .. }
            )
        })
        .map(|e| (e.at, e.kind))
        .collect()
}

fn master_heartbeats(net: &Net, bus: usize) -> Vec<Instant> {
    net.wire(bus)
        .into_iter()
        .filter(|x| {
            x.1 == MASTER
                && x.2.id() == Id::Standard(0x701)
                && matches!(x.3, TxOutcome::Delivered { .. })
        })
        .map(|x| x.0)
        .collect()
}

fn app_frames_of(net: &Net, bus: usize, node: u8) -> Vec<Instant> {
    let tpdo = |f: &Frame| f.id() == Id::Standard(0x180 + node as u16);
    net.wire(bus)
        .into_iter()
        .filter(|x| x.1 == node && tpdo(&x.2))
        .map(|x| x.0)
        .collect()
}

#[test]
fn slaves_follow_the_master_to_the_other_bus_after_t_minus_one_periods() {
    let stop = Instant::from_millis(2_500);
    let mut net = network_with(21, SLAVES, cfg, stop);
    let m = net.dev(MASTER);
    let t = Instant::from_millis(1_000);
    net.sim.at(t, move |sim| {
        assert!(sim.device_mut(m).link.select_channel(t, 1));
    });
    net.sim.run_until(stop);

    assert_eq!(
        toggles(&net, MASTER),
        [(
            t,
            LinkEventKind::Channel {
                from: 0,
                to: 1,
                reason: SwitchReason::Command
            }
        )]
    );
    let last = *master_heartbeats(&net, 0).last().unwrap();
    assert!(last <= t);
    let toggle_at = last + P + P; // lost after P, first toggle (Ttoggle − 1) × P later
    let found = master_heartbeats(&net, 1)
        .into_iter()
        .find(|h| *h > toggle_at)
        .unwrap();
    for node in 2..=SLAVES + 1 {
        assert_eq!(
            toggles(&net, node),
            [
                (last + P, LinkEventKind::MasterLost { master: M, bus: 0 }),
                (
                    toggle_at,
                    LinkEventKind::Toggle {
                        from: 0,
                        to: 1,
                        ctoggle: 1
                    }
                ),
                (found, LinkEventKind::MasterFound { master: M, bus: 1 }),
            ],
            "node {node}"
        );
        let ecss = net.station(node).link.ecss().unwrap();
        assert_eq!((ecss.bdefault(), ecss.ctoggle()), (1, 1));
        // The dictionary shows it: 0x2000 sub 1 Bdefault and sub 4 Ctoggle.
        let od = net.station(node).machine.a.od();
        assert_eq!(
            (od.get_u32(0x2000, 1), od.get_u32(0x2000, 4)),
            (Some(1), Some(1))
        );
        // On the wire: the slave's traffic on bus 1 until the toggle, on bus 2 after it.
        assert!(app_frames_of(&net, 0, node).iter().all(|x| *x <= toggle_at));
        let on_2 = app_frames_of(&net, 1, node);
        assert!(on_2.len() > 100 && on_2.iter().all(|x| *x > toggle_at));
        // The master's frames on bus 2 before the toggle were not delivered: the first master
        // heartbeat the slave saw on bus 2 is the one that found it.
        assert!(master_heartbeats(&net, 1)[0] < toggle_at);
    }
}

#[test]
fn without_a_master_slaves_toggle_n_times_then_stay_and_report_until_it_returns() {
    let stop = Instant::from_millis(4_000);
    let mut net = network_with(22, SLAVES, cfg, stop);
    let m = net.dev(MASTER).erased();
    net.sim
        .at(Instant::from_millis(1_000), move |sim| sim.power_off(m));
    net.sim
        .at(Instant::from_millis(3_000), move |sim| sim.power_on(m));
    net.sim.run_until(stop);

    let hbs = master_heartbeats(&net, 0);
    let last = *hbs
        .iter()
        .rfind(|h| **h <= Instant::from_millis(1_000))
        .unwrap();
    let back = *hbs
        .iter()
        .find(|h| **h > Instant::from_millis(3_000))
        .unwrap();
    let tg = |n: u64, from, to, c| {
        (
            last + P + P + (P + P).saturating_mul(n),
            LinkEventKind::Toggle {
                from,
                to,
                ctoggle: c,
            },
        )
    };
    for node in 2..=SLAVES + 1 {
        assert_eq!(
            toggles(&net, node),
            [
                (last + P, LinkEventKind::MasterLost { master: M, bus: 0 }),
                tg(0, 0, 1, 1),
                tg(1, 1, 0, 2),
                tg(2, 0, 1, 3),
                tg(3, 1, 0, 4),
                // The fourth toggle is the last: "no master" at its instant, and bus 1, where
                // the search ended, is the default.
                (
                    tg(3, 1, 0, 4).0,
                    LinkEventKind::NoMaster { bus: 0, ctoggle: 4 }
                ),
                (back, LinkEventKind::MasterFound { master: M, bus: 0 }),
            ],
            "node {node}"
        );
        let ecss = net.station(node).link.ecss().unwrap();
        assert!(!ecss.no_master());
        assert_eq!((ecss.bdefault(), ecss.ctoggle()), (0, 4));
        // On the wire: the slave's frames alternate between the buses while it searches.
        let on_2 = app_frames_of(&net, 1, node);
        assert!(!on_2.is_empty());
        assert!(on_2
            .iter()
            .all(|x| (*x > tg(0, 0, 1, 1).0 && *x <= tg(1, 1, 0, 2).0)
                || (*x > tg(2, 0, 1, 3).0 && *x <= tg(3, 1, 0, 4).0)));
    }
}

/// What a slave shows at one instant: NMT state, 0x2000 sub 1 and sub 4 in its dictionary, and
/// the layer's own Bdefault and Ctoggle.
type Sample = (Instant, NmtState, u8, u8, u8, u8);

#[test]
fn losing_the_master_puts_the_slave_in_pre_operational_and_0x2000_shows_the_toggling() {
    let stop = Instant::from_millis(4_000);
    let mut net = network_with(23, SLAVES, cfg, stop);
    let m = net.dev(MASTER);
    let start = Instant::from_millis(500);
    net.sim.at(start, move |sim| {
        let node = &mut sim.device_mut(m).machine.a;
        node.nmt_command(start, NmtCommand::Start, NmtTarget::All)
            .unwrap();
    });
    let me = m.erased();
    net.sim
        .at(Instant::from_millis(1_000), move |sim| sim.power_off(me));
    net.sim
        .at(Instant::from_millis(3_000), move |sim| sim.power_on(me));
    let samples: Rc<RefCell<Vec<Sample>>> = Rc::default();
    let s = net.dev(2);
    for k in 60..400u64 {
        let t = Instant::from_millis(10 * k);
        let out = samples.clone();
        net.sim.at(t, move |sim| {
            let st = sim.device(s);
            let od = st.machine.a.od();
            let read = |sub| od.get_u32(0x2000, sub).unwrap() as u8;
            let ecss = st.link.ecss().unwrap();
            out.borrow_mut().push((
                t,
                st.machine.a.nmt_state(),
                read(1),
                read(4),
                ecss.bdefault(),
                ecss.ctoggle(),
            ));
        });
    }
    net.sim.run_until(stop);

    let lost = net
        .link_events(2)
        .into_iter()
        .find(|e| matches!(e.kind, LinkEventKind::MasterLost { .. }))
        .unwrap()
        .at;
    let samples = samples.borrow();
    let mut seen = std::collections::BTreeSet::new();
    for &(t, state, od_b, od_c, b, c) in samples.iter() {
        // The dictionary always shows what the layer does.
        assert_eq!((od_b, od_c), (b, c), "at {t}");
        seen.insert(c);
        if t < lost {
            assert_eq!(
                state,
                NmtState::Operational,
                "at {t}: started before the loss"
            );
        } else {
            assert_eq!(
                state,
                NmtState::PreOperational,
                "at {t}: pre-operational after it"
            );
        }
    }
    // Ctoggle counted 0 to Ntoggle (4) in the dictionary.
    assert_eq!(seen.into_iter().collect::<Vec<_>>(), [0, 1, 2, 3, 4]);
    // Read over SDO-visible state at the end: the master is back on bus 1, Ctoggle stays 4.
    assert_eq!(samples.last().map(|x| (x.2, x.3)), Some((0, 4)));
}

/// The instants at which `node` received a heartbeat of the master on `bus`: delivered on the
/// wire and not dropped at `node`'s port (whether the layer listened to that bus or not).
fn heard(net: &Net, node: u8, bus: usize) -> Vec<Instant> {
    let me = net.dev(node).erased();
    let mut v: Vec<Instant> = vec![];
    for r in net.sim.trace() {
        match r {
            TraceRecord::Tx(x)
                if x.bus == net.buses[bus]
                    && x.frame.id() == Id::Standard(0x700 + MASTER as u16)
                    && !x.babble
                    && matches!(x.outcome, TxOutcome::Delivered { .. }) =>
            {
                v.push(x.end)
            }
            // A receiver's fault follows its frame's record.
            TraceRecord::Rx(x)
                if x.bus == net.buses[bus]
                    && x.port.device == me
                    && x.fault == RxFault::Dropped
                    && x.frame.id() == Id::Standard(0x700 + MASTER as u16) =>
            {
                assert_eq!(v.pop(), Some(x.at));
            }
            _ => {}
        }
    }
    v
}

/// The last of `times` at or before `t`.
fn last_by(times: &[Instant], t: Instant) -> Instant {
    times[times.partition_point(|x| *x <= t) - 1]
}

/// The first of `times` after `t`.
fn first_after(times: &[Instant], t: Instant) -> Instant {
    times[times.partition_point(|x| *x <= t)]
}

#[test]
fn a_flaky_default_bus_does_not_make_the_slaves_oscillate() {
    let slaves = 4;
    let stop = Instant::from_millis(30_000);
    let mut net = network_with(24, slaves, cfg, stop);
    let (a, m) = (net.buses[0], net.dev(MASTER));
    let s = Instant::from_millis;
    // 0.5–3.5 s: bus 1 loses every seventh frame, the master's heartbeats among them.
    net.sim.at(s(500), move |sim| sim.drop_every_on_bus(a, 7));
    net.sim.at(s(3_500), move |sim| sim.drop_every_on_bus(a, 0));
    // Two outages of bus 1: one longer than a whole search (1.5 s), one shorter (0.5 s).
    for (down, up) in [(4_000, 5_500), (7_000, 7_500)] {
        net.sim.at(s(down), move |sim| sim.bus_down(a));
        net.sim.at(s(up), move |sim| sim.bus_up(a));
    }
    // 9 s: the master is moved to bus 2. From 10 s on, bus 1 flaps every 300 ms and loses
    // half of what it carries: the slaves must not follow it.
    let moved = s(9_000);
    net.sim.at(moved, move |sim| {
        assert!(sim.device_mut(m).link.select_channel(moved, 1));
    });
    net.sim.at(s(10_000), move |sim| {
        sim.set_bus_faults(a, FaultRates::NONE.with_drop(0.5))
    });
    for k in 0..33u64 {
        let t = s(10_000 + 600 * k);
        net.sim.at(t, move |sim| sim.bus_down(a));
        net.sim
            .at(t + Duration::from_millis(300), move |sim| sim.bus_up(a));
    }
    net.sim.run_until(stop);

    // The master moved once, when told to.
    assert_eq!(
        toggles(&net, MASTER),
        [(
            moved,
            LinkEventKind::Channel {
                from: 0,
                to: 1,
                reason: SwitchReason::Command
            }
        )]
    );
    let tg = |at, from, to, ctoggle| (at, LinkEventKind::Toggle { from, to, ctoggle });
    let lost = |at, bus| (at, LinkEventKind::MasterLost { master: M, bus });
    let found = |at, bus| (at, LinkEventKind::MasterFound { master: M, bus });
    for node in 2..=slaves + 1 {
        let (on_1, on_2) = (heard(&net, node, 0), heard(&net, node, 1));
        // The drops did hit the master's heartbeats, but never for a consumer time.
        let early = |v: &[Instant]| -> Vec<Instant> {
            v.iter()
                .copied()
                .filter(|t| *t >= s(400) && *t <= s(3_600))
                .collect()
        };
        let (sent, got) = (early(&master_heartbeats(&net, 0)), early(&on_1));
        assert!(
            got.len() + 4 < sent.len(),
            "node {node}: {} of {}",
            got.len(),
            sent.len()
        );
        assert!(got.windows(2).all(|w| w[1] - w[0] < P), "node {node}");

        // The long outage: four toggles, "no master" with the fourth, back on bus 1 (the
        // default again) when the master is heard there.
        let h1 = last_by(&on_1, s(4_000));
        let p = |n: u64| P.saturating_mul(n);
        let f1 = first_after(&on_1, s(5_500));
        // The short one: found on bus 1 when the second toggle brings the slave back. (The
        // toggles fall on the heartbeat grid: a heartbeat ending at a toggle's instant reaches
        // the slave just before it toggles, on the bus it leaves.)
        let h2 = last_by(&on_1, s(7_000));
        let f2 = first_after(&on_1, h2 + p(4));
        // The move: found on bus 2 at the first toggle; that bus is the default.
        let h3 = last_by(&on_1, moved);
        let f3 = first_after(&on_2, h3 + p(2));
        assert_eq!(
            toggles(&net, node),
            [
                lost(h1 + p(1), 0),
                tg(h1 + p(2), 0, 1, 1),
                tg(h1 + p(4), 1, 0, 2),
                tg(h1 + p(6), 0, 1, 3),
                tg(h1 + p(8), 1, 0, 4),
                (h1 + p(8), LinkEventKind::NoMaster { bus: 0, ctoggle: 4 }),
                found(f1, 0),
                lost(h2 + p(1), 0),
                tg(h2 + p(2), 0, 1, 1),
                tg(h2 + p(4), 1, 0, 2),
                found(f2, 0),
                lost(h3 + p(1), 0),
                tg(h3 + p(2), 0, 1, 1),
                found(f3, 1),
            ],
            "node {node}"
        );
        assert!(
            f3 < s(9_500),
            "node {node}: settled on bus 2 before bus 1 began to flap"
        );
        let st = net.station(node);
        let ecss = st.link.ecss().unwrap();
        assert_eq!(
            (ecss.active_bus(), ecss.bdefault(), ecss.ctoggle()),
            (1, 1, 1),
            "node {node}"
        );
        let od = st.machine.a.od();
        assert_eq!(
            (od.get_u32(0x2000, 1), od.get_u32(0x2000, 4)),
            (Some(1), Some(1)),
            "node {node}"
        );
    }
}

/// How one search for the master ended.
#[derive(Debug, Default)]
struct Searches {
    /// Found after this many toggles (index 0 to Ntoggle − 1).
    found_after: [usize; 4],
    /// Ended with "no master" (then found, or not, later).
    no_master: usize,
}

/// Checks `node`'s events against the rule, search by search, with the instants taken from the
/// heartbeats it actually received: every loss exactly `P` after the last heartbeat heard on
/// the active bus, the k-th toggle `(2k − 1)·P` after the loss, at most 4, "no master" with the
/// fourth and only then, the master found at the first heartbeat heard on the bus the slave is
/// on, and nothing between searches.
fn check_searches(net: &Net, node: u8) -> Searches {
    let on = [heard(net, node, 0), heard(net, node, 1)];
    let ev = toggles(net, node);
    let mut out = Searches::default();
    let (mut i, mut bus) = (0, 0u8);
    while i < ev.len() {
        let (at, kind) = ev[i];
        assert_eq!(
            kind,
            LinkEventKind::MasterLost { master: M, bus },
            "node {node} at {at}"
        );
        assert_eq!(
            last_by(&on[bus as usize], at) + P,
            at,
            "node {node}: loss at {at}"
        );
        let (lost, mut last) = (at, at);
        i += 1;
        let mut k = 0u8;
        while let Some((at, LinkEventKind::Toggle { from, to, ctoggle })) = ev.get(i).copied() {
            k += 1;
            assert_eq!(at, lost + P.saturating_mul(2 * k as u64 - 1), "node {node}");
            assert_eq!(
                (from, to, ctoggle),
                (bus, 1 - bus, k),
                "node {node} at {at}"
            );
            (bus, last) = (to, at);
            i += 1;
        }
        assert!(k <= 4, "node {node}: {k} toggles after the loss at {lost}");
        if k == 4 {
            let no_master = LinkEventKind::NoMaster { bus, ctoggle: 4 };
            assert_eq!(ev.get(i), Some(&(last, no_master)), "node {node}");
            out.no_master += 1;
            i += 1;
        }
        let Some(&(at, kind)) = ev.get(i) else {
            break;
        };
        assert_eq!(
            kind,
            LinkEventKind::MasterFound { master: M, bus },
            "node {node}"
        );
        assert_eq!(at, first_after(&on[bus as usize], last), "node {node}");
        if k < 4 {
            // Before the next toggle was due (one due at the same instant comes after it).
            let next = lost + P.saturating_mul(2 * k as u64 + 1);
            assert!(
                at <= next,
                "node {node}: found at {at} after a toggle due at {next}"
            );
            out.found_after[k as usize] += 1;
        }
        i += 1;
    }
    out
}

#[test]
fn under_random_losses_of_the_masters_heartbeat_every_search_is_exact_and_bounded() {
    let slaves = 4;
    let stop = Instant::from_millis(60_000);
    let mut net = network_with(25, slaves, cfg, stop);
    let a = net.buses[0];
    // From 1 s on, each receiver of bus 1, where the master stays, loses each frame with
    // probability 0.6: three heartbeats in a row are lost now and then, and so is the master.
    net.sim.at(Instant::from_millis(1_000), move |sim| {
        sim.set_bus_faults(a, FaultRates::NONE.with_drop(0.6))
    });
    net.sim.run_until(stop);

    assert_eq!(
        toggles(&net, MASTER),
        [],
        "the master never moves by itself"
    );
    let mut total = Searches::default();
    for node in 2..=slaves + 1 {
        let s = check_searches(&net, node);
        for k in 0..4 {
            total.found_after[k] += s.found_after[k];
        }
        total.no_master += s.no_master;
        // Bounded: at most Ntoggle toggles per loss, however long the run.
        let count =
            |f: fn(&LinkEventKind) -> bool| toggles(&net, node).iter().filter(|e| f(&e.1)).count();
        let losses = count(|k| matches!(k, LinkEventKind::MasterLost { .. }));
        let toggled = count(|k| matches!(k, LinkEventKind::Toggle { .. }));
        assert!(
            toggled <= 4 * losses,
            "node {node}: {toggled} toggles, {losses} losses"
        );
    }
    // The run went through every way a search can end here: the master found before the first
    // toggle, after the second (back on bus 1), or "no master". Never after an odd number: the
    // master stays on bus 1.
    assert!(
        total.found_after[0] > 0 && total.found_after[2] > 0 && total.no_master > 0,
        "{total:?}"
    );
    assert_eq!((total.found_after[1], total.found_after[3]), (0, 0));
}
