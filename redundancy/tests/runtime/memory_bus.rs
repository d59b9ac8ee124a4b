//! The logical network object under duocan's tokio runtime, on two in-memory buses: the same
//! sans-IO device the simulator runs, driven by wall-clock time. SDO through `Handle::request`
//! (start on the device, completion by request id) and `Handle::sdo_read`, NMT through
//! `Handle::try_call` and state queries through `Handle::call`, each with one flat error.

use duocan::master::{objects, Master, MasterConfig};
use duocan::nmt::NmtTarget;
use duocan::od::{comm, DynamicDictionary};
use duocan::port::mem::MemBus;
use duocan::runtime::Runtime;
use duocan::sdo::SdoOptions;
use duocan::{Duration, Instant, NmtCommand, NmtState, Node, NodeConfig, NodeId, Station};
use duocan_redundancy::supervisor::flying_master::MasterRole;
use duocan_redundancy::PairSpec;
use duocan_redundancy::{
    DualBus, DualBusConfig, LogicalNetwork, Member, NetworkError, NetworkEventKind,
    SupervisedStation, Supervisor, SupervisorConfig,
};

fn n(id: u8) -> NodeId {
    NodeId::must(id)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_network_object_under_the_tokio_runtime() {
    let ms = Duration::from_millis;
    let buses = [MemBus::new("can1"), MemBus::new("can2")];
    let od = objects::master_dictionary(1, comm::Identity::default());
    let master = Master::new(n(1), od, MasterConfig::new()).unwrap();
    // A weak peer is declared but absent: this master negotiates and becomes active.
    let cfg = SupervisorConfig::new(0, n(1), ms(20), ms(50), ms(10)).with_peer(1, n(2));
    let mut sup = Supervisor::new(master, cfg, Instant::ZERO);
    sup.add_pair(
        Instant::ZERO,
        PairSpec::new(n(0x10), n(0x50), ms(20), ms(100)),
    )
    .unwrap();
    let net: LogicalNetwork<DynamicDictionary> = LogicalNetwork::new(
        SupervisedStation::new(DualBus::new(DualBusConfig::default()), sup).unwrap(),
    );
    let h = Runtime::new(net)
        .name("turnout rack")
        .port(buses[0].port())
        .port(buses[1].port())
        .spawn()
        .unwrap();
    let mut boards = vec![];
    for id in [0x10u8, 0x50] {
        let identity = comm::Identity {
            vendor: 0xA5E,
            ..Default::default()
        };
        let mut node = Node::new(
            NodeConfig::slave(n(id)),
            comm::standard_dictionary(id, identity),
        );
        node.boot(Instant::ZERO);
        let b = Runtime::new(Station::new(DualBus::new(DualBusConfig::default()), node))
            .port(buses[0].port())
            .port(buses[1].port())
            .spawn()
            .unwrap();
        boards.push(b);
    }

    // Active after the power-on negotiation (~0.6 s), both members joined: the first one
    // configured runs (which one that is depends on the tasks' timing), the other stands by.
    let mut active = None;
    for _ in 0..100 {
        tokio::time::sleep(std::time::Duration::from_millis(50)).await;
        active = h
            .call(|net, _| {
                let (_, p) = net.pairs().next()?;
                let both = p.member(Member::A).joined() && p.member(Member::B).joined();
                (net.role() == MasterRole::Active && both)
                    .then_some(p.active)
                    .flatten()
            })
            .await
            .unwrap();
        if active.is_some() {
            break;
        }
    }
    let Some(active) = active else {
        let table = h
            .call(|net, now| net.status(now).to_string())
            .await
            .unwrap();
        panic!("the master did not become active with the pair joined:\n{table}");
    };
    let (run, stand) = match active {
        Member::A => (0, 1),
        Member::B => (1, 0),
    };
    for (board, want) in [
        (run, NmtState::Operational),
        (stand, NmtState::PreOperational),
    ] {
        let state = boards[board]
            .call(|st, _| st.machine.nmt_state())
            .await
            .unwrap();
        assert_eq!(state, want, "board {board}");
    }

    // SDO: started on the device, completed by the event with its request id.
    let vendor = h
        .request(
            |net, now| net.sdo_read(now, n(0x50), 0x1018, 1),
            |req, e| match &e.kind {
                NetworkEventKind::Sdo(s) if s.request == *req => Some(
                    s.result
                        .clone()
                        .map(|b| b.to_vec())
                        .map_err(NetworkError::from),
                ),
                _ => None,
            },
        )
        .await
        .unwrap();
    assert_eq!(vendor, 0xA5Eu32.to_le_bytes());
    // The same through the handle's SDO call, which does the above.
    let vendor = h
        .sdo_read(n(0x50), 0x1018, 1, SdoOptions::default())
        .await
        .unwrap();
    assert_eq!(vendor, 0xA5Eu32.to_le_bytes());

    // NMT through the network object, states through a call.
    h.try_call(|net, now| net.nmt(now, NmtCommand::Stop, NmtTarget::Node(n(0x50))))
        .await
        .unwrap();
    let mut stopped = false;
    for _ in 0..40 {
        tokio::time::sleep(std::time::Duration::from_millis(25)).await;
        stopped = boards[1]
            .call(|st, _| st.machine.nmt_state())
            .await
            .unwrap()
            == NmtState::Stopped;
        if stopped {
            break;
        }
    }
    assert!(stopped);
    let table = h
        .call(|net, now| net.status(now).to_string())
        .await
        .unwrap();
    assert!(table.contains("master node 0x01 (0): active"), "{table}");
    h.shutdown().await;
}
