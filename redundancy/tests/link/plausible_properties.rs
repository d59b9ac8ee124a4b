//! Property tests of heartbeat plausibility (`duocan_redundancy::link::plausible`) through the
//! dual-bus layer's public API: random heartbeat arrivals per bus, with jitter, losses, extra
//! heartbeats of state changes, babble bursts and impostors.
//!
//! - A well-behaved node (its producer period with jitter up to a quarter period, either copy
//!   lost now and then but never twice in a row on one bus, groups of up to three extra
//!   heartbeats at least twelve periods apart) is never suspect.
//! - A babble burst on one bus (consecutive frames less than `3T/20` apart) is flagged at its
//!   sixth frame at the latest, whatever came before, and its frames are dropped from then on;
//!   the node is suspect only while the other bus does not speak for it (no heartbeat there
//!   for 1.5 periods).
//! - Rule 1 is exactly the span rule the docs state: the first verdict is the first arrival
//!   that ends a span `s` holding more than `5 + 4s/(3T)` heartbeats.
//! - An impostor left alone on one bus is suspect exactly one reachability window after the
//!   node's last heartbeat on the other, healthy bus.

use duocan::machine::{BusLink, LinkRequest};
use duocan::{Duration, Frame, Id, Instant, NodeId};
use duocan_redundancy::{DualBus, DualBusConfig, LinkCommand, LinkMode};
use proptest::prelude::*;

const A: u8 = 0x10;
/// A lower-priority node beating on both buses: the witness that a bus is healthy.
const WITNESS: u8 = 0x50;

fn hb(node: u8, state: u8) -> Frame {
    Frame::from_array(Id::Standard(0x700 + node as u16), [state])
}

/// One arrival: (µs, port, frame, index in the burst if it is a babbled frame).
type Arrival = (u64, usize, Frame, Option<usize>);

/// The layer with both nodes watched at producer time `t_us`; reachability window 3 periods.
fn layer(t_us: u64) -> DualBus {
    let period = Duration::from_micros(t_us);
    let mut l = DualBus::new(DualBusConfig::with_guard_period(
        LinkMode::ActiveActive,
        period,
    ));
    for node in [A, WITNESS] {
        l.handle_command(
            Instant::ZERO,
            LinkCommand::Watch {
                node: NodeId::must(node),
                producer_ms: (t_us / 1000) as u16,
            },
        );
    }
    l
}

/// What the layer said, in order: (instant, node, suspect), and each arrival it dropped as
/// implausible (instant, port).
#[derive(Debug, Default)]
struct Outcome {
    verdicts: Vec<(u64, u8, bool)>,
    dropped: Vec<(u64, usize)>,
}

/// Feeds `arrivals` (sorted by time) to the layer, running its deadlines on time.
fn drive(l: &mut DualBus, arrivals: &[Arrival]) -> Outcome {
    let mut o = Outcome::default();
    let collect = |l: &mut DualBus, now: u64, o: &mut Outcome| {
        while let Some(r) = l.poll_machine_request() {
            if let LinkRequest::NodeSuspect { node, suspect, .. } = r {
                o.verdicts.push((now, node.raw(), suspect));
            }
        }
        while l.poll_transmit().is_some() {}
        while l.poll_event().is_some() {}
    };
    for (t, port, f, _) in arrivals {
        let now = Instant::from_micros(*t);
        while let Some(d) = l.poll_timeout().filter(|d| *d <= now) {
            l.handle_timeout(d);
            collect(l, d.as_micros(), &mut o);
        }
        let before = l.stats().implausible;
        let _ = l.handle_rx(now, *port, f);
        if l.stats().implausible > before {
            o.dropped.push((*t, *port));
        }
        collect(l, *t, &mut o);
    }
    o
}

/// A well-behaved node's arrivals: `periods` heartbeats every `t_us` from `start` with the
/// given jitters (µs, |j| ≤ T/4), losses per copy (never two in a row on one bus), the bus-2 copy
/// `skew` µs after the bus-1 one, and extra heartbeats (state changes) at `extras`.
fn well_behaved(
    node: u8,
    start: u64,
    t_us: u64,
    jitter: &[i64],
    lost: &[[bool; 2]],
    skew: u64,
    extras: &[(usize, u64, u8)],
) -> Vec<Arrival> {
    let mut v = vec![];
    let mut prev_lost = [false; 2];
    for (k, j) in jitter.iter().enumerate() {
        let t = (start + k as u64 * t_us) as i64 + j;
        for port in 0..2 {
            let drop = lost[k][port] && !prev_lost[port];
            prev_lost[port] = drop;
            if !drop {
                v.push((t as u64 + port as u64 * skew, port, hb(node, 5), None));
            }
        }
    }
    for &(k, off, n) in extras {
        let t = start + k as u64 * t_us + off;
        for i in 0..n as u64 {
            for port in 0..2 {
                v.push((t + i * 7 + port as u64 * skew, port, hb(node, 0x7F), None));
            }
        }
    }
    v
}

