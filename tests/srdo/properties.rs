//! The consumer under random fault schedules: a producer sends a pair every refresh time, each
//! pair clean or hit by one fault (normal dropped, inverse dropped, one bit flipped in either,
//! the two swapped, the inverse delayed past SRVT, the producer stopping). An oracle that
//! reads the schedule pair by pair, as CiA 304 states the rules, says when and why the consumer
//! must enter its safe state and which values it must deliver before; the consumer must agree
//! exactly, and never deliver a value that was not sent intact.

use duocan::cia304::srdo::consumer::{ConsumerStep, SrdoCause, SrdoConsumer};
use duocan::{Duration, Frame, Id, Instant};
use proptest::prelude::*;

const NORMAL: u16 = 0x101;
const INVERTED: u16 = 0x102;

#[derive(Clone, Copy, Debug)]
enum Fault {
    Clean,
    DropNormal,
    DropInverted,
    /// One bit (index modulo the data's bits) flipped in the normal (false) or inverted frame.
    Corrupt(bool, u8),
    Swap,
    /// The inverse arrives SRVT + this many µs after the normal frame.
    Delay(u32),
    Stop,
}

fn fault() -> impl Strategy<Value = Fault> {
    prop_oneof![
        6 => Just(Fault::Clean),
        1 => Just(Fault::DropNormal),
        1 => Just(Fault::DropInverted),
        1 => (any::<bool>(), any::<u8>()).prop_map(|(i, b)| Fault::Corrupt(i, b)),
        1 => Just(Fault::Swap),
        1 => (0u32..5_000).prop_map(Fault::Delay),
        1 => Just(Fault::Stop),
    ]
}

#[derive(Clone, Debug)]
struct Schedule {
    sct: u64,
    srvt: u64,
    refresh: u64,
    len: usize,
    /// Per pair: the gap normal → inverse (< SRVT), the data (byte 0 is the pair's number, see
    /// `pair_number`), the fault.
    pairs: Vec<(u64, [u8; 8], Fault)>,
}

fn schedule() -> impl Strategy<Value = Schedule> {
    (2_000u64..=10_000, 31_000u64..=80_000, 1usize..=8).prop_flat_map(|(srvt, sct, len)| {
        let pair = (0..srvt, any::<[u8; 8]>(), fault());
        (
            srvt + 1_000..=30_000,
            proptest::collection::vec(pair, 1..40),
        )
            .prop_map(move |(refresh, mut pairs)| {
                for (k, p) in pairs.iter_mut().enumerate() {
                    p.1[0] = pair_number(k);
                }
                Schedule {
                    sct,
                    srvt,
                    refresh,
                    len,
                    pairs,
                }
            })
    })
}

/// The number pair `k` carries in its first byte: the `k`-th byte of even parity, so that one
/// flipped bit never turns a pair's data into another pair's. (Nothing can tell that case apart:
/// a corrupted half that happens to be the exact inverse of another pair's held half, within
/// SRVT, is a valid pair. One bit flipped in the first byte of pair 1 = 1 gave 0, the inverse of
/// pair 0's inverted half, whose normal half had been dropped; CAN's CRC is what stands
/// against single flipped bits on the wire.)
fn pair_number(k: usize) -> u8 {
    (0u8..=255)
        .filter(|b| b.count_ones() % 2 == 0)
        .nth(k)
        .expect("40 pairs at most, 128 such bytes")
}

fn at(us: u64) -> Instant {
    Instant::from_micros(us)
}

/// What CiA 304 says of the schedule: the values delivered, then the trip (time, cause).
fn oracle(s: &Schedule) -> (Vec<Vec<u8>>, (u64, SrdoCause)) {
    let mut delivered = vec![];
    let mut last_ok = 0u64;
    for (k, &(gap, data, fault)) in s.pairs.iter().enumerate() {
        let t = k as u64 * s.refresh;
        let sct = last_ok + s.sct;
        // The next pair's first frame, if it sends one (true: a normal frame); only that pair
        // can come before a deadline, as the refresh time exceeds SRVT.
        let next = s.pairs.get(k + 1).and_then(|&(g, _, f)| {
            let t = t + s.refresh;
            match f {
                Fault::Stop => None,
                Fault::DropNormal => Some((t + g, false)),
                Fault::Swap => Some((t, false)),
                _ => Some((t, true)),
            }
        });
        // When one half (`normal` or not) is held from `n`: the first deadline to pass, or the
        // next pair's first frame before it: the same half with other data, or the other half
        // not its inverse (each pair's data differs in its first byte).
        let held = |n: u64, normal: bool| {
            let first = if n >= sct {
                return (sct, SrdoCause::CycleTime);
            } else if n + s.srvt <= sct {
                (n + s.srvt, SrdoCause::Validation)
            } else {
                (sct, SrdoCause::CycleTime)
            };
            match next {
                Some((m, half)) if m < first.0 && half == normal => (m, SrdoCause::Sequence),
                Some((m, _)) if m < first.0 => (m, SrdoCause::NotInverted),
                _ => first,
            }
        };
        match fault {
            // Either order: the pair completes with its second half.
            Fault::Clean | Fault::Swap if t + gap < sct => {
                delivered.push(data[..s.len].to_vec());
                last_ok = t + gap;
            }
            Fault::Clean | Fault::Swap | Fault::Stop => {
                return (delivered, (sct, SrdoCause::CycleTime))
            }
            Fault::DropNormal => return (delivered, held(t + gap, false)),
            Fault::DropInverted | Fault::Delay(_) => return (delivered, held(t, true)),
            Fault::Corrupt(..) if t + gap < sct => {
                return (delivered, (t + gap, SrdoCause::NotInverted))
            }
            Fault::Corrupt(..) => return (delivered, (sct, SrdoCause::CycleTime)),
        }
    }
    (delivered, (last_ok + s.sct, SrdoCause::CycleTime))
}

