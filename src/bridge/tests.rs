//! The bridge's rules with frames and time given by hand.

use super::*;
use crate::frame::Id;
use proptest::prelude::*;

fn f(id: u16, b: u8) -> Frame {
    Frame::from_array(Id::Standard(id), [b])
}
fn ms(n: u64) -> Duration {
    Duration::from_millis(n)
}
fn at(n: u64) -> Instant {
    Instant::from_millis(n)
}
/// Bus 1: members 0 (master), 1, 2; bus 2: members 3 (master), 4, 5.
fn dual() -> Bridge {
    Bridge::new(BridgeConfig::new(&[
        &["vm1a", "vs1a", "vs1b"],
        &["vm2a", "vs2a", "vs2b"],
    ]))
    .unwrap()
}
fn drain(b: &mut Bridge) -> Vec<(usize, Frame)> {
    core::iter::from_fn(|| b.poll_transmit()).collect()
}
fn sorted(mut v: Vec<(usize, Frame)>) -> Vec<(usize, Frame)> {
    v.sort_by_key(|(m, f)| (*m, f.data()[0]));
    v
}

#[test]
fn a_frame_reaches_every_other_member_of_its_bus_and_nothing_else() {
    let mut b = dual();
    b.handle_rx(at(0), 1, &f(0x181, 1));
    assert_eq!(sorted(drain(&mut b)), [(0, f(0x181, 1)), (2, f(0x181, 1))]);
    b.handle_rx(at(0), 3, &f(0x000, 2));
    assert_eq!(sorted(drain(&mut b)), [(4, f(0, 2)), (5, f(0, 2))]);
    assert_eq!(b.counters(1).unwrap().rx, 1);
    assert_eq!(b.counters(0).unwrap().tx, 1);
    assert_eq!(b.poll_timeout(), None);
}

#[test]
fn configs_that_cannot_be_bridged_are_errors() {
    assert!(matches!(
        Bridge::new(BridgeConfig::new(&[&["a"]])),
        Err(BridgeError::Members(_))
    ));
    assert_eq!(
        Bridge::new(BridgeConfig::new(&[&["a", "b"], &["b", "c"]])).err(),
        Some(BridgeError::Duplicate("b".into()))
    );
    assert_eq!(
        Bridge::new(BridgeConfig::new(&[&["a", "b"]]).with_queue(0)).err(),
        Some(BridgeError::Queue)
    );
    let many: Vec<String> = (0..=MAX_MEMBERS).map(|i| alloc::format!("m{i}")).collect();
    let many: Vec<&str> = many.iter().map(String::as_str).collect();
    assert!(Bridge::new(BridgeConfig::new(&[&many])).is_err());
}

#[test]
fn a_cut_bus_carries_nothing_and_the_other_bus_carries_on() {
    let mut b = dual();
    b.bus_down(0);
    b.handle_rx(at(0), 0, &f(0x701, 1));
    b.handle_rx(at(0), 3, &f(0x701, 1));
    assert_eq!(sorted(drain(&mut b)), [(4, f(0x701, 1)), (5, f(0x701, 1))]);
    assert_eq!(b.bus_counters(0).unwrap().cut, 1);
    b.bus_up(0);
    b.handle_rx(at(1), 0, &f(0x701, 2));
    assert_eq!(drain(&mut b).len(), 2);
}

#[test]
fn a_cut_port_neither_sends_nor_receives() {
    let mut b = dual();
    b.disconnect(2);
    b.handle_rx(at(0), 0, &f(0x80, 1));
    assert_eq!(drain(&mut b), [(1, f(0x80, 1))]);
    b.handle_rx(at(0), 2, &f(0x702, 5));
    assert_eq!(drain(&mut b), []);
    assert_eq!(
        b.counters(2).unwrap().cut,
        2,
        "one not received, one not sent"
    );
    b.reconnect(2);
    b.handle_rx(at(1), 0, &f(0x80, 2));
    assert_eq!(drain(&mut b).len(), 2);
}

