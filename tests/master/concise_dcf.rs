//! The concise DCF (0x1F22): the 20-slave network of `dcf_config.rs` configured from concise
//! DCFs written into the master's 0x1F22 ends exactly as when configured from the DCFs, with the
//! same frames on the bus; a tool downloads one over SDO; a malformed one is refused with an
//! abort code and configures nothing; random configurations survive bytes and back.

use super::dcf_config::{network_from, From, Run, IDS, REFUSING};
use crate::net::*;
use duocan::machine::{CompositeEvent, StationEvent};
use duocan::master::{
    objects::CONCISE_DCF, BootError, ConciseDcf, ConciseEntry, ConfigStep, MasterConfig,
    MasterEventKind as K, SlaveConfig,
};
use duocan::od::{comm, ObjectDictionary};
use duocan::sdo::{SdoErrorKind, SdoOptions, TransferMode};
use duocan::sim::DevId;
use duocan::{AbortCode, Instant, NodeId};
use proptest::prelude::*;

/// (index, sub, value) of every entry of one dictionary.
type Entries = Vec<(u16, u8, Vec<u8>)>;

/// Every entry of every slave's dictionary, by node.
fn dictionaries(run: &Run) -> Vec<(u8, Entries)> {
    IDS.map(|id| {
        let mut all = vec![];
        run.slave(id)
            .od()
            .for_each(&mut |e| all.push((e.def.index, e.def.sub, e.data.to_vec())));
        all.sort();
        (id, all)
    })
    .collect()
}

#[test]
fn concise_dcfs_in_0x1f22_configure_the_twenty_slaves_exactly_as_their_dcfs() {
    let end = Instant::from_millis(500);
    let mut dcf = network_from(From::Dcf);
    dcf.sim.run_until(end);
    let mut concise = network_from(From::Concise);
    concise.sim.run_until(end);

    // The same frames, at the same times, and the same values in every slave's dictionary.
    let (a, b) = (frames(&dcf.sim), frames(&concise.sim));
    assert!(a.len() > 1_000, "{} frames", a.len());
    assert_eq!(a, b);
    assert_eq!(dictionaries(&dcf), dictionaries(&concise));
    let events = master_events(concise.sim.events(concise.master));
    let configured = all(&events, |k| {
        matches!(k, K::SlaveConfigured { .. }).then_some(())
    });
    assert_eq!(configured.len(), 20);
    let refused = all(&events, |k| match k {
        K::ConfigWriteAborted {
            node, index, sub, ..
        } => Some((node.raw(), *index, *sub)),
        _ => None,
    });
    assert_eq!(
        refused.iter().map(|(_, x)| *x).collect::<Vec<_>>(),
        [(REFUSING, APP, 3)]
    );

    // Read back over SDO: every value the DCF gives (the refused one still 0).
    let mut items = vec![];
    for (id, d) in IDS.zip(&concise.dcfs) {
        for e in d.parameter_values() {
            let fixed = matches!(
                e.access,
                duocan::eds::AccessType::Ro | duocan::eds::AccessType::Const
            );
            let skip = matches!(
                e.index,
                0x1020 | comm::STORE_PARAMETERS | comm::RESTORE_DEFAULTS | comm::HEARTBEAT_CONSUMER
            );
            if fixed || skip {
                continue;
            }
            let want = if (id, e.index, e.sub) == (REFUSING, APP, 3) {
                0u16.to_le_bytes().to_vec()
            } else {
                e.value_bytes(id)
            };
            items.push((id, e.index, e.sub, want));
        }
    }
    assert!(items.len() > 20 * 20);
    assert_eq!(concise.read_back(end, &items), items.len());
}

/// A master with slave 2 (nothing configured in code), slave 3 configured by the master, and
/// a tool; booted.
fn rig() -> (Net, DevId<Tool>) {
    let mut net = MasterConfig::new();
    for id in [2, 3] {
        net = net.slave(SlaveConfig::new(NodeId::must(id)).identity(expected(id)));
    }
    with_tool(500_000, net, duocan::master::MAX_CONCISE_BYTES)
}

/// The tool downloads `bytes` into the master's 0x1F22 sub `sub` (block transfer); the result.
fn download(n: &mut Net, tool: DevId<Tool>, sub: u8, bytes: &[u8]) -> Result<(), SdoErrorKind> {
    let now = n.sim.now();
    let opts = SdoOptions::default().with_mode(TransferMode::Block);
    let client = &mut n.sim.device_mut(tool).machine.b;
    client
        .download(now, MASTER_ID, CONCISE_DCF, sub, bytes, opts)
        .unwrap();
    loop {
        n.sim.step().expect("idle without a result");
        for (_, e) in n.sim.take_events(tool) {
            if let StationEvent::Machine(CompositeEvent::B(e)) = e {
                return e.result.map(|_| ()).map_err(|e| e.kind);
            }
        }
    }
}

fn config() -> ConciseDcf {
    let cfg = SlaveConfig::new(NodeId::must(2))
        .write_u16(APP, 1, 0x1234)
        .write_u16(APP, 2, 0x5678)
        .heartbeat(40, 0);
    ConciseDcf::from_config(&cfg).unwrap()
}

