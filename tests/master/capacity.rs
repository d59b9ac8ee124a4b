//! The master's own PDOs and SDO sessions: configuration values (`MasterConfig::with_tpdos`,
//! `with_rpdos`, `with_sdo_sessions`), allocated once when the master is built and never grown;
//! what does not fit is refused as it always was.

use duocan::cia302::pdo_config::{mirror, Local, Mirror, MirrorError, PdoConfig};
use duocan::master::{
    objects, Master, MasterConfig, MasterError, MasterEventKind, MasterSdoClient,
};
use duocan::od::{comm, DataType, DynamicDictionary, ObjectDictionary};
use duocan::pdo::{Dir, MapEntry};
use duocan::profile::Predefined;
use duocan::sdo::{Channel, SdoErrorKind, SdoOptions};
use duocan::{CobId, Frame, Id, Instant, Machine, NmtState, NodeConfig, NodeId};

fn build(config: MasterConfig) -> Result<Master<DynamicDictionary>, MasterError> {
    let od = objects::master_dictionary(1, comm::Identity::default());
    Master::new(NodeId::must(1), od, config)
}

/// A booted master with no slaves: it starts itself, so its PDOs run.
fn booted(config: MasterConfig) -> Master<DynamicDictionary> {
    let mut m = build(config).expect("master");
    m.boot(Instant::ZERO);
    assert_eq!(m.node().nmt_state(), NmtState::Operational);
    m
}

/// Mirrors a one-entry (16-bit) slave TPDO on `cob` into the master's RPDO `pdo`, landing in
/// 0x2100 + `pdo` sub 1.
fn mirror_rpdo(m: &mut Master<DynamicDictionary>, pdo: u16, cob: u32) -> Result<(), MirrorError> {
    let remote = PdoConfig::new(CobId(cob), 255)
        .mapping(&[MapEntry::new(0x6000, 0, 16)])
        .unwrap();
    let locals = [Some(Local::new(0x2100 + pdo, 1, DataType::Unsigned16))];
    let mir = Mirror {
        pdo,
        transmission_type: 255,
        event_timer_ms: 0,
        inhibit_100us: 0,
        locals: &locals,
    };
    mirror(m.node_mut(), Instant::ZERO, Dir::Transmit, &remote, &mir)
}

/// The slave TPDO identifiers mirrored: TPDO1 and TPDO2 of nodes 2–41 (80 PDOs), then TPDO3 of
/// nodes 2–21.
fn cob(k: u16) -> u32 {
    let (tpdo, node) = (k / 40, k % 40 + 2);
    0x180 + 0x100 * tpdo as u32 + node as u32
}

#[test]
fn a_master_configured_for_100_rpdos_mirrors_100_slave_tpdos_and_refuses_the_101st() {
    let mut m = booted(MasterConfig::new().with_rpdos(100));
    assert_eq!(m.node().rpdo_capacity(), 100);
    for k in 0..100u16 {
        mirror_rpdo(&mut m, k + 1, cob(k)).unwrap_or_else(|e| panic!("RPDO{}: {e}", k + 1));
    }
    // The 101st is refused as any PDO beyond a node's capacity is.
    assert_eq!(
        mirror_rpdo(&mut m, 101, 0x4A0),
        Err(MirrorError::NoSuchPdo {
            pdo: 101,
            capacity: 100
        })
    );
    assert_eq!(m.node().rpdo_status(101), None);

    // Eighty slave TPDOs (two per board of forty) and twenty more arrive: every one lands.
    let t = Instant::from_millis(5);
    for k in 0..100u16 {
        let v = 1000 + k;
        m.handle_frame(
            t,
            &Frame::new(Id::Standard(cob(k) as u16), &v.to_le_bytes()).unwrap(),
        );
    }
    for k in 0..100u16 {
        let pdo = k + 1;
        assert_eq!(
            m.node().od().get_value::<u16>(0x2100 + pdo, 1),
            Ok(1000 + k),
            "RPDO{pdo}"
        );
        let s = m.node().rpdo_status(pdo).unwrap();
        assert_eq!((s.running, s.received), (true, 1), "RPDO{pdo}");
    }
    // The tables did not grow with the load.
    assert_eq!(
        (m.node().rpdo_capacity(), m.node().tpdo_capacity()),
        (100, 4)
    );
}

#[test]
fn the_default_master_keeps_4_tpdos_64_rpdos_and_8_sessions() {
    let mut m = booted(MasterConfig::new());
    assert_eq!(
        (
            m.node().tpdo_capacity(),
            m.node().rpdo_capacity(),
            m.sdo().sessions()
        ),
        (
            duocan::master::TPDOS,
            duocan::master::RPDOS,
            duocan::master::SESSIONS
        )
    );
    assert_eq!(
        (
            m.node().tpdo_capacity(),
            m.node().rpdo_capacity(),
            m.sdo().sessions()
        ),
        (4, 64, 8)
    );
    mirror_rpdo(&mut m, 64, 0x185).unwrap();
    assert_eq!(
        mirror_rpdo(&mut m, 65, 0x186),
        Err(MirrorError::NoSuchPdo {
            pdo: 65,
            capacity: 64
        })
    );
    assert_eq!(concurrent_uploads(&mut m, 9), 8);
}