/// The frames on the wire, in time order.
fn wire(s: &Schedule) -> Vec<(u64, Frame)> {
    let mut out = vec![];
    let frame = |id, d: &[u8]| Frame::new(Id::Standard(id), d).unwrap();
    for (k, &(gap, data, fault)) in s.pairs.iter().enumerate() {
        let t = k as u64 * s.refresh;
        let n = &data[..s.len];
        let mut inv: Vec<u8> = n.iter().map(|b| !b).collect();
        let mut plain = n.to_vec();
        match fault {
            Fault::Clean => {
                out.push((t, frame(NORMAL, &plain)));
                out.push((t + gap, frame(INVERTED, &inv)));
            }
            Fault::DropNormal => out.push((t + gap, frame(INVERTED, &inv))),
            Fault::DropInverted => out.push((t, frame(NORMAL, &plain))),
            Fault::Corrupt(inverted, bit) => {
                let bit = bit as usize % (8 * s.len);
                let hit = if inverted { &mut inv } else { &mut plain };
                hit[bit / 8] ^= 1 << (bit % 8);
                out.push((t, frame(NORMAL, &plain)));
                out.push((t + gap, frame(INVERTED, &inv)));
            }
            Fault::Swap => {
                out.push((t, frame(INVERTED, &inv)));
                out.push((t + gap, frame(NORMAL, &plain)));
            }
            Fault::Delay(x) => {
                out.push((t, frame(NORMAL, &plain)));
                out.push((t + s.srvt + x as u64, frame(INVERTED, &inv)));
            }
            Fault::Stop => break,
        }
    }
    out.sort_by_key(|(t, _)| *t);
    out
}

/// Runs the consumer over the frames as a driver would (deadlines before later frames).
fn run(s: &Schedule) -> (Vec<Vec<u8>>, Option<(u64, SrdoCause)>, u64) {
    let (sct, srvt) = (Duration::from_micros(s.sct), Duration::from_micros(s.srvt));
    let mut c = SrdoConsumer::new(NORMAL, INVERTED, sct, srvt, s.len as u8);
    c.start(Instant::ZERO);
    let mut delivered = vec![];
    let mut trip = None;
    let mut last = 0;
    let mut step = |st: Option<ConsumerStep>, delivered: &mut Vec<Vec<u8>>, now: Instant| match st {
        Some(ConsumerStep::Deliver(d)) => {
            delivered.push(d[..s.len].to_vec());
            last = now.as_micros();
        }
        Some(ConsumerStep::Trip(f)) => {
            assert!(trip.is_none(), "one trip, then nothing");
            trip = Some((f.at.as_micros(), f.cause));
        }
        _ => {}
    };
    let frames = wire(s);
    let end = frames.last().map_or(0, |(t, _)| *t) + 2 * s.sct;
    for (t, f) in &frames {
        while let Some(d) = c.poll_timeout().filter(|d| *d <= at(*t)) {
            step(c.handle_timeout(d), &mut delivered, d);
        }
        step(c.handle_frame(at(*t), f), &mut delivered, at(*t));
    }
    while let Some(d) = c.poll_timeout().filter(|d| *d <= at(end)) {
        step(c.handle_timeout(d), &mut delivered, d);
    }
    (delivered, trip, last)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn the_consumer_is_safe_exactly_when_the_standard_says(s in schedule()) {
        let (want_values, want_trip) = oracle(&s);
        let (values, trip, last) = run(&s);
        prop_assert_eq!(trip, Some(want_trip));
        prop_assert_eq!(&values, &want_values);
        // Never a value that was not sent intact: each one is the data of a pair sent whole.
        for v in &values {
            let intact = s.pairs.iter().any(|(_, d, f)| matches!(f, Fault::Clean | Fault::Swap) && d[..s.len] == v[..]);
            prop_assert!(intact);
        }
        // Within the stated bound: never later than SCT after the last value delivered.
        prop_assert!(want_trip.0 <= last + s.sct);
    }
}
