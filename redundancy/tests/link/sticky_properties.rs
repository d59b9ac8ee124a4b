//! Property tests of the sticky merge (`link::sticky`) over the exact merge's fault schedules:
//! complete buses with skew either way, one bus dropping frames, a lagging lossy bus, a dead
//! bus (`merge_properties.rs`), buses cut and repaired at random, and the dual-bus layer with
//! a port whose frames come late by random steps either way, with and without receive
//! timestamps (`lag_properties.rs`).
//!
//! What is asserted, arrival by arrival (each arrival is a copy of a known occurrence):
//!
//! - no occurrence is ever delivered twice;
//! - every occurrence lost (none of its copies delivered) lies within one timeout after its
//!   stream's last frame on the bus it was bound to: each of its copies was judged after a
//!   frame of the same stream on the other bus stamped at most one timeout before it;
//! - a stream whose frames were all delivered from one bus (never switched away from it) that
//!   carried all of them lost none;
//! - each stream is delivered in the order sent;
//! - the merger's switch count is the number of times a stream's frames began to come from the
//!   other bus.
//!
//! With both buses complete, a stream that pauses for about the timeout may lose at the switch
//! the frames that follow the pause closer than the skew between the buses: that is the policy
//! (`a_pause_of_about_the_timeout_can_lose_frames_at_the_switch` shows it); a stream whose
//! pauses stay below the timeout less the skew loses nothing.

use crate::lag_properties::{run as lag_run, Run};
use crate::merge_properties::{schedule, Lossy, Schedule, W};
use duocan::machine::BusLink;
use duocan::{Duration, Frame, Id, Instant, NodeId};
use duocan_redundancy::link::sticky::{StickyMerger, StickyVerdict, StreamKey};
use duocan_redundancy::{DualBus, DualBusConfig, MergePolicy};
use proptest::prelude::*;

/// One arrival as the merge judged it.
#[derive(Clone, Copy, Debug)]
struct Seen {
    port: usize,
    /// Which occurrence it is a copy of (index into the schedule's frames, in send order per
    /// stream).
    occurrence: usize,
    stream: usize,
    /// The stamp the merge judged it by (µs).
    stamp: u64,
    delivered: bool,
}

/// Checks the properties of the module documentation over `seen`, in the order judged.
fn check(
    seen: &[Seen],
    occurrences: usize,
    timeout: u64,
    switches: u64,
) -> Result<(), TestCaseError> {
    let streams = seen.iter().map(|s| s.stream + 1).max().unwrap_or(0);
    let mut times = vec![0usize; occurrences];
    let mut arrived = vec![[false; 2]; occurrences];
    // Per arrival: the newest stamp of its stream on the other port judged before it.
    let mut newest = vec![[None::<u64>; 2]; streams];
    let mut cover = Vec::with_capacity(seen.len());
    // Per stream: the ports its deliveries came from, in order of delivery.
    let mut from: Vec<Vec<usize>> = vec![vec![]; streams];
    let mut last_delivered = vec![None::<usize>; streams];
    for s in seen {
        cover.push(newest[s.stream][1 - s.port]);
        let n = &mut newest[s.stream][s.port];
        *n = Some(n.map_or(s.stamp, |x| x.max(s.stamp)));
        arrived[s.occurrence][s.port] = true;
        if s.delivered {
            times[s.occurrence] += 1;
            prop_assert!(
                times[s.occurrence] == 1,
                "occurrence {} delivered twice",
                s.occurrence
            );
            prop_assert!(
                last_delivered[s.stream].is_none_or(|l| l < s.occurrence),
                "stream {}: {} after {:?}",
                s.stream,
                s.occurrence,
                last_delivered[s.stream]
            );
            last_delivered[s.stream] = Some(s.occurrence);
            from[s.stream].push(s.port);
        }
    }
    for (s, c) in seen.iter().zip(&cover) {
        if times[s.occurrence] == 0 {
            prop_assert!(
                c.is_some_and(|c| c + timeout >= s.stamp),
                "occurrence {} lost on port {} at {} µs, its stream last on the other port at {:?}",
                s.occurrence,
                s.port,
                s.stamp,
                c
            );
        }
    }
    let changes: usize = from
        .iter()
        .map(|f| f.windows(2).filter(|w| w[0] != w[1]).count())
        .sum();
    prop_assert_eq!(changes as u64, switches);
    for (stream, ports) in from.iter().enumerate() {
        let Some(&p) = ports.first() else { continue };
        if ports.iter().any(|q| *q != p) {
            continue;
        }
        // Never switched away from `p`: if `p` carried all of the stream, nothing was lost.
        let mine: Vec<usize> = seen
            .iter()
            .filter(|s| s.stream == stream)
            .map(|s| s.occurrence)
            .collect();
        if mine.iter().all(|o| arrived[*o][p]) {
            let lost: Vec<_> = mine.iter().filter(|o| times[**o] == 0).collect();
            prop_assert!(
                lost.is_empty(),
                "stream {stream} on bus {p} lost {:?}",
                lost
            );
        }
    }
    Ok(())
}

