//! LSS (CiA 305) through the front door (`Network::lss`) over both doors: the plain door on the
//! simulated station's two buses, and the redundant master's door on two buses with the same
//! two boards without a node-ID. They are found by fastscan, configured, booted and answer on
//! both buses; the single services; a listen-only network and a standby master send nothing.

use crate::doors::{self, on_both, Door, BOTH};
use duocan::cia305::{fastscan_cost, Inquiry, LssMasterConfig, LssMode, LssPlan};
use duocan::net::{NetError, NetOptions, Network, SIM_VENDOR};
use duocan::port::mem::MemBus;
use duocan::runtime::Handle;
use duocan::{NodeId, Station};
use duocan_redundancy::net::{
    open_dual_named, sim_lss_address, sim_lss_board, SimLssBoard, SIM_LSS_PRODUCT, SIM_LSS_SERIALS,
};
use duocan_redundancy::DualBus;
use std::time::Duration;

/// A board of the station's without a node-ID, on both buses.
type Board = Handle<Station<DualBus, SimLssBoard>>;

/// The network on `door`, and what must keep running with it: the plain door on the simulated
/// station (which has the boards), the redundant one on two buses with the two boards.
async fn open(door: Door) -> (Network, Vec<Board>) {
    match door {
        Door::Plain => (
            open_dual_named("sim-station", NetOptions::default()).unwrap(),
            vec![],
        ),
        Door::Redundant => {
            let buses = [MemBus::new("bus1"), MemBus::new("bus2")];
            let net = doors::open(door, &buses).await;
            let boards = SIM_LSS_SERIALS
                .iter()
                .map(|s| on_both(sim_lss_board(*s), &buses))
                .collect();
            (net, boards)
        }
    }
}

async fn close(net: Network, boards: Vec<Board>) {
    net.close().await;
    for b in boards {
        b.shutdown().await;
    }
}

#[tokio::test(start_paused = true)]
async fn fastscan_configures_both_boards_and_they_boot_on_both_buses() {
    for door in BOTH {
        fastscan_configures_both_boards(door).await;
    }
}

async fn fastscan_configures_both_boards(door: Door) {
    let (net, running) = open(door).await;
    let lss = net.lss();
    assert!(lss.identify_non_configured().await.unwrap());
    let plan = LssPlan::new().with_free((0x20..=0x7F).filter_map(NodeId::new));
    let report = lss.fastscan(plan).await.unwrap();
    let boards: Vec<_> = SIM_LSS_SERIALS
        .iter()
        .map(|s| sim_lss_address(*s))
        .collect();
    assert_eq!(
        report.assigned,
        [
            (boards[0], NodeId::must(0x20)),
            (boards[1], NodeId::must(0x21))
        ]
    );
    assert_eq!(report.stopped, None);
    // The frames are the protocol's, to the frame: each board's answer counted once after the
    // merge of the two buses.
    let cost = fastscan_cost(&mut boards.clone(), &LssMasterConfig::default(), false);
    assert_eq!(
        (report.requests, report.answers),
        (cost.requests, cost.answers)
    );
    assert_eq!((cost.requests, cost.answers), (271, 360));
    // The time: the waiting the protocol needs, plus the frames on the 1 Mbit/s buses.
    assert!(report.took.as_micros() >= cost.waiting.as_micros());
    assert!(
        report.took.as_micros() < cost.waiting.as_micros() + 200_000,
        "{:?} against {:?} of waiting",
        report.took,
        cost.waiting
    );
    println!(
        "fastscan of 2 boards on two buses ({door:?} door): {} requests, {} answers, {:?} (the protocol: {} requests, {} answers, {:?} of waiting)",
        report.requests, report.answers, report.took, cost.requests, cost.answers, cost.waiting
    );
    // Each boots with its node-ID and identity and is heard on both buses.
    for (i, id) in [0x20u8, 0x21].into_iter().enumerate() {
        let node = net.node(id);
        node.wait_for_boot_up_since(duocan::Instant::ZERO, Duration::from_secs(1))
            .await
            .unwrap();
        let sdo = node.sdo();
        assert_eq!(sdo.read::<u32>(0x1018, 1).await.unwrap(), SIM_VENDOR);
        assert_eq!(sdo.read::<u32>(0x1018, 2).await.unwrap(), SIM_LSS_PRODUCT);
        assert_eq!(
            sdo.read::<u32>(0x1018, 4).await.unwrap(),
            SIM_LSS_SERIALS[i]
        );
    }
    // Reach is reported once the dual-bus layer has heard a node a while (its heartbeats).
    tokio::time::sleep(Duration::from_secs(1)).await;
    for id in [0x20, 0x21] {
        assert_eq!(
            net.heard_on(id).await.unwrap(),
            Some([true, true].into()),
            "{id:#04x}"
        );
    }
    // Nobody left without a node-ID: a second scan is one reset nobody answers.
    assert!(!lss.identify_non_configured().await.unwrap());
    let again = lss.fastscan(LssPlan::new()).await.unwrap();
    assert_eq!(
        (again.assigned.len(), again.requests, again.answers),
        (0, 1, 0)
    );
    close(net, running).await;
}

