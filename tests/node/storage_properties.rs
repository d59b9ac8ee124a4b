//! Property test of 0x1010/0x1011 and the resets against a model: per parameter, the value
//! after a reset that covers it is the stored one if any, else the power-on one; storing a
//! group copies its current values, restoring removes them; a failed store or restore changes
//! nothing. Random sequences of SDO writes, stores, restores, both resets, power cycles and
//! medium failures.

use crate::storage::{
    ms, nmt, sdo_write, slave, values, Flaky, Slave, APPLICATION, LOAD, MANUFACTURER, POWER_ON,
    RESET_COMMUNICATION, RESET_NODE, SAVE,
};
use duocan::od::comm;
use duocan::od::parameters::ParameterGroup;
use duocan::AbortCode;
use proptest::prelude::*;

/// The three parameters the model follows: 0x1017 (communication), 0x2000 (manufacturer),
/// 0x6000 (application).
const INDICES: [u16; 3] = [comm::HEARTBEAT_PRODUCER, MANUFACTURER, APPLICATION];

#[derive(Clone, Debug)]
enum Op {
    Write(usize, u16),
    Store(u8),
    Restore(u8),
    ResetCommunication,
    ResetNode,
    PowerCycle,
    /// The medium refuses the next store or restore.
    Fail,
}

fn any_op() -> impl Strategy<Value = Op> {
    prop_oneof![
        3 => (0usize..3, 1u16..2000).prop_map(|(e, v)| Op::Write(e, v)),
        2 => (1u8..=4).prop_map(Op::Store),
        2 => (1u8..=4).prop_map(Op::Restore),
        1 => Just(Op::ResetCommunication),
        1 => Just(Op::ResetNode),
        1 => Just(Op::PowerCycle),
        1 => Just(Op::Fail),
    ]
}

struct Model {
    current: [u32; 3],
    stored: [Option<u32>; 3],
    fail: bool,
}

impl Model {
    fn power_on(e: usize) -> u32 {
        [POWER_ON.0 as u32, POWER_ON.1, POWER_ON.2 as u32][e]
    }
    fn reload(&mut self, range: std::ops::RangeInclusive<u16>) {
        for (e, index) in INDICES.iter().enumerate() {
            if range.contains(index) {
                self.current[e] = self.stored[e].unwrap_or(Self::power_on(e));
            }
        }
    }
}

fn bytes(e: usize, v: u16) -> Vec<u8> {
    if INDICES[e] == MANUFACTURER {
        (v as u32).to_le_bytes().to_vec()
    } else {
        v.to_le_bytes().to_vec()
    }
}

fn observed(node: &Slave) -> [u32; 3] {
    let (a, b, c) = values(node);
    [a as u32, b, c as u32]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]
    #[test]
    fn stores_restores_and_resets_follow_the_model(ops in proptest::collection::vec(any_op(), 1..40)) {
        let mut node = slave(Flaky::default());
        let mut m = Model {
            current: [1000, 20, 10],
            stored: [None; 3],
            fail: false,
        };
        let t = ms(1);
        for op in ops {
            match op {
                Op::Write(e, v) => {
                    sdo_write(&mut node, t, INDICES[e], 0, &bytes(e, v)).unwrap();
                    m.current[e] = v as u32;
                }
                Op::Store(sub) | Op::Restore(sub) => {
                    let store = matches!(op, Op::Store(_));
                    let (index, signature) = if store {
                        (comm::STORE_PARAMETERS, SAVE)
                    } else {
                        (comm::RESTORE_DEFAULTS, LOAD)
                    };
                    let group = ParameterGroup::from_sub(sub).unwrap();
                    let r = sdo_write(&mut node, t, index, sub, signature);
                    // A restore with nothing to remove touches nothing, so it cannot fail.
                    let nothing_to_do = !store && m.stored.iter().all(Option::is_none);
                    if m.fail && !nothing_to_do {
                        prop_assert_eq!(r, Err(AbortCode::HARDWARE_ERROR));
                    } else {
                        prop_assert_eq!(r, Ok(()));
                        for (e, index) in INDICES.iter().enumerate() {
                            if group.contains(*index) {
                                m.stored[e] = store.then_some(m.current[e]);
                            }
                        }
                    }
                    m.fail = false;
                    node.od_mut().storage_mut().fail = false;
                }
                Op::ResetCommunication => {
                    nmt(&mut node, t, RESET_COMMUNICATION);
                    m.reload(0x1000..=0x1FFF);
                }
                Op::ResetNode => {
                    nmt(&mut node, t, RESET_NODE);
                    m.reload(0x1000..=0xFFFF);
                }
                Op::PowerCycle => {
                    let medium = std::mem::take(node.od_mut().storage_mut());
                    node = slave(medium);
                    m.reload(0x1000..=0xFFFF);
                }
                Op::Fail => {
                    m.fail = true;
                    node.od_mut().storage_mut().fail = true;
                }
            }
            prop_assert_eq!(observed(&node), m.current);
        }
    }
}
