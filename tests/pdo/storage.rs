//! Where the PDO tables live does not change what a node does: a node whose tables are on the
//! heap (`Heap`, the master's node) and one with the same capacities inline (the default) answer
//! the same inputs with the same frames, events and deadlines.

use crate::common::node;
use crate::properties::{any_pdo_frame, every_pdo_type};
use duocan::frame::storage::Heap;
use duocan::node::{Node, NodeConfig, ALL_NODES};
use duocan::od::comm;
use duocan::profile::Predefined;
use duocan::{Duration, Instant, Machine, NmtState, NodeId};
use proptest::prelude::*;

type HeapNode = Node<duocan::od::DynamicDictionary, Predefined, ALL_NODES, 4, 4, Heap>;

proptest! {
    #[test]
    fn a_node_with_heap_tables_behaves_as_the_inline_one(
        ops in proptest::collection::vec((any_pdo_frame(), 0u64..3_000, 0u8..20, any::<u16>()), 1..300)
    ) {
        let mut inline = node(5, false);
        every_pdo_type(inline.od_mut());
        // The same dictionary as `node` builds.
        let mut od = comm::standard_dictionary(
            5,
            comm::Identity { vendor: 0x1234, product: 5, ..Default::default() },
        );
        every_pdo_type(&mut od);
        let cfg = NodeConfig::slave(NodeId::must(5));
        let mut heap = HeapNode::with_pdo_capacity(cfg, od, Predefined, 4, 4);
        prop_assert_eq!((heap.tpdo_capacity(), heap.rpdo_capacity()), (4, 4));
        let mut now = Instant::ZERO;
        inline.boot(now);
        heap.boot(now);
        for n in [&mut inline as &mut dyn NodeLike, &mut heap] {
            n.start(now);
        }
        for (f, dt, op, v) in ops {
            now += Duration::from_micros(dt);
            let due = inline.poll_timeout();
            prop_assert_eq!(due, heap.poll_timeout());
            if due.is_some_and(|t| t <= now) {
                inline.handle_timeout(now);
                heap.handle_timeout(now);
            }
            match op {
                0 => {
                    inline.set_nmt_state(now, NmtState::PreOperational);
                    heap.set_nmt_state(now, NmtState::PreOperational);
                }
                1 => {
                    inline.set_nmt_state(now, NmtState::Operational);
                    heap.set_nmt_state(now, NmtState::Operational);
                }
                2..=5 => {
                    prop_assert_eq!(inline.set(now, 0x6001, 0, v), heap.set(now, 0x6001, 0, v));
                }
                6 => {
                    prop_assert_eq!(inline.tpdo_request(now, v % 6), heap.tpdo_request(now, v % 6));
                }
                _ => {}
            }
            inline.handle_frame(now, &f);
            heap.handle_frame(now, &f);
            let drain = |n: &mut dyn NodeLike| (n.frames(), n.events());
            prop_assert_eq!(drain(&mut inline), drain(&mut heap));
            for p in 0..=5 {
                prop_assert_eq!(inline.tpdo_status(p), heap.tpdo_status(p));
                prop_assert_eq!(inline.rpdo_status(p), heap.rpdo_status(p));
            }
        }
        prop_assert_eq!((heap.tpdo_capacity(), heap.rpdo_capacity()), (4, 4));
    }
}

/// What the property does to both nodes alike.
trait NodeLike {
    fn start(&mut self, now: Instant);
    fn frames(&mut self) -> Vec<duocan::Frame>;
    fn events(&mut self) -> Vec<duocan::NodeEvent>;
}

impl<S: duocan::frame::storage::Storage> NodeLike
    for Node<duocan::od::DynamicDictionary, Predefined, ALL_NODES, 4, 4, S>
{
    fn start(&mut self, now: Instant) {
        self.set_nmt_state(now, NmtState::Operational);
        self.set(now, comm::EMCY_INHIBIT, 0, 0u16).unwrap();
    }
    fn frames(&mut self) -> Vec<duocan::Frame> {
        core::iter::from_fn(|| self.poll_transmit()).collect()
    }
    fn events(&mut self) -> Vec<duocan::NodeEvent> {
        core::iter::from_fn(|| self.poll_event()).collect()
    }
}