#[test]
fn a_partition_splits_a_bus_into_groups_until_healed() {
    let mut b = dual();
    b.partition(0, &[&[0, 1]]);
    b.handle_rx(at(0), 0, &f(0x80, 1));
    assert_eq!(drain(&mut b), [(1, f(0x80, 1))]);
    b.handle_rx(at(0), 2, &f(0x702, 1));
    assert_eq!(drain(&mut b), []);
    assert_eq!(b.counters(2).unwrap().partitioned, 1);
    assert_eq!(b.counters(0).unwrap().partitioned, 1);
    // The other bus is not split.
    b.handle_rx(at(0), 3, &f(0x80, 1));
    assert_eq!(drain(&mut b).len(), 2);
    b.heal(0);
    b.handle_rx(at(1), 2, &f(0x702, 2));
    assert_eq!(drain(&mut b).len(), 2);
}

#[test]
fn every_nth_frame_is_dropped_exactly() {
    let mut b = dual();
    b.drop_every(1, 3);
    let mut got = Vec::new();
    for i in 0..9 {
        b.handle_rx(at(i), 0, &f(0x181, i as u8));
        got.extend(drain(&mut b).into_iter().filter(|(m, _)| *m == 1));
    }
    let data: Vec<u8> = got.iter().map(|(_, f)| f.data()[0]).collect();
    assert_eq!(data, [0, 1, 3, 4, 6, 7]);
    assert_eq!(b.counters(1).unwrap().dropped, 3);
    assert_eq!(b.counters(2).unwrap().dropped, 0, "member 2 is not faulted");
    // On the bus: lost for every receiver.
    b.drop_every_on_bus(1, 2);
    b.handle_rx(at(10), 3, &f(1, 1));
    b.handle_rx(at(10), 3, &f(1, 2));
    assert_eq!(
        drain(&mut b).len(),
        2,
        "the first to both, the second to nobody"
    );
    assert_eq!(b.bus_counters(1).unwrap().dropped, 1);
}

#[test]
fn latency_delays_exactly_and_keeps_the_order() {
    let mut b = dual();
    b.set_port_latency(1, ms(5));
    b.handle_rx(at(0), 0, &f(0x181, 1));
    assert_eq!(drain(&mut b), [(2, f(0x181, 1))]);
    assert_eq!(b.poll_timeout(), Some(at(5)));
    // Latency removed: the next frame still waits for the one ahead of it.
    b.set_port_latency(1, Duration::ZERO);
    b.handle_rx(at(1), 0, &f(0x181, 2));
    assert_eq!(drain(&mut b), [(2, f(0x181, 2))]);
    b.handle_timeout(at(4));
    assert_eq!(drain(&mut b), []);
    b.handle_timeout(at(5));
    assert_eq!(drain(&mut b), [(1, f(0x181, 1)), (1, f(0x181, 2))]);
    assert_eq!(b.poll_timeout(), None);
}

#[test]
fn corruption_is_dropped_when_detected_and_one_bit_when_not() {
    let mut b = dual();
    b.set_port_faults(1, FaultRates::NONE.with_corrupt_detected(1.0));
    b.handle_rx(at(0), 0, &f(0x181, 0));
    assert_eq!(drain(&mut b), [(2, f(0x181, 0))]);
    assert_eq!(b.counters(1).unwrap().corrupted, 1);
    b.set_port_faults(1, FaultRates::NONE.with_corrupt_undetected(1.0));
    b.handle_rx(at(0), 0, &f(0x181, 0));
    let got = drain(&mut b);
    let to1 = got.iter().find(|(m, _)| *m == 1).unwrap().1;
    assert_eq!(to1.data()[0].count_ones(), 1, "one bit flipped: {to1:?}");
    assert_eq!(b.counters(1).unwrap().flipped, 1);
}

#[test]
fn duplicates_arrive_twice_in_order() {
    let mut b = dual();
    b.set_port_faults(2, FaultRates::NONE.with_duplicate(1.0));
    b.handle_rx(at(0), 0, &f(0x181, 7));
    b.handle_rx(at(0), 0, &f(0x181, 8));
    let to2: Vec<u8> = drain(&mut b)
        .into_iter()
        .filter(|(m, _)| *m == 2)
        .map(|(_, f)| f.data()[0])
        .collect();
    assert_eq!(to2, [7, 7, 8, 8]);
}

#[test]
fn a_babbler_sends_at_its_rate_until_stopped() {
    let mut b = dual();
    b.babble(2, Some(f(0x7FF, 0xBB)), ms(1));
    let mut n = 0;
    for t in 0..=9 {
        b.handle_timeout(at(t));
        n += drain(&mut b).len();
    }
    assert_eq!(n, 20, "10 babbles to each of the 2 other members");
    assert_eq!(b.counters(2).unwrap().babbled, 10);
    b.babble(2, None, ms(1));
    b.handle_timeout(at(20));
    assert_eq!(drain(&mut b), []);
    assert_eq!(b.poll_timeout(), None);
}