/// (bus, from, length) in µs: arrivals on the cut bus are lost.
type Cut = (usize, u64, u64);

/// Cuts of either bus.
fn cuts() -> impl Strategy<Value = Vec<Cut>> {
    prop::collection::vec((0..2usize, 0u64..130_000, 1_000u64..60_000), 1..4)
}

fn cut(mut s: Schedule, cuts: &[Cut]) -> Schedule {
    for arr in &mut s.arrivals {
        for (bus, from, len) in cuts {
            if arr[*bus].is_some_and(|t| t >= *from && t < from + len) {
                arr[*bus] = None;
            }
        }
    }
    s
}

/// Runs a sticky merger with `timeout` over a schedule, in time order (ties at random); each
/// sender is a node's stream.
fn run_core(s: &Schedule, timeout: u64) -> Result<(Vec<Seen>, StickyMerger), TestCaseError> {
    let mut events: Vec<(u64, u32, usize, usize)> = vec![];
    for (i, arr) in s.arrivals.iter().enumerate() {
        for (bus, t) in arr.iter().enumerate() {
            if let Some(t) = t {
                events.push((*t, s.ties[i][bus], bus, i));
            }
        }
    }
    events.sort();
    let mut m = StickyMerger::new(Duration::from_micros(timeout));
    let mut seen = vec![];
    for (t, _, port, i) in events {
        let sender = s.sent[i].sender;
        let key = StreamKey::Node(NodeId::must(sender as u8 + 1));
        let v = m.arrive(Instant::from_micros(t), port, key);
        prop_assert!(v != StickyVerdict::Unproven, "every port is trusted");
        seen.push(Seen {
            port,
            occurrence: i,
            stream: sender,
            stamp: t,
            delivered: matches!(v, StickyVerdict::Deliver | StickyVerdict::Switched),
        });
    }
    check(&seen, s.sent.len(), timeout, m.stats().switches)?;
    let delivered = seen.iter().filter(|s| s.delivered).count() as u64;
    prop_assert_eq!(m.stats().delivered, delivered);
    prop_assert_eq!(m.stats().dropped, seen.len() as u64 - delivered);
    Ok((seen, m))
}

/// The dual-bus layer with the sticky merge (default timeout) over a run of the lag
/// properties: each node's heartbeat and counters are its stream.
fn run_layer(r: &Run) -> Result<(), TestCaseError> {
    let cfg = DualBusConfig::default().with_merge(MergePolicy::sticky());
    let mut l = DualBus::new(cfg);
    let mut seen = vec![];
    for &(at, port, i, stamp) in &r.arrivals {
        let now = Instant::from_micros(at);
        while let Some(d) = l.poll_timeout().filter(|d| *d <= now) {
            l.handle_timeout(d);
        }
        let res = if r.stamped {
            l.handle_rx_at(now, port, &r.sent[i].2, Instant::from_micros(stamp))
        } else {
            l.handle_rx(now, port, &r.sent[i].2)
        };
        seen.push(Seen {
            port,
            occurrence: i,
            stream: r.sent[i].1,
            stamp,
            delivered: res.is_some(),
        });
        while l.poll_event().is_some() {}
        while l.poll_transmit().is_some() {}
    }
    let sticky = l.sticky().expect("configured").stats();
    let timeout = MergePolicy::STICKY_TIMEOUT.as_micros();
    check(&seen, r.sent.len(), timeout, sticky.switches)?;
    prop_assert_eq!(sticky.unproven, 0);
    // The exact merge is idle.
    prop_assert_eq!(l.merger().stats().delivered, 0);
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(1000))]

    /// Both buses complete, skew either way below the window. With a timeout of the window, a
    /// stream whose frames pause for about that long may switch, and lose at the switch what
    /// followed the pause closer than the skew (see `a_pause_of_about_the_timeout_...`); with
    /// a timeout longer than every pause plus the skew (frames at most 3 ms apart here): the
    /// exact stream, no switch.
    #[test]
    fn sticky_both_buses_complete((s, _) in schedule(Lossy::Complete)) {
        run_core(&s, W)?;
        let (seen, m) = run_core(&s, 2 * W)?;
        prop_assert_eq!(seen.iter().filter(|s| s.delivered).count(), s.sent.len());
        prop_assert_eq!(m.stats().switches, 0);
    }

    /// One bus drops 30 % of the frames, skew either way.
    #[test]
    fn sticky_one_bus_drops((s, _) in schedule(Lossy::Drops(30))) {
        run_core(&s, W)?;
    }

    /// The lossy bus drops half the frames and lags the complete one.
    #[test]
    fn sticky_lagging_bus_drops((s, _) in schedule(Lossy::DropsLagging(50))) {
        run_core(&s, W)?;
    }

    /// One bus dead from the start: nothing lost (its streams are never bound to it).
    #[test]
    fn sticky_one_bus_dead((s, _) in schedule(Lossy::Dead)) {
        run_core(&s, W)?;
    }

    /// Complete buses cut and repaired at random, either or both.
    #[test]
    fn sticky_buses_cut_and_repaired((s, _) in schedule(Lossy::Complete), cuts in cuts()) {
        run_core(&cut(s, &cuts), W)?;
    }

    /// A longer timeout over the same cuts: the losses grow with it, the properties hold.
    #[test]
    fn sticky_buses_cut_with_a_longer_timeout((s, _) in schedule(Lossy::Complete), cuts in cuts()) {
        run_core(&cut(s, &cuts), 4 * W)?;
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(150))]

    /// The layer: bus 2's reader runs behind by random steps up to 70 ms (stamped frames).
    #[test]
    fn sticky_layer_a_late_reader_on_one_bus(r in lag_run(true, true)) {
        run_layer(&r)?;
    }

    /// The layer: either bus's reader runs behind by random steps up to 70 ms (stamped).
    #[test]
    fn sticky_layer_late_readers_on_either_bus(r in lag_run(false, true)) {
        run_layer(&r)?;
    }

    /// The layer without receive timestamps: either bus lags by random steps up to 35 ms,
    /// below the timeout.
    #[test]
    fn sticky_layer_either_bus_lagging_without_timestamps(r in lag_run(false, false)) {
        run_layer(&r)?;
    }
}