#[test]
fn a_tool_downloads_a_concise_dcf_and_the_next_boot_applies_it() {
    let (mut n, tool) = rig();
    assert_eq!(n.slave(2).od().get_u32(APP, 1), Some(0));
    let bytes = config().to_bytes();
    download(&mut n, tool, 2, &bytes).unwrap();
    assert_eq!(
        n.m().node().od().read(CONCISE_DCF, 2).map(<[u8]>::to_vec),
        Ok(bytes)
    );
    let now = n.sim.now();
    n.m_mut().boot_slave(now, NodeId::must(2)).unwrap();
    n.sim.run_for(duocan::Duration::from_millis(100));
    let s = n.slave(2);
    assert_eq!(s.od().get_u32(APP, 1), Some(0x1234));
    assert_eq!(s.od().get_u32(APP, 2), Some(0x5678));
    assert_eq!(s.od().get_u32(comm::HEARTBEAT_PRODUCER, 0), Some(40));
    // Slave 3 has none: untouched.
    assert_eq!(n.slave(3).od().get_u32(APP, 1), Some(0));
}

#[test]
fn a_malformed_concise_dcf_is_refused_and_configures_nothing() {
    let (mut n, tool) = rig();
    let good = config().to_bytes();
    download(&mut n, tool, 2, &good).unwrap();
    // Cut inside the last entry; a count above the entries given; trailing bytes.
    let mut more = good.clone();
    more[0] = 4;
    let mut trailing = good.clone();
    trailing.push(0);
    for bad in [&good[..good.len() - 3], &more[..], &trailing[..]] {
        assert_eq!(
            download(&mut n, tool, 2, bad),
            Err(SdoErrorKind::Server(AbortCode::VALUE_RANGE))
        );
        // The good one stays.
        assert_eq!(
            n.m().node().od().read(CONCISE_DCF, 2).map(<[u8]>::to_vec),
            Ok(good.clone())
        );
    }

    // One stored behind the check's back (straight into storage) fails the boot before any
    // write, naming the entry and offset.
    let cut = &good[..good.len() - 3];
    n.m_mut()
        .node_mut()
        .od_mut()
        .store(CONCISE_DCF, 3, cut)
        .unwrap();
    let t = n.sim.now();
    n.m_mut().boot_slave(t, NodeId::must(3)).unwrap();
    n.sim.run_for(duocan::Duration::from_millis(100));
    let events = n.events();
    let failed = all(&events, |k| match k {
        K::ConfigFailed { node, reason, .. } if node.raw() == 3 => Some(*reason),
        _ => None,
    });
    let [(_, BootError::ConciseDcf(e))] = failed.as_slice() else {
        panic!("{failed:?}");
    };
    // Three entries of 9 bytes: the cut falls inside the third one's header.
    assert_eq!((e.entry, e.offset), (3, good.len() - 9));
    assert_eq!(n.slave(3).od().get_u32(APP, 1), Some(0));
    let writes = frames(&n.sim).into_iter().filter(|(at, f)| {
        *at >= t && f.id() == duocan::Id::Standard(0x603) && f.data()[0] & 0xE0 == 0x20
    });
    assert_eq!(writes.count(), 0);
}

fn entries() -> impl Strategy<Value = Vec<ConciseEntry>> {
    prop::collection::vec(
        (
            any::<u16>(),
            any::<u8>(),
            prop::collection::vec(any::<u8>(), 0..12),
        )
            .prop_map(|(index, sub, data)| ConciseEntry { index, sub, data }),
        0..40,
    )
}

proptest! {
    #[test]
    fn random_concise_dcfs_survive_bytes_and_back(entries in entries()) {
        let dcf = ConciseDcf { entries };
        let bytes = dcf.to_bytes();
        prop_assert_eq!(duocan::master::validate_concise(&bytes), Ok(dcf.entries.len() as u32));
        prop_assert_eq!(ConciseDcf::parse(&bytes), Ok(dcf.clone()));
        // Every cut of the bytes is an error, never a panic.
        for cut in 0..bytes.len() {
            prop_assert!(ConciseDcf::parse(&bytes[..cut]).is_err());
        }
    }

    #[test]
    fn random_configurations_survive_a_concise_dcf(
        writes in prop::collection::vec(
            ((0x2000u16..0x2100), any::<u8>(), prop::collection::vec(any::<u8>(), 1..8)),
            0..30,
        ),
        heartbeat in prop::option::of(any::<u16>()),
    ) {
        let node = NodeId::must(9);
        let mut cfg = SlaveConfig::new(node);
        for (index, sub, data) in &writes {
            cfg = cfg.write(*index, *sub, data);
        }
        cfg.heartbeat_producer_ms = heartbeat;
        let bytes = ConciseDcf::from_config(&cfg).unwrap().to_bytes();
        let back = SlaveConfig::new(node).with_concise(&ConciseDcf::parse(&bytes).unwrap());
        prop_assert_eq!(&back.steps, &cfg.steps);
        prop_assert_eq!(back.heartbeat_producer_ms, heartbeat);
        let writes_only = back.steps.iter().all(|s| matches!(s, ConfigStep::Write { .. }));
        prop_assert!(writes_only);
    }
}
