//! The redundant network's front door on a CANopen FD network (`with_fd`): the simulated
//! station (`open_named("sim-pairs")`) with every board and the peer master speaking CAN FD on
//! both buses and serving USDO. The door's typed reads and writes go over USDO through the
//! redundant master's dual-bus layer (a door opened with `with_fd` reads and writes over USDO
//! only, so each success below is a USDO transfer), to the running board of a pair and to the
//! peer master's own dictionary (through its supervisor and CiA 302-2 master), and they go on
//! through the scripted bus cut and pair failover. Guarding, which CAN FD cannot carry, is
//! refused when the network is built.

use duocan::master::{Assignment, MasterConfig, SlaveConfig};
use duocan::net::{NetError, SIM_VENDOR};
use duocan::{Duration, Instant, NodeId};
use duocan_redundancy::net::{RedundantNetwork, SIM_BUS_FAILS, SIM_B_BOOTS, SIM_MEMBER_FAILS};
use duocan_redundancy::supervisor::fd_guarding::{GuardingOnFd, GuardingSource};
use duocan_redundancy::supervisor::flying_master::MasterRole;
use duocan_redundancy::{RedundantError, Role};

/// The door's USDO client: a node-ID no device of the network has.
const CLIENT: u8 = 0x7F;
const PAIR_HB: u64 = 25;
const PAIR_TIMEOUT: u64 = 80;

fn ms(n: u64) -> Duration {
    Duration::from_millis(n)
}

fn builder() -> duocan_redundancy::RedundantNetworkBuilder {
    RedundantNetwork::builder()
        .node_id(1)
        .heartbeat(ms(20))
        .master_timeout(ms(50))
        .pair(0x10, 0x50)
        .pair_heartbeat(ms(PAIR_HB))
        .pair_timeout(ms(PAIR_TIMEOUT))
        .peer_master(2)
        .with_fd(CLIENT)
}

/// One write of `value` to the running board's Output 1 (0x6200 sub 1) and its read-back,
/// with its identity: the board's node-ID, or the door's error.
async fn round_trip(net: &RedundantNetwork, value: u16) -> Result<u8, NetError> {
    let board = net
        .running_board(0x10, std::time::Duration::from_secs(1))
        .await
        .map_err(|e| match e {
            RedundantError::Net(e) => e,
            e => panic!("{e}"),
        })?;
    let sdo = net.node(board).sdo();
    // The product code of a simulated board is its node-ID.
    assert_eq!(sdo.read::<u32>(0x1018, 2).await?, u32::from(board));
    sdo.write(0x6200, 1, value).await?;
    assert_eq!(sdo.read::<u16>(0x6200, 1).await?, value);
    Ok(board)
}

