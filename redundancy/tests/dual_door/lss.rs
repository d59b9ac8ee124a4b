//! LSS (CiA 305) through the front door (`Network::lss`) on the simulated station's two buses:
//! its two boards without a node-ID found by fastscan, configured, booted and answering on
//! both buses; the single services; a listen-only network sends nothing.

use duocan::cia305::{fastscan_cost, Inquiry, LssMasterConfig, LssMode, LssPlan};
use duocan::net::{NetError, NetOptions, SIM_VENDOR};
use duocan::NodeId;
use duocan_redundancy::net::{open_dual_named, sim_lss_address, SIM_LSS_PRODUCT, SIM_LSS_SERIALS};
use std::time::Duration;

#[tokio::test(start_paused = true)]
async fn fastscan_configures_both_boards_and_they_boot_on_both_buses() {
    let net = open_dual_named("sim", NetOptions::default()).unwrap();
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
        "fastscan of 2 boards on the simulated dual bus: {} requests, {} answers, {:?} (the protocol: {} requests, {} answers, {:?} of waiting)",
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
            Some([true, true]),
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
    net.close().await;
}

#[tokio::test(start_paused = true)]
async fn select_inquire_configure_and_switch_back_boots_the_board() {
    let net = open_dual_named("sim", NetOptions::default()).unwrap();
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
    net.close().await;
}

#[tokio::test(start_paused = true)]
async fn a_listen_only_network_sends_no_lss() {
    let net = open_dual_named("sim", NetOptions::default().with_listen_only(true)).unwrap();
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