/// Extra heartbeats: groups of 1–3, at least twelve periods apart (one group per 24 periods,
/// anywhere in the first half), within the node's `periods` (after them the node is silent:
/// an extra heartbeat two periods after its last, its last copy on one bus lost, is a node
/// heard on one bus only for the reachability window, which rule 2 rightly calls suspect).
fn extras_in(periods: usize) -> impl Strategy<Value = Vec<(usize, u64, u8)>> {
    prop::collection::vec((0usize..12, 0u64..1000, 1u8..=3), periods.div_ceil(24)).prop_map(
        move |v| {
            v.into_iter()
                .enumerate()
                .map(|(g, (k, off, n))| (g * 24 + k, off, n))
                .filter(|(k, ..)| *k < periods)
                .collect()
        },
    )
}

prop_compose! {
    fn behaved(periods: usize)
        (t_ms in 10u64..=100)
        (t_us in Just(t_ms * 1000),
         jitter in prop::collection::vec(-(t_ms as i64 * 250)..=(t_ms as i64 * 250), periods),
         lost in prop::collection::vec(any::<[bool; 2]>()
             .prop_map(|[a, b]| [a && b, !a && b]), periods),
         skew in 0u64..1000,
         extras in extras_in(periods),
         witness_phase in 0u64..1000)
        -> (u64, Vec<i64>, Vec<[bool; 2]>, u64, Vec<(usize, u64, u8)>, u64)
    {
        (t_us, jitter, lost, skew, extras, witness_phase * t_us / 1000)
    }
}

fn witness(start: u64, t_us: u64, periods: usize) -> Vec<Arrival> {
    (0..periods as u64)
        .flat_map(|k| {
            (0..2usize).map(move |p| (start + k * t_us + 300 + p as u64, p, hb(WITNESS, 5), None))
        })
        .collect()
}

fn sorted(mut v: Vec<Arrival>) -> Vec<Arrival> {
    v.sort_by_key(|a| (a.0, a.1));
    v
}

