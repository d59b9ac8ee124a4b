//! Property tests of the dual-bus layer with a port whose frames come late: random steps up
//! and down on one port and then the other, under random traffic.
//!
//! Traffic: three senders, each sending frames that carry a counter (never the same frame twice)
//! at random gaps of 0.3–3 ms, and a heartbeat that repeats unchanged every 250 ms. Both buses
//! carry every frame; each port adds up to 0.3 ms of skew and hands frames over in order (a
//! lower lag lets newer frames wait for the ones on their way). The layer is driven sans-IO,
//! timers exactly when due.
//!
//! Two kinds of port:
//!
//! - **With receive timestamps** (SocketCAN's kernel stamps, the simulator's wire time), the
//!   lag is a reader that runs behind: up to 70 ms (the horizon, 80 ms, less the window). Every
//!   frame exactly once, in the order sent per sender; no lag is reported.
//! - **Without** (a driver that stamps a frame when it hands it over), the lag shows between
//!   twins and is measured from the counters (fresh frames) and corrected, up to 35 ms either
//!   way. Nothing is lost; a frame comes twice only while a step of a port's lag is not
//!   measured yet (`crate::link::lag`): at most eight per step of half the window or more
//!   (a queue that drains at once when its lag drops hands its frames over with times that
//!   say nothing, which costs a few more before two samples agree).

use duocan::machine::BusLink;
use duocan::{Frame, Id, Instant};
use duocan_redundancy::{DualBus, DualBusConfig, PortState};
use proptest::prelude::*;
use std::collections::HashMap;

const MS: u64 = 1_000;
const SENDERS: usize = 3;
const HEARTBEAT: u64 = 250 * MS;
/// The default configuration's skew window.
const WINDOW: u64 = 5 * MS;

/// A stretch of time during which `port` lags by `lag` µs and the other port not at all.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Segment {
    len: u64,
    port: usize,
    lag: u64,
}

// The runs are shared with the sticky merge's properties (`sticky_properties.rs`).
#[derive(Clone, Debug)]
pub(crate) struct Run {
    /// (send time, sender, frame), in send order.
    pub(crate) sent: Vec<(u64, usize, Frame)>,
    /// (hand-over time, port, index into `sent`, receive timestamp), in hand-over order.
    pub(crate) arrivals: Vec<(u64, usize, usize, u64)>,
    pub(crate) segments: Vec<Segment>,
    /// The ports stamp frames on arrival (the lag is a late reader), or on hand-over.
    pub(crate) stamped: bool,
}

fn lag_at(segments: &[Segment], t: u64, port: usize) -> u64 {
    let mut start = 0;
    for s in segments {
        if t < start + s.len {
            return if s.port == port { s.lag } else { 0 };
        }
        start += s.len;
    }
    0
}

/// The steps of a port's lag, or of how much later one port's copies come than the other's, by
/// half the window or more (at the start, between segments, and back to none after the last
/// one): at most eight frames come twice for each (see the module documentation).
fn bound(r: &Run) -> usize {
    let (mut before, mut steps) = ([0u64; 2], 0);
    for lags in r
        .segments
        .iter()
        .map(|s| {
            let mut now = [0u64; 2];
            now[s.port] = s.lag;
            now
        })
        .chain([[0, 0]])
    {
        // What is measured is how much later one port's copies come than the other's; the
        // correction ignores less than half a window, so a step of half a window may leave a
        // whole window uncorrected.
        let ports = (0..2)
            .filter(|p| lags[*p].abs_diff(before[*p]) >= WINDOW / 2)
            .count();
        let relative = (lags[1] as i64 - lags[0] as i64) - (before[1] as i64 - before[0] as i64);
        steps += ports.max(usize::from(relative.unsigned_abs() >= WINDOW / 2));
        before = lags;
    }
    8 * steps
}

fn segments(one_port: bool, most: u64) -> impl Strategy<Value = Vec<Segment>> {
    let port = if one_port {
        Just(1).boxed()
    } else {
        (0..2usize).boxed()
    };
    prop::collection::vec(
        (100u64..1_500, port, prop_oneof![Just(0u64), 0u64..=most]).prop_map(|(len, port, lag)| {
            Segment {
                len: len * MS,
                port,
                lag: lag * MS,
            }
        }),
        1..6,
    )
}

pub(crate) fn run(one_port: bool, stamped: bool) -> impl Strategy<Value = Run> {
    let most = if stamped { 70 } else { 35 };
    (
        segments(one_port, most),
        prop::collection::vec((300u64..3_000, 0..SENDERS, 0u64..300, 0u64..300), 1..2_000),
    )
        .prop_map(move |(segments, traffic)| build(segments, traffic, stamped))
}

