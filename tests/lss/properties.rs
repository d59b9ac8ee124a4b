//! Properties: fastscan finds any set of non-configured slaves in identity order at the
//! predicted cost; the slave state machine, fed any frames, keeps its invariants.

use super::fastscan::{cost, counts};
use super::wire::{addr, req, slave, Wire};
use duocan::cia305::{
    LssAddress, LssMaster, LssMasterConfig, LssMasterEventKind as K, LssMode, LssPlan,
};
use duocan::{Duration, Frame, Id, Instant, Machine, NodeId};
use proptest::prelude::*;

fn address() -> impl Strategy<Value = LssAddress> {
    // Few values per part, so that slaves share vendors, products and revisions.
    (0u32..3, 0u32..3, 0u32..3, any::<u32>()).prop_map(|(v, p, r, s)| addr(v, p, r, s))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn fastscan_configures_every_slave_in_identity_order(
        ids in proptest::collection::btree_set(address(), 1..6),
        configured in proptest::collection::vec(address(), 0..3),
    ) {
        let ids: Vec<LssAddress> = ids.into_iter().collect();
        let cfg = LssMasterConfig::default()
            .with_timeout(Duration::from_millis(5))
            .with_settle(Duration::from_micros(500));
        let mut slaves: Vec<_> = ids.iter().map(|a| slave(*a, 0xFF)).collect();
        // Configured slaves (even with an identity equal to a non-configured one) stay out.
        slaves.extend(configured.iter().map(|a| slave(*a, 100)));
        let mut w = Wire::new(LssMaster::new(cfg), slaves);
        w.master.fastscan(Instant::ZERO, LssPlan::new().with_free((1..=127).map(NodeId::must))).unwrap();
        w.run(100_000);
        let assigned: Vec<(LssAddress, u8)> = w
            .take_events()
            .into_iter()
            .filter_map(|k| match k {
                K::Assigned { address, node } => Some((address, node.raw())),
                _ => None,
            })
            .collect();
        let want: Vec<(LssAddress, u8)> = ids.iter().copied().zip(1u8..).collect();
        prop_assert_eq!(assigned, want);
        for (i, a) in ids.iter().enumerate() {
            prop_assert_eq!(w.slaves[i].node_id(), NodeId::new(i as u8 + 1), "{}", a);
        }
        for s in &w.slaves[ids.len()..] {
            prop_assert_eq!(s.node_id(), Some(NodeId::must(100)));
        }
        prop_assert_eq!(counts(&w), cost(&ids, cfg.timeout, cfg.settle, false));
    }

    #[test]
    fn the_slave_keeps_its_invariants_whatever_it_is_fed(
        frames in proptest::collection::vec(
            (prop_oneof![Just(0x7E5u16), Just(0x000u16), Just(0x7E4u16)],
             prop_oneof![
                 Just(0x04u8), Just(0x11), Just(0x13), Just(0x15), Just(0x17), Just(0x40),
                 Just(0x43), Just(0x46), Just(0x4B), Just(0x4C), Just(0x51), Just(0x5A),
                 Just(0x5E), Just(0x81), Just(0x82), any::<u8>()
             ],
             proptest::array::uniform7(prop_oneof![Just(0u8), Just(1), Just(0xFF), any::<u8>()]),
             0u8..=8,
             0u64..50),
            0..80),
        node in prop_oneof![Just(0xFFu8), 1u8..=127],
    ) {
        let mut s = slave(addr(1, 2, 3, 4), node);
        let mut now = Instant::ZERO;
        for (id, cs, rest, len, dt) in frames {
            now += Duration::from_millis(dt);
            let mut data = [0u8; 8];
            data[0] = cs;
            data[1..].copy_from_slice(&rest);
            let f = Frame::new(Id::Standard(id), &data[..usize::from(len)]).unwrap();
            let mode = s.mode();
            s.handle_frame(now, &f);
            if let Some(t) = s.poll_timeout() {
                prop_assert!(t > now, "a deadline in the past");
            }
            while let Some(a) = s.poll_transmit() {
                prop_assert_eq!((a.id(), a.dlc()), (Id::Standard(0x7E4), 8));
                // Configuration services are answered in configuration mode only.
                let config = matches!(a.data()[0], 0x11 | 0x13 | 0x17 | 0x5A..=0x5E);
                prop_assert!(!config || mode == LssMode::Configuration, "{:02x?} in {:?}", a.data(), mode);
            }
            let pending = s.pending_node_id();
            prop_assert!(pending == 0xFF || (1..=127).contains(&pending));
            while s.poll_event().is_some() {}
            s.handle_timeout(now);
        }
        // Whatever happened, it still answers a well-formed request in configuration mode.
        s.handle_timeout(now + Duration::from_secs(200));
        let later = now + Duration::from_secs(200);
        s.handle_frame(later, &req([0x04, 1, 0, 0, 0, 0, 0, 0]));
        s.handle_frame(later, &req([0x5A, 0, 0, 0, 0, 0, 0, 0]));
        prop_assert_eq!(s.poll_transmit().map(|f| f.data()[..2].to_vec()), Some(vec![0x5A, 1]));
    }
}
