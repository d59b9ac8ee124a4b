//! Multiplexed PDOs between the CiA 302-2 master and slaves on the simulated bus (real frame
//! durations): the master's destination-address write changes a slave's object, and a slave's
//! source-address value reaches the master's dispatcher list, mapped to the master's own object.

use crate::net::{identity, master_with, slave_dictionary, SlaveDev, MASTER_ID};
use duocan::master::MasterConfig;
use duocan::mpdo::{dispatcher_list, scanner_list, DispatcherEntry, ScannerEntry};
use duocan::od::{Access, DefaultValue, DynamicDictionary, ObjectDef, ObjectDictionary};
use duocan::pdo::params;
use duocan::sim::{BusConfig, SimNetwork, TraceRecord, TxOutcome};
use duocan::{Id, Instant, NmtCommand, NmtState, NmtTarget, Node, NodeConfig, NodeId, Station};

/// The master's DAM channel (its TPDO1), which the slaves receive on RPDO1.
const DAM_COB: u32 = 0x300;
/// Slave 2's SAM channel (its TPDO2), which the master receives on RPDO1.
const SAM_COB: u32 = 0x282;

fn mpdo_tables(od: &mut DynamicDictionary, tx: (u16, u32, u8), rx: (u16, u32, u8)) {
    let (tp, tcob, tcount) = tx;
    let (rp, rcob, rcount) = rx;
    let cob = |c: u32| DefaultValue::Unsigned(c as u64);
    // Replace whatever the dictionary had for these PDOs.
    for i in [
        0x1800 + tp - 1,
        0x1A00 + tp - 1,
        0x1400 + rp - 1,
        0x1600 + rp - 1,
    ] {
        od.remove_object(i);
    }
    od.insert_all(&params::tpdo_comm(tp, cob(tcob), 254, 0, 0))
        .unwrap();
    let mut m = params::tpdo_mapping::<2>(tp, &[]);
    m[0] = ObjectDef::u8(m[0].index, 0, Access::Rw, tcount);
    od.insert_all(&m).unwrap();
    od.insert_all(&params::rpdo_comm(rp, cob(rcob), 254, 0))
        .unwrap();
    let mut m = params::rpdo_mapping::<2>(rp, &[]);
    m[0] = ObjectDef::u8(m[0].index, 0, Access::Rw, rcount);
    od.insert_all(&m).unwrap();
}

fn slave(id: u8) -> SlaveDev {
    let mut od = slave_dictionary(id, identity(id), None);
    // TPDO2: SAM (node 2's 0x2000/1..=2 scanned); RPDO1: MPDO consumer on the DAM channel.
    mpdo_tables(
        &mut od,
        (2, SAM_COB + id as u32 - 2, 0xFE),
        (1, DAM_COB, 0xFF),
    );
    let scan = ScannerEntry {
        index: 0x2000,
        sub: 1,
        block: 2,
    };
    od.insert_all(&scanner_list::<2>(0, &[scan.raw()])).unwrap();
    let cfg = NodeConfig::slave(NodeId::must(id)).with_auto_start(true);
    Station::single(Node::new(cfg, od))
}

#[test]
fn dam_writes_reach_a_slave_and_sam_values_reach_the_master_dispatcher() {
    let m = master_with(MASTER_ID, MasterConfig::new(), |od| {
        mpdo_tables(od, (1, DAM_COB, 0xFF), (1, SAM_COB, 0xFE));
        od.insert_all(&[
            ObjectDef::u16(0x2200, 1, Access::Rw, 0).mappable(),
            ObjectDef::u16(0x2200, 2, Access::Rw, 0).mappable(),
        ])
        .unwrap();
        let entry = DispatcherEntry {
            producer: 2,
            producer_index: 0x2000,
            producer_sub: 1,
            local_index: 0x2200,
            local_sub: 1,
            block: 2,
        };
        od.insert_all(&dispatcher_list::<2>(0, &[entry.raw()]))
            .unwrap();
    });
    let mut sim = SimNetwork::new(11);
    let bus = sim.add_bus(BusConfig::new("can0", 250_000));
    let master = sim
        .add_device("master", Station::single(m), &[bus])
        .unwrap();
    let s2 = sim.add_device("slave2", slave(2), &[bus]).unwrap();
    let s3 = sim.add_device("slave3", slave(3), &[bus]).unwrap();
    sim.device_mut(master).machine.boot(Instant::ZERO);
    for s in [s2, s3] {
        sim.device_mut(s).machine.boot(Instant::ZERO);
    }
    sim.run_until(Instant::from_millis(50));
    let now = sim.now();
    let node = sim.device_mut(master).machine.node_mut();
    node.set_nmt_state(now, NmtState::Operational);
    node.nmt_command(now, NmtCommand::Start, NmtTarget::All)
        .unwrap();
    sim.run_until(Instant::from_millis(100));
    for s in [s2, s3] {
        assert_eq!(sim.device(s).machine.nmt_state(), NmtState::Operational);
    }

    // The master writes 0x0BAD into slave 3's 0x2000/2.
    let now = sim.now();
    sim.device_mut(master)
        .machine
        .node_mut()
        .mpdo_send_dam(now, 1, 3, 0x2000, 2, &[0xAD, 0x0B])
        .unwrap();
    sim.run_until(Instant::from_millis(110));
    let od3 = sim.device(s3).machine.od();
    assert_eq!(od3.get_value::<u16>(0x2000, 2), Ok(0x0BAD));
    let od2 = sim.device(s2).machine.od();
    assert_eq!(
        od2.get_value::<u16>(0x2000, 2),
        Ok(0),
        "addressed to 3 only"
    );
    assert_eq!(sim.device(s2).machine.mpdo_stats().other_node, 1);

    // Slave 2 sends its 0x2000/1 as SAM; the master's dispatcher puts it into 0x2200/1.
    let now = sim.now();
    let n2 = &mut sim.device_mut(s2).machine;
    n2.set(now, 0x2000, 1, 0x4321u16).unwrap();
    n2.mpdo_send_sam(now, 2, 0x2000, 1).unwrap();
    sim.run_until(Instant::from_millis(120));
    let mo = sim.device(master).machine.node().od();
    assert_eq!(mo.get_value::<u16>(0x2200, 1), Ok(0x4321));
    assert_eq!(mo.get_value::<u16>(0x2200, 2), Ok(0));
    assert_eq!(sim.device(master).machine.node().mpdo_stats().written, 1);

    // On the wire: one DAM frame, one SAM frame, with the exact bytes.
    let mpdos: Vec<(Id, Vec<u8>)> = sim
        .trace()
        .iter()
        .filter_map(|r| match r {
            TraceRecord::Tx(t)
                if matches!(t.outcome, TxOutcome::Delivered { .. })
                    && [DAM_COB, SAM_COB].contains(&t.frame.id().raw()) =>
            {
                Some((t.frame.id(), t.frame.data().to_vec()))
            }
            _ => None,
        })
        .collect();
    assert_eq!(
        mpdos,
        [
            (
                Id::Standard(0x300),
                vec![0x83, 0x00, 0x20, 0x02, 0xAD, 0x0B, 0, 0]
            ),
            (
                Id::Standard(0x282),
                vec![0x02, 0x00, 0x20, 0x01, 0x21, 0x43, 0, 0]
            ),
        ]
    );
}
