//! Property tests of the receive merger over random traffic schedules.
//!
//! A schedule: several senders, each sending a random sequence of frames drawn from a few keys
//! (so the same frame is often sent several times in a row, faster than the window), with random
//! gaps. Each bus delivers every frame after a random delay below the skew window, keeping each
//! sender's order (a bus is FIFO per sender); one bus may drop frames at random. Arrivals of both
//! buses are fed to the merger in time order, ties in random order.

use duocan::{Duration, Frame, Id, Instant};
use duocan_redundancy::link::merge::{Merger, Verdict};
use proptest::prelude::*;
use std::collections::HashMap;

pub(crate) const W: u64 = 10_000; // µs
const MAX_DELAY: u64 = W - 1;

// The schedules are shared with the sticky merge's properties (`sticky_properties.rs`) and the
// mixed classic and CAN FD streams (`merge_fd_properties.rs`).

#[derive(Clone, Debug)]
pub(crate) struct Sent {
    pub(crate) sender: usize,
    pub(crate) frame: Frame,
    pub(crate) at: u64,
}

#[derive(Clone, Debug)]
pub(crate) struct Schedule {
    pub(crate) sent: Vec<Sent>,
    /// Arrival time of each sent frame on bus 0 and bus 1 (`None`: dropped).
    pub(crate) arrivals: Vec<[Option<u64>; 2]>,
    /// Random tie-breakers per arrival.
    pub(crate) ties: Vec<[u32; 2]>,
}

/// How the second (lossy) bus behaves relative to the complete one.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Lossy {
    /// Delivers everything too.
    Complete,
    /// Drops with the given probability (percent), random skew either way.
    Drops(u8),
    /// Drops, and never arrives before the complete bus.
    DropsLagging(u8),
    /// Delivers nothing.
    Dead,
}

fn frame(sender: usize, kind: u8) -> Frame {
    // Three identifiers per sender, two payloads: many exact repeats.
    let id = 0x180 + sender as u16 * 4 + (kind % 3) as u16;
    Frame::from_array(Id::Standard(id), [kind / 3])
}

prop_compose! {
    fn sender_traffic(sender: usize)
        (items in prop::collection::vec((1u64..3_000, 0u8..6, 0..=MAX_DELAY, 0..=MAX_DELAY, 0u8..100, any::<[u32; 2]>()), 1..40),
         start in 0u64..5_000)
        -> Vec<(Sent, u64, u64, u8, [u32; 2])>
    {
        let mut t = start;
        items.into_iter().map(|(gap, kind, d0, d1, p, ties)| {
            t += gap;
            (Sent { sender, frame: frame(sender, kind), at: t }, d0, d1, p, ties)
        }).collect()
    }
}

pub(crate) fn schedule(lossy: Lossy) -> impl Strategy<Value = (Schedule, bool)> {
    (1usize..=5)
        .prop_flat_map(|n| (0..n).map(sender_traffic).collect::<Vec<_>>())
        .prop_flat_map(move |per_sender| (Just(per_sender), any::<bool>()))
        .prop_map(move |(per_sender, complete_is_bus0)| {
            let (c, l) = if complete_is_bus0 { (0, 1) } else { (1, 0) };
            let mut sched = Schedule {
                sent: vec![],
                arrivals: vec![],
                ties: vec![],
            };
            for frames in per_sender {
                // A bus keeps each sender's order: an arrival is never before the previous one.
                let mut last = [0u64; 2];
                for (s, d0, d1, p, ties) in frames {
                    let mut arr = [None, None];
                    let dc = d0;
                    let dl = match lossy {
                        Lossy::DropsLagging(_) => d0.max(d1),
                        _ => d1,
                    };
                    let tc = (s.at + dc).max(last[c] + 1);
                    last[c] = tc;
                    arr[c] = Some(tc);
                    let dropped = match lossy {
                        Lossy::Complete => false,
                        Lossy::Drops(pct) | Lossy::DropsLagging(pct) => p < pct,
                        Lossy::Dead => true,
                    };
                    let tl = (s.at + dl).max(last[l] + 1);
                    let tl = match lossy {
                        Lossy::DropsLagging(_) => tl.max(tc),
                        _ => tl,
                    };
                    if !dropped {
                        last[l] = tl;
                        arr[l] = Some(tl);
                    }
                    sched.sent.push(s);
                    sched.arrivals.push(arr);
                    sched.ties.push(ties);
                }
            }
            (sched, complete_is_bus0)
        })
}

/// Runs the merger; returns the delivered frames as indices into `sent` of the arrival that was
/// delivered, in delivery order.
fn run(s: &Schedule) -> (Vec<(u64, usize)>, Merger<1024>) {
    let mut events: Vec<(u64, u32, usize, usize)> = vec![];
    for (i, arr) in s.arrivals.iter().enumerate() {
        for (bus, t) in arr.iter().enumerate() {
            if let Some(t) = t {
                events.push((*t, s.ties[i][bus], bus, i));
            }
        }
    }
    events.sort();
    let mut m: Merger<1024> = Merger::new(Duration::from_micros(W));
    let mut delivered = vec![];
    for (t, _, bus, i) in events {
        if m.arrive(Instant::from_micros(t), bus, &s.sent[i].frame) == Verdict::Deliver {
            delivered.push((t, i));
        }
    }
    (delivered, m)
}

fn counts<'a>(frames: impl Iterator<Item = &'a Frame>) -> HashMap<Frame, usize> {
    let mut h = HashMap::new();
    for f in frames {
        *h.entry(*f).or_default() += 1;
    }
    h
}