/// (send time, identifier index, delay on each bus).
type IdSent = (u64, u16, [u64; 2]);

/// Frames of many identifiers without a known sender, more than the identifier table holds,
/// on buses cut and repaired at random.
fn id_traffic() -> impl Strategy<Value = (Vec<IdSent>, Vec<Cut>)> {
    (
        prop::collection::vec((1u64..200, 0u16..150, 0..W, 0..W), 1..600),
        cuts(),
    )
        .prop_map(|(items, cuts)| {
            let mut t = 0;
            let sent = items
                .into_iter()
                .map(|(gap, id, d0, d1)| {
                    t += gap;
                    (t, id, [d0, d1])
                })
                .collect();
            (sent, cuts)
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(500))]

    /// Identifier streams beyond the table share one stream or take a done one's entry: never
    /// a duplicate, each identifier in the order sent.
    #[test]
    fn sticky_identifier_overflow_never_duplicates((sent, cuts) in id_traffic()) {
        // Each bus keeps each identifier's order.
        let mut events = vec![];
        for bus in 0..2 {
            let mut last = vec![0u64; 150];
            for (i, (t, id, d)) in sent.iter().enumerate() {
                let at = (t + d[bus]).max(last[*id as usize] + 1);
                last[*id as usize] = at;
                if !cuts.iter().any(|(b, from, len)| *b == bus && at >= *from && at < from + len) {
                    events.push((at, bus, i));
                }
            }
        }
        events.sort();
        let mut m = StickyMerger::new(Duration::from_micros(W));
        let mut times = vec![0u32; sent.len()];
        let mut last = vec![None::<usize>; 150];
        for (at, bus, i) in events {
            let id = sent[i].1;
            let frame = Frame::from_array(Id::Standard(0x200 + id), [i as u8]);
            let key = StreamKey::of(&frame, None);
            if m.arrive(Instant::from_micros(at), bus, key) != StickyVerdict::Dropped {
                times[i] += 1;
                prop_assert!(times[i] == 1, "{} delivered twice", i);
                prop_assert!(last[id as usize].is_none_or(|l| l < i), "identifier {}: {} after {:?}", id, i, last[id as usize]);
                last[id as usize] = Some(i);
            }
        }
        prop_assert!(m.id_streams() <= duocan_redundancy::link::sticky::ID_STREAMS);
    }
}

/// Bus 1 is bound; the sender pauses for 45 ms, then sends two frames 0.4 ms apart; bus 2 has
/// them 0.5 ms earlier than bus 1. Bus 2's first copy is stamped within the timeout (40 ms) of
/// the last frame on bus 1 (dropped: bus 1 is expected to bring it), its second one beyond
/// (the switch); bus 1's copy of the first comes after the switch (dropped: bus 2 is bound).
/// Both buses carried the frame; it is lost, within the timeout after the stream's last frame
/// on bus 1. A duplicate is what the policy never risks instead.
#[test]
fn a_pause_of_about_the_timeout_can_lose_frames_at_the_switch() {
    let mut m = StickyMerger::new(Duration::from_millis(40));
    let key = StreamKey::Node(NodeId::must(4));
    let us = Instant::from_micros;
    assert_eq!(m.arrive(us(1_000), 0, key), StickyVerdict::Deliver);
    assert_eq!(m.arrive(us(1_500), 1, key), StickyVerdict::Dropped);
    // After the pause: frame j stamped 40.8 ms on bus 2, j + 1 41.2 ms.
    assert_eq!(m.arrive(us(40_800), 1, key), StickyVerdict::Dropped);
    assert_eq!(m.arrive(us(41_200), 1, key), StickyVerdict::Switched);
    assert_eq!(m.arrive(us(41_300), 0, key), StickyVerdict::Dropped);
    assert_eq!(m.arrive(us(41_700), 0, key), StickyVerdict::Dropped);
    assert_eq!(m.stats().delivered, 2, "frame j is lost");
}