/// Rule 1 as the docs state it, over one bus's arrivals.
fn too_fast_at(arrivals: &[u64], t_us: u64) -> Option<u64> {
    let t = t_us as i128;
    (0..arrivals.len()).find_map(|j| {
        (0..=j)
            .any(|i| {
                let count = (j - i + 1) as i128;
                let span = (arrivals[j] - arrivals[i]) as i128;
                3 * t * (count - 5) > 4 * span
            })
            .then_some(arrivals[j])
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn a_well_behaved_node_is_never_suspect(
        (t_us, jitter, lost, skew, extras, phase) in behaved(60)
    ) {
        let start = 1_000_000;
        let mut arrivals = well_behaved(A, start, t_us, &jitter, &lost, skew, &extras);
        arrivals.extend(witness(start + phase, t_us, 60));
        let mut l = layer(t_us);
        let o = drive(&mut l, &sorted(arrivals));
        prop_assert!(o.verdicts.is_empty(), "{:?}", o.verdicts);
        prop_assert!(o.dropped.is_empty());
        prop_assert_eq!(l.stats().implausible, 0);
    }

    #[test]
    fn a_babble_burst_is_flagged_by_its_sixth_frame(
        (t_us, jitter, lost, skew, extras, phase) in behaved(30),
        port in 0usize..2,
        at_period in 2usize..28,
        offset in 0u64..1000,
        spacing_per_mille in 1u64..150,
        len in 6usize..200,
        state in any::<u8>(),
    ) {
        let start = 1_000_000;
        let mut arrivals = well_behaved(A, start, t_us, &jitter, &lost, skew, &extras);
        arrivals.extend(witness(start + phase, t_us, 30));
        // Consecutive babbled frames less than 3T/20 apart (and at least 40 µs: a frame time).
        let spacing = (t_us * spacing_per_mille / 1000).clamp(40, t_us * 3 / 20 - 1);
        let b0 = start + at_period as u64 * t_us + offset * t_us / 1000;
        let f = Frame::from_array(Id::Standard(0x700 + A as u16), [state]);
        arrivals.extend((0..len).map(|i| (b0 + i as u64 * spacing, port, f, Some(i))));
        let mut l = layer(t_us);
        let o = drive(&mut l, &sorted(arrivals.clone()));
        // The bus is found too fast at the sixth babbled frame at the latest (earlier if the
        // node's own heartbeats or extras had filled the bucket), and from then on the burst's
        // frames are dropped on that bus.
        let verdict = o
            .dropped
            .iter()
            .find(|d| d.1 == port)
            .expect("a babbler is always flagged")
            .0;
        prop_assert!(verdict <= b0 + 5 * spacing);
        let burst_after: Vec<u64> = (0..len)
            .map(|i| b0 + i as u64 * spacing)
            .filter(|t| *t >= verdict)
            .collect();
        prop_assert!(burst_after
            .iter()
            .all(|t| o.dropped.contains(&(*t, port))));
        // The node itself is suspect only while the other bus does not speak for it (none of
        // its heartbeats there for 1.5 periods: a lost copy), or by rule 2 (the babbled bus
        // silent for the window after the burst and the node's last copy there).
        let on = |bus: usize, with_burst: bool| -> Vec<u64> {
            arrivals
                .iter()
                .filter(|a| a.1 == bus && (with_burst || a.3.is_none()))
                .filter(|a| a.2.id() == hb(A, 5).id())
                .map(|a| a.0)
                .collect()
        };
        let (other, babbled) = (on(1 - port, false), on(port, true));
        let last_before = |v: &[u64], t: u64| v.iter().copied().filter(|x| *x <= t).max();
        // What the other bus had carried when the verdict came: arrivals are handed over in
        // the order of their times, then of their ports, so one on the other bus at the
        // verdict's very instant came before it only from port 0.
        let other_before = |t: u64| {
            let shown = if port == 1 { t } else { t.saturating_sub(1) };
            last_before(&other, shown)
        };
        let window = 3 * t_us;
        for v in o.verdicts.iter().filter(|v| v.1 == A && v.2) {
            let rule_one = other_before(v.0).is_some_and(|l| v.0 > l + t_us * 3 / 2);
            let rule_two = last_before(&babbled, v.0).is_some_and(|l| v.0 >= l + window);
            prop_assert!(
                rule_one || rule_two,
                "suspect at {} with the other bus's last heartbeat at {:?}", v.0,
                other_before(v.0)
            );
        }
        prop_assert!(l.stats().implausible >= burst_after.len() as u64);
    }

    #[test]
    fn rule_one_is_the_span_rule(
        t_ms in 10u64..=50,
        gaps in prop::collection::vec(prop_oneof![0u64..200, 200u64..5_000, 5_000u64..60_000], 1..120),
    ) {
        let t_us = t_ms * 1000;
        let mut t = 1_000_000;
        let times: Vec<u64> = gaps.iter().map(|g| { t += g; t }).collect();
        let arrivals: Vec<Arrival> = times.iter().map(|t| (*t, 0, hb(A, 5), None)).collect();
        let mut l = layer(t_us);
        let o = drive(&mut l, &arrivals);
        let first = o.verdicts.iter().find(|v| v.1 == A && v.2).map(|v| v.0);
        prop_assert_eq!(first, too_fast_at(&times, t_us));
    }

    #[test]
    fn an_impostor_alone_on_one_bus_is_suspect_one_window_after_the_node_left_the_other(
        t_ms in 10u64..=100,
        periods in 6usize..20,
        dies_at in 0u64..1000,
        impostor_phase in 0u64..1000,
        bus in 0usize..2,
    ) {
        let t_us = t_ms * 1000;
        let start = 1_000_000;
        let death = start + periods as u64 * t_us + dies_at * t_us / 1000;
        // The real node on both buses until it dies; the impostor on `bus` from its death on,
        // at the node's period; the witness on both buses all along.
        let mut arrivals: Vec<Arrival> = vec![];
        let mut t = start;
        while t < death {
            for p in 0..2 {
                arrivals.push((t + p as u64, p, hb(A, 5), None));
            }
            t += t_us;
        }
        let last_other = arrivals.iter().filter(|a| a.1 != bus).map(|a| a.0).max().unwrap();
        let end = death + 10 * t_us;
        let mut t = death + impostor_phase * t_us / 1000;
        while t < end {
            arrivals.push((t, bus, hb(A, 5), None));
            t += t_us;
        }
        arrivals.extend(witness(start, t_us, (end - start) as usize / t_us as usize));
        let mut l = layer(t_us);
        let o = drive(&mut l, &sorted(arrivals));
        let window = 3 * t_us;
        prop_assert_eq!(
            o.verdicts.iter().filter(|v| v.1 == A).copied().collect::<Vec<_>>(),
            vec![(last_other + window, A, true)]
        );
        prop_assert_eq!(l.plausibility().one_bus(NodeId::must(A)), Some(bus as u8));
    }
}