#[tokio::test(start_paused = true)]
async fn select_inquire_configure_and_switch_back_boots_the_board() {
    for door in BOTH {
        select_inquire_configure_and_switch_back(door).await;
    }
}

async fn select_inquire_configure_and_switch_back(door: Door) {
    let (net, boards) = open(door).await;
    let lss = net.lss();
    let board = sim_lss_address(SIM_LSS_SERIALS[1]);
    // In waiting mode the board ignores inquire.
    assert_eq!(
        lss.inquire(Inquiry::NodeId).await,
        Err(NetError::Lss(duocan::cia305::LssError::Timeout(
            duocan::cia305::LssService::Inquire(Inquiry::NodeId)
        )))
    );
    lss.switch_selective(board).await.unwrap();
    assert_eq!(lss.inquire(Inquiry::Vendor).await.unwrap(), SIM_VENDOR);
    assert_eq!(lss.inquire(Inquiry::Serial).await.unwrap(), board.serial);
    assert_eq!(lss.inquire(Inquiry::NodeId).await.unwrap(), 0xFF);
    assert_eq!(
        lss.configure_node_id(0).await,
        Err(NetError::Lss(duocan::cia305::LssError::InvalidNodeId(0)))
    );
    lss.configure_node_id(0x33).await.unwrap();
    let since = net.now();
    lss.switch_global(LssMode::Waiting).await.unwrap();
    let node = net.node(0x33);
    node.wait_for_boot_up_since(since, Duration::from_secs(1))
        .await
        .unwrap();
    assert_eq!(
        node.sdo().read::<u32>(0x1018, 4).await.unwrap(),
        board.serial
    );
    // The other board is still without a node-ID.
    assert!(lss.identify_non_configured().await.unwrap());
    close(net, boards).await;
}

#[tokio::test(start_paused = true)]
async fn a_listen_only_network_sends_no_lss() {
    let net = open_dual_named("sim-station", NetOptions::default().with_listen_only(true)).unwrap();
    assert_eq!(
        net.lss().switch_global(LssMode::Configuration).await,
        Err(NetError::ListenOnly { node: None })
    );
    assert_eq!(
        net.lss().fastscan(LssPlan::new()).await,
        Err(NetError::ListenOnly { node: None })
    );
    net.close().await;
}

#[tokio::test(start_paused = true)]
async fn a_standby_master_sends_no_lss_and_says_why() {
    let buses = [MemBus::new("bus1"), MemBus::new("bus2")];
    let (active, standby) = crate::redundant::two_masters(&buses).await;
    let mut spy = buses[1].port();
    assert_eq!(
        standby.lss().switch_global(LssMode::Configuration).await,
        Err(NetError::Standby { node: None })
    );
    assert_eq!(
        standby.lss().fastscan(LssPlan::new()).await,
        Err(NetError::Standby { node: None })
    );
    assert!(
        crate::redundant::seen_on(&mut spy, 0x7E5).await.is_empty(),
        "nothing sent"
    );
    // The active master's door sends it.
    active.lss().switch_global(LssMode::Waiting).await.unwrap();
    assert_eq!(crate::redundant::seen_on(&mut spy, 0x7E5).await.len(), 1);
    active.close().await;
    standby.close().await;
}