/// Starts uploads of 0x1018 sub 1 from nodes 2, 3, … (`n` of them) until one is refused for lack
/// of a session, answers every one that started and checks each result. Returns how many ran.
fn concurrent_uploads(m: &mut Master<DynamicDictionary>, n: u8) -> usize {
    let t = Instant::from_millis(1);
    let sessions = m.sdo().sessions();
    let mut started = vec![];
    for k in 0..n {
        let node = NodeId::must(2 + k);
        match m
            .sdo_mut()
            .upload(t, node, 0x1018, 1, SdoOptions::default())
        {
            Ok(id) => started.push((node, id)),
            Err(e) => {
                assert_eq!(e.kind, SdoErrorKind::NoSession { sessions });
                assert_eq!(
                    started.len(),
                    sessions,
                    "refused only when all sessions run"
                );
                break;
            }
        }
    }
    assert_eq!(m.sdo().in_flight(), started.len());
    // Every request is on the wire before any answer: the transfers run at the same time.
    let mut requests = vec![];
    while let Some(f) = m.poll_transmit() {
        if (0x601..=0x67F).contains(&f.id().raw()) {
            requests.push(f.id().raw() - 0x600);
        }
    }
    let want: Vec<u32> = started.iter().map(|(n, _)| n.raw() as u32).collect();
    assert_eq!(requests, want);
    let t = Instant::from_millis(2);
    for (node, _) in &started {
        let v = 0x1000 + node.raw() as u32;
        let b = v.to_le_bytes();
        let answer = [0x43, 0x18, 0x10, 0x01, b[0], b[1], b[2], b[3]];
        m.handle_frame(
            t,
            &Frame::from_array(Channel::predefined(*node).response, answer),
        );
    }
    let mut done = vec![];
    while let Some(e) = m.poll_event() {
        if let MasterEventKind::Sdo(s) = e.kind {
            let v = 0x1000 + s.node.raw() as u32;
            assert_eq!(s.data(), Some(&v.to_le_bytes()[..]), "{}", s.node);
            done.push(s.request);
        }
    }
    assert_eq!(done, started.iter().map(|(_, id)| *id).collect::<Vec<_>>());
    assert_eq!(m.sdo().in_flight(), 0);
    assert_eq!(
        m.sdo().sessions(),
        sessions,
        "the session table did not grow"
    );
    started.len()
}

#[test]
fn a_master_configured_for_16_sessions_runs_16_transfers_at_once_and_refuses_the_17th() {
    let mut m = booted(MasterConfig::new().with_sdo_sessions(16));
    assert_eq!(m.sdo().sessions(), 16);
    assert_eq!(concurrent_uploads(&mut m, 17), 16);
    // And again: the sessions are free for the next round.
    assert_eq!(concurrent_uploads(&mut m, 17), 16);
}

#[test]
fn pdo_counts_beyond_what_cia_301_numbers_are_a_configuration_error() {
    assert!(matches!(
        build(MasterConfig::new().with_rpdos(513)),
        Err(MasterError::TooManyPdos {
            dir: Dir::Receive,
            count: 513
        })
    ));
    assert!(matches!(
        build(MasterConfig::new().with_tpdos(600)),
        Err(MasterError::TooManyPdos {
            dir: Dir::Transmit,
            count: 600
        })
    ));
    let m = build(MasterConfig::new().with_tpdos(512).with_rpdos(512)).unwrap();
    assert_eq!(
        (m.node().tpdo_capacity(), m.node().rpdo_capacity()),
        (512, 512)
    );
    assert_eq!(
        build(MasterConfig::new().with_sdo_sessions(0))
            .unwrap()
            .sdo()
            .sessions(),
        1
    );
}

fn extended(node: NodeId) -> Channel {
    Channel {
        request: Id::Extended(0x100_0000 + node.raw() as u32),
        response: Id::Extended(0x200_0000 + node.raw() as u32),
    }
}

#[test]
fn a_client_given_to_with_parts_gets_the_configured_session_count_and_keeps_its_limit_and_channels()
{
    let od = objects::master_dictionary(1, comm::Identity::default());
    let sdo = MasterSdoClient::with_sessions(1000, 3).with_channels(extended);
    let m = Master::with_parts(
        NodeConfig::master(NodeId::must(1)),
        od,
        Predefined,
        sdo,
        MasterConfig::new().with_sdo_sessions(5),
    )
    .unwrap();
    let five = NodeId::must(5);
    assert_eq!(m.sdo().sessions(), 5);
    assert_eq!(m.sdo().limit(), 1000);
    assert_eq!(m.sdo().channel(five), extended(five));
}