#[tokio::test(start_paused = true)]
async fn usdo_to_the_running_board_goes_on_through_a_bus_cut_and_a_pair_failover() {
    let net = builder().open_named("sim-pairs").unwrap();
    // Until B is on the buses, A alone runs.
    tokio::time::sleep(std::time::Duration::from_micros(
        SIM_B_BOOTS.as_micros() + 200_000,
    ))
    .await;
    assert_eq!(net.role().await.unwrap(), MasterRole::Active);
    let a = net.node(0x10).sdo();
    assert_eq!(a.read::<u32>(0x1018, 1).await.unwrap(), SIM_VENDOR);
    // The standby member answers as any node.
    let b = net.node(0x50).sdo();
    assert_eq!(b.read::<u32>(0x1018, 2).await.unwrap(), 0x50);
    // The peer master's own dictionary, over USDO through its supervisor and master: its
    // heartbeat producer time is the builder's.
    let peer = net.node(2).sdo();
    assert_eq!(peer.read::<u16>(0x1017, 0).await.unwrap(), 20);

    // A write and read-back on the running board every 50 ms until after the failover.
    // (A transfer to A as it stops waits for the door's timeout, 1 s.)
    let end = Instant::ZERO + SIM_MEMBER_FAILS + ms(1600);
    let (mut runs, mut failed) = (vec![], vec![]);
    let mut value = 0u16;
    while net.now() < end {
        value += 1;
        let at = net.now();
        match round_trip(&net, value).await {
            Ok(board) => runs.push((at, board)),
            Err(e) => failed.push((at, e)),
        }
        tokio::time::sleep(std::time::Duration::from_millis(50)).await;
    }
    // Board A ran until it stopped, through the cut of bus 1; B after the failover.
    let cut = Instant::ZERO + SIM_BUS_FAILS;
    let stopped = Instant::ZERO + SIM_MEMBER_FAILS;
    assert!(
        runs.iter().any(|&(t, b)| b == 0x10 && t > cut + ms(100)),
        "{runs:?}"
    );
    assert!(
        runs.iter().all(|&(t, b)| b == 0x10 || t >= stopped),
        "{runs:?}"
    );
    assert!(
        runs.iter().any(|&(t, b)| b == 0x50 && t > stopped),
        "{runs:?} {failed:?}"
    );
    // Only a transfer to A while it was dead (before B took over) may fail.
    let switched = stopped + ms(PAIR_HB + PAIR_TIMEOUT);
    for (t, e) in &failed {
        assert!(
            *t >= stopped - ms(50) && *t <= switched,
            "failed at {t}, not while A was dead and still active: {e}"
        );
    }
    let status = net.status().await.unwrap();
    assert!(status.contains("failed"), "bus 1 is cut: {status}");
    net.close().await;
}

#[tokio::test(start_paused = true)]
async fn guarding_on_an_fd_network_is_refused_naming_the_node() {
    // The master guarding a plain slave (0x1F81 guard time).
    let guarded =
        SlaveConfig::new(NodeId::must(0x20)).with_assignment(Assignment::slave().guarded(100, 3));
    let mut master = MasterConfig::new();
    master.slaves.push(guarded.clone());
    let e = builder().master(master.clone()).build().unwrap_err();
    assert_eq!(
        e,
        RedundantError::GuardingOnFd(GuardingOnFd {
            node: NodeId::must(0x20),
            source: GuardingSource::MasterGuards { guard_time_ms: 100 },
        })
    );
    assert_eq!(e.node(), Some(NodeId::must(0x20)));
    let text = e.to_string();
    assert!(
        text.contains("node 0x20")
            && text.contains("no remote frames")
            && text.contains("heartbeats"),
        "{text}"
    );
    // On a classic network the same settings build.
    let classic = RedundantNetwork::builder()
        .node_id(1)
        .pair(0x10, 0x50)
        .master(master);
    assert!(classic.build().is_ok());
    // A pair member whose configuration sets its life guarding (0x100D).
    let member = SlaveConfig::new(NodeId::must(0x50)).write_u8(0x100D, 0, 3);
    let e = builder().member_config(member).build().unwrap_err();
    assert_eq!(
        e,
        RedundantError::GuardingOnFd(GuardingOnFd {
            node: NodeId::must(0x50),
            source: GuardingSource::SlaveConfig { index: 0x100D },
        })
    );
    // Opening is building: refused before anything runs.
    let e = builder()
        .member_config(SlaveConfig::new(NodeId::must(0x10)).write_u16(0x100C, 0, 100))
        .open_named("sim-pairs")
        .err()
        .expect("refused");
    assert!(
        matches!(e, RedundantError::GuardingOnFd(g) if g.node.raw() == 0x10),
        "{e}"
    );
    // A zero guard time is no guarding.
    let off = SlaveConfig::new(NodeId::must(0x10)).write_u16(0x100C, 0, 0);
    assert!(builder().member_config(off).build().is_ok());
    // The USDO client's node-ID is a node-ID of its own.
    let e = builder().pair(0x11, CLIENT).build().unwrap_err();
    assert!(
        matches!(
            e,
            RedundantError::NodeTwice {
                first: Role::PairMember,
                second: Role::UsdoClient,
                ..
            }
        ),
        "{e}"
    );
}