#[test]
fn a_full_queue_drops_and_counts_the_overflow() {
    let mut b = Bridge::new(BridgeConfig::new(&[&["a", "b"]]).with_queue(2)).unwrap();
    b.set_port_latency(1, ms(1));
    for i in 0..5 {
        b.handle_rx(at(0), 0, &f(1, i));
    }
    b.handle_timeout(at(1));
    assert_eq!(drain(&mut b).len(), 2);
    assert_eq!(b.counters(1).unwrap().overflow, 3);
}

proptest! {
    /// Whatever the faults, every frame each receiver was due is accounted for exactly once:
    /// delivered (duplicates counted apart), or in one drop counter; and frames to a member
    /// leave in the order they came (never before their time).
    #[test]
    fn every_frame_is_accounted_for_and_order_is_kept(
        seed in any::<u64>(),
        drop in 0.0f64..0.5, dup in 0.0f64..0.5, delay in 0.0f64..1.0,
        det in 0.0f64..0.3, bus_drop in 0.0f64..0.3,
        every in 0u32..5, lat in 0u64..3000,
        cut in proptest::option::of(0usize..3),
        frames in proptest::collection::vec((0usize..3, 0u64..2000), 1..200),
    ) {
        let mut b = Bridge::new(
            BridgeConfig::new(&[&["a", "b", "c"]]).with_seed(seed).with_queue(64),
        ).unwrap();
        let rates = FaultRates::NONE
            .with_drop(drop)
            .with_duplicate(dup)
            .with_delay(delay, Duration::from_micros(5000))
            .with_corrupt_detected(det);
        b.set_port_faults(1, rates);
        b.set_bus_faults(0, FaultRates::NONE.with_drop(bus_drop));
        b.drop_every(2, every);
        b.set_port_latency(0, Duration::from_micros(lat));
        if let Some(m) = cut { b.disconnect(m); }
        let mut t = Instant::ZERO;
        let mut sent = 0u64;
        let mut seq = 0u32;
        let mut last_seq = [None::<u32>; 3];
        let mut check = |b: &mut Bridge| -> Result<(), TestCaseError> {
            while let Some((m, fr)) = b.poll_transmit() {
                let s = u32::from_le_bytes(fr.data()[..4].try_into().unwrap());
                // Duplicates repeat the same sequence number; nothing goes backwards.
                prop_assert!(last_seq[m].is_none_or(|l| s >= l), "member {m}: {s} after {last_seq:?}");
                last_seq[m] = Some(s);
            }
            Ok(())
        };
        for (src, dt) in frames {
            t += Duration::from_micros(dt);
            if b.poll_timeout().is_some_and(|d| d <= t) {
                b.handle_timeout(t);
            }
            check(&mut b)?;
            let mut data = [0u8; 8];
            data[..4].copy_from_slice(&seq.to_le_bytes());
            seq += 1;
            b.handle_rx(t, src, &Frame::new(Id::Standard(0x181), &data).unwrap());
            sent += 1;
            check(&mut b)?;
        }
        let end = t + Duration::from_secs(1);
        b.handle_timeout(end);
        check(&mut b)?;
        prop_assert_eq!(b.poll_timeout(), None);
        let bus = *b.bus_counters(0).unwrap();
        let mut due = 0u64;
        let mut accounted = 0u64;
        for m in 0..3 {
            let c = *b.counters(m).unwrap();
            // Each frame a member sent was due at the other two, unless it never left the
            // sender (cut) or was lost on the bus for both.
            due += 2 * c.rx;
            accounted += c.tx - c.duplicated + c.cut + c.partitioned + c.dropped + c.corrupted
                + c.overflow;
        }
        let sender_cut = cut.map_or(0, |m| b.counters(m).unwrap().rx);
        // A frame cut at its sender is counted once there, and was due at two members.
        accounted += sender_cut;
        accounted += 2 * bus.dropped;
        prop_assert_eq!(sent, (0..3).map(|m| b.counters(m).unwrap().rx).sum::<u64>());
        prop_assert_eq!(due, accounted);
    }
}