/// Each sender's frames in the order the application got them, and as sent.
pub(crate) fn per_sender(
    s: &Schedule,
    delivered: &[(u64, usize)],
) -> (Vec<Vec<Frame>>, Vec<Vec<Frame>>) {
    let n = s.sent.iter().map(|x| x.sender + 1).max().unwrap_or(0);
    let mut got = vec![vec![]; n];
    let mut want = vec![vec![]; n];
    for (_, i) in delivered {
        // Frames identify their sender (identifiers are per sender).
        got[s.sent[*i].sender].push(s.sent[*i].frame);
    }
    for x in &s.sent {
        want[x.sender].push(x.frame);
    }
    (got, want)
}

/// True if no frame dropped on the lossy bus is overtaken or repeated there too soon: every
/// later frame of the same sender arrives on the lossy bus strictly after the dropped one
/// arrives on the complete bus, and a later copy of the same frame only once the dropped one's
/// record has expired there. Otherwise no merger that delivers without waiting can tell what it
/// sees (a frame after a gap, or a twin) and the sender's order cannot be guaranteed; the count
/// still is.
pub(crate) fn order_is_observable(s: &Schedule, lossy: usize) -> bool {
    let c = 1 - lossy;
    for (i, x) in s.sent.iter().enumerate() {
        if s.arrivals[i][lossy].is_some() {
            continue;
        }
        let cx = s.arrivals[i][c].unwrap_or(u64::MAX);
        for (j, y) in s.sent.iter().enumerate().skip(i + 1) {
            if y.sender != x.sender {
                continue;
            }
            let Some(ly) = s.arrivals[j][lossy] else {
                continue;
            };
            if ly <= cx || (y.frame == x.frame && ly < cx + W) {
                return false;
            }
        }
    }
    true
}

pub(crate) fn check_exactly_once(
    s: &Schedule,
    delivered: &[(u64, usize)],
    m: &Merger<1024>,
) -> Result<(), TestCaseError> {
    let got = counts(delivered.iter().map(|(_, i)| &s.sent[*i].frame));
    let want = counts(s.sent.iter().map(|x| &x.frame));
    prop_assert_eq!(delivered.len(), s.sent.len(), "no loss, no duplicate");
    prop_assert_eq!(got, want);
    prop_assert_eq!(m.stats().evicted, 0);
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    /// Both buses deliver everything, random skew either way below the window: the delivered
    /// stream is the sent stream, sender by sender.
    #[test]
    fn both_buses_complete_exact_stream((s, _) in schedule(Lossy::Complete)) {
        let (delivered, m) = run(&s);
        check_exactly_once(&s, &delivered, &m)?;
        let (got, want) = per_sender(&s, &delivered);
        prop_assert_eq!(got, want);
    }

    /// One bus drops frames at random, random skew either way: every occurrence exactly once;
    /// each sender's order kept whenever no later frame overtakes or repeats a dropped one too
    /// soon on the lossy bus (what an eager merger cannot see; see `order_is_observable` and
    /// `order_is_lost_only_by_overtaking_a_drop`).
    #[test]
    fn one_bus_drops_exactly_once((s, c0) in schedule(Lossy::Drops(30))) {
        let (delivered, m) = run(&s);
        check_exactly_once(&s, &delivered, &m)?;
        let lossy = if c0 { 1 } else { 0 };
        if order_is_observable(&s, lossy) {
            let (got, want) = per_sender(&s, &delivered);
            prop_assert_eq!(got, want);
        }
    }

    /// The lossy bus drops at random and lags the complete one: exact stream (a late copy can
    /// only ever be a twin, whatever it is matched with).
    #[test]
    fn lagging_bus_drops_exact_stream((s, _) in schedule(Lossy::DropsLagging(50))) {
        let (delivered, m) = run(&s);
        check_exactly_once(&s, &delivered, &m)?;
        let (got, want) = per_sender(&s, &delivered);
        prop_assert_eq!(got, want);
    }

    /// One bus dead: exact stream, and every record is forgotten at the horizon (eight
    /// windows: nothing tells the merger that bus is dead).
    #[test]
    fn one_bus_dead_exact_stream((s, _) in schedule(Lossy::Dead)) {
        let (delivered, mut m) = run(&s);
        check_exactly_once(&s, &delivered, &m)?;
        let (got, want) = per_sender(&s, &delivered);
        prop_assert_eq!(got, want);
        let end = s.arrivals.iter().flatten().flatten().max().copied().unwrap_or(0);
        m.expire(Instant::from_micros(end + 8 * W));
        prop_assert_eq!((m.len(), m.keys()), (0, 0));
        prop_assert_eq!(m.stats().forgotten, s.sent.len() as u64);
    }
}

/// Why the order guarantee needs the condition above: sender sends k, then j. Bus 1 drops k and
/// is ahead; bus 2 is 4 ms late. At 2 ms, j is on bus 1 and nothing says k is missing: any merger
/// that does not hold frames back must deliver j before k.
#[test]
fn order_is_lost_only_by_overtaking_a_drop() {
    let k = frame(0, 0);
    let j = frame(0, 1);
    let s = Schedule {
        sent: vec![
            Sent {
                sender: 0,
                frame: k,
                at: 0,
            },
            Sent {
                sender: 0,
                frame: j,
                at: 2_000,
            },
        ],
        arrivals: vec![[None, Some(4_000)], [Some(2_000), Some(6_000)]],
        ties: vec![[0, 0], [0, 0]],
    };
    assert!(!order_is_observable(&s, 0));
    let (delivered, _) = run(&s);
    let frames: Vec<Frame> = delivered.iter().map(|(_, i)| s.sent[*i].frame).collect();
    assert_eq!(
        frames,
        [j, k],
        "no loss, no duplicate; order as the buses showed it"
    );
}