fn build(segments: Vec<Segment>, traffic: Vec<(u64, usize, u64, u64)>, stamped: bool) -> Run {
    {
        let mut sent = vec![];
        let mut counter = [0u32; SENDERS];
        let mut t = 0;
        let mut next_heartbeat = [0u64; SENDERS];
        let mut skews = vec![];
        for (gap, sender, s0, s1) in traffic {
            t += gap;
            for (h, next) in next_heartbeat.iter_mut().enumerate() {
                if *next <= t {
                    let hb = Frame::from_array(Id::Standard(0x701 + h as u16), [5]);
                    sent.push((*next, h, hb));
                    skews.push([s0 / 2, s1 / 2]);
                    *next += HEARTBEAT;
                }
            }
            let id = Id::Standard(0x181 + sender as u16);
            sent.push((
                t,
                sender,
                Frame::from_array(id, counter[sender].to_le_bytes()),
            ));
            counter[sender] += 1;
            skews.push([s0, s1]);
        }
        // Sorted by send time (heartbeats were slotted in when due); each port in order.
        let mut order: Vec<usize> = (0..sent.len()).collect();
        order.sort_by_key(|i| sent[*i].0);
        let sent: Vec<_> = order.iter().map(|i| sent[*i]).collect();
        let skews: Vec<_> = order.iter().map(|i| skews[*i]).collect();
        let mut arrivals = vec![];
        for port in [0usize, 1] {
            let mut last = 0;
            for (i, (s, _, _)) in sent.iter().enumerate() {
                let wire = s + skews[i][port];
                let at = (wire + lag_at(&segments, *s, port)).max(last + 1);
                last = at;
                arrivals.push((at, port, i, if stamped { wire } else { at }));
            }
        }
        arrivals.sort();
        Run {
            sent,
            arrivals,
            segments,
            stamped,
        }
    }
}

/// Feeds the arrivals to a layer; the delivered frames as indices into `sent`, in order.
fn deliver(r: &Run) -> (Vec<usize>, DualBus) {
    let mut l = DualBus::new(DualBusConfig::default());
    let mut delivered = vec![];
    // Frames are unique but for the heartbeats: each delivered frame stands for the oldest
    // occurrence of it not delivered yet.
    let mut pending: HashMap<Frame, Vec<usize>> = HashMap::new();
    for (i, (_, _, f)) in r.sent.iter().enumerate() {
        pending.entry(*f).or_default().push(i);
    }
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
        if let Some(f) = res {
            // The oldest copy of this frame sent by now and not delivered yet; if there is none,
            // this arrival comes a second time.
            let copies = pending.get_mut(&f).unwrap();
            let oldest = copies.first().filter(|c| r.sent[**c].0 <= at).copied();
            delivered.push(match oldest {
                Some(c) => {
                    copies.remove(0);
                    c
                }
                None => i,
            });
        }
        while l.poll_event().is_some() {}
        while l.poll_transmit().is_some() {}
    }
    (delivered, l)
}

fn check(r: &Run) -> Result<(), TestCaseError> {
    let (delivered, l) = deliver(r);
    let mut times = vec![0usize; r.sent.len()];
    for i in &delivered {
        times[*i] += 1;
    }
    let lost: Vec<_> = (0..r.sent.len()).filter(|i| times[*i] == 0).collect();
    prop_assert!(lost.is_empty(), "lost {:?}", lost);
    let twice = delivered.len() - r.sent.len();
    let bound = if r.stamped { 0 } else { bound(r) };
    prop_assert!(twice <= bound, "{twice} duplicates, bound {bound}");
    prop_assert_eq!(l.merger().stats().evicted, 0);
    prop_assert!(l.port_state(0) != PortState::Failed && l.port_state(1) != PortState::Failed);
    if r.stamped {
        // Exactly once, and each sender's frames in the order sent; nothing to report.
        let mut last = [None; SENDERS];
        for i in delivered {
            let sender = r.sent[i].1;
            prop_assert!(last[sender].is_none_or(|j| j < i), "sender {sender}: {i}");
            last[sender] = Some(i);
        }
        prop_assert_eq!(l.lag().lag(0) + l.lag().lag(1), duocan::Duration::ZERO);
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    /// Bus 2's reader runs behind by random steps, up and down, up to 70 ms; stamped frames.
    #[test]
    fn a_late_reader_on_one_bus_costs_nothing(r in run(true, true)) {
        check(&r)?;
    }

    /// One bus's reader runs behind, then the other's, by random steps up to 70 ms; stamped.
    #[test]
    fn late_readers_on_either_bus_cost_nothing(r in run(false, true)) {
        check(&r)?;
    }

    /// Without timestamps: bus 2 lags by random steps up to 35 ms.
    #[test]
    fn one_bus_lagging_without_timestamps_loses_nothing_and_doubles_only_until_measured(
        r in run(true, false)
    ) {
        check(&r)?;
    }

    /// Without timestamps: one bus lags, then the other, by random steps up to 35 ms.
    #[test]
    fn either_bus_lagging_without_timestamps_loses_nothing_and_doubles_only_until_measured(
        r in run(false, false)
    ) {
        check(&r)?;
    }
}
