//! Property tests of the receive merger over mixed classic and CAN FD traffic: the schedules
//! of `merge_properties.rs` (senders repeating frames faster than the window, random skew,
//! one bus dropping, lagging or dead), each frame made classic or FD so that a classic frame
//! and an FD frame share an identifier and bytes, FD frames differ only in their last byte or
//! only in their length, and each copy is carried with BRS and ESI at random (link-level flags
//! the merge does not key on). Every occurrence is delivered once, each sender's order kept
//! as for classic streams, and the memory bounded as there.

use super::merge_properties::{
    check_exactly_once, order_is_observable, per_sender, schedule, Lossy, Schedule, W,
};
use duocan::frame::FdFrame;
use duocan::{Duration, Frame, Id, Instant};
use duocan_redundancy::link::merge::{Merger, Verdict};
use proptest::prelude::*;

/// A frame on the wire: classic or FD.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Wire {
    Classic(Frame),
    Fd(FdFrame),
}

/// The mixed frame a schedule's frame stands for: one-to-one, so equal frames stay equal and
/// different ones different.
fn mixed(f: &Frame) -> Wire {
    let Id::Standard(id) = f.id() else {
        unreachable!("the schedules send standard identifiers")
    };
    let d = f.data()[0];
    let fd = |data: &[u8]| Wire::Fd(FdFrame::new(f.id(), data).unwrap());
    match (id - 0x180) % 4 {
        // A classic frame, and an FD frame with the same identifier and byte.
        0 if d == 0 => Wire::Classic(*f),
        0 => fd(&[0]),
        // 64 bytes, differing in the last one only.
        1 => {
            let mut data = [0x11; 64];
            data[63] += d;
            fd(&data)
        }
        // 12 bytes, or the same 12 and four zeros (16).
        _ => {
            let data: Vec<u8> = (1..=12).chain([0; 4]).collect();
            fd(&data[..if d == 0 { 12 } else { 16 }])
        }
    }
}

/// Runs the merger on the mixed frames, each copy with BRS and ESI from its tie-breaker;
/// returns the delivered arrivals as indices into `sent`, in delivery order.
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
    for (t, tie, bus, i) in events {
        let now = Instant::from_micros(t);
        let v = match mixed(&s.sent[i].frame) {
            Wire::Classic(f) => m.arrive(now, bus, &f),
            Wire::Fd(f) => m.arrive_fd(now, bus, &f.with_brs(tie & 1 != 0).with_esi(tie & 2 != 0)),
        };
        if v == Verdict::Deliver {
            delivered.push((t, i));
        }
        assert_within_capacity(&m);
    }
    (delivered, m)
}

fn assert_within_capacity(m: &Merger<1024>) {
    assert!(m.len() <= m.capacity() && m.keys() <= m.len());
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(1000))]

    /// Both buses carry everything: the delivered stream is the sent stream, sender by sender.
    #[test]
    fn both_buses_complete_mixed_exact_stream((s, _) in schedule(Lossy::Complete)) {
        let (delivered, m) = run(&s);
        check_exactly_once(&s, &delivered, &m)?;
        let (got, want) = per_sender(&s, &delivered);
        prop_assert_eq!(got, want);
    }

    /// One bus drops at random: every occurrence once, the order kept where it is observable.
    #[test]
    fn one_bus_drops_mixed_exactly_once((s, c0) in schedule(Lossy::Drops(30))) {
        let (delivered, m) = run(&s);
        check_exactly_once(&s, &delivered, &m)?;
        if order_is_observable(&s, if c0 { 1 } else { 0 }) {
            let (got, want) = per_sender(&s, &delivered);
            prop_assert_eq!(got, want);
        }
    }

    /// One bus drops and lags: the exact stream.
    #[test]
    fn lagging_bus_drops_mixed_exact_stream((s, _) in schedule(Lossy::DropsLagging(50))) {
        let (delivered, m) = run(&s);
        check_exactly_once(&s, &delivered, &m)?;
        let (got, want) = per_sender(&s, &delivered);
        prop_assert_eq!(got, want);
    }

    /// One bus dead: the exact stream, and every record, FD or classic, forgotten at the
    /// horizon (memory back to nothing).
    #[test]
    fn one_bus_dead_mixed_exact_stream((s, _) in schedule(Lossy::Dead)) {
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

/// The mapping is one-to-one on the schedules' frames, and makes the cases the properties are
/// about: a classic and an FD frame alike in identifier and bytes, FD frames alike but for
/// their last byte or their length.
#[test]
fn the_mixed_frames_are_distinct_and_collide_where_meant() {
    let mut seen = vec![];
    for sender in 0..5u16 {
        for kind in 0..6u8 {
            let id = 0x180 + sender * 4 + u16::from(kind % 3);
            let f = Frame::from_array(Id::Standard(id), [kind / 3]);
            let w = mixed(&f);
            assert!(!seen.contains(&w), "{w:?} twice");
            seen.push(w);
        }
    }
    let Wire::Classic(c) = mixed(&Frame::from_array(Id::Standard(0x180), [0])) else {
        panic!("classic expected")
    };
    let Wire::Fd(f) = mixed(&Frame::from_array(Id::Standard(0x180), [1])) else {
        panic!("FD expected")
    };
    assert_eq!((c.id(), c.data()), (f.id(), f.data()));
}
