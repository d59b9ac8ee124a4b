//! The redundant network's front door on the simulated station (`open_named("sim")`), on
//! tokio's paused clock: the builder's settings reach the running machines, SDO goes through
//! the handle to a pair member, and the scripted faults give one failover of each kind.

use duocan::{Duration, Instant};
use duocan_redundancy::net::{
    RedundantEvent, RedundantNetwork, SIM_BUS_FAILS, SIM_MEMBER_FAILS, SIM_PEERS_FAIL,
};
use duocan_redundancy::supervisor::flying_master::MasterRole;
use duocan_redundancy::{Member, NetworkError, RedundantError};

const ms: fn(u64) -> Duration = Duration::from_millis;

/// Every event until the simulation ends.
async fn all_events(net: &RedundantNetwork) -> Vec<RedundantEvent> {
    let mut events = net.events();
    let mut out = vec![];
    while let Some(e) = events.next().await {
        out.push(e);
    }
    out
}

#[tokio::test(start_paused = true)]
async fn the_simulated_station_plays_one_failover_of_each_kind() {
    let net = RedundantNetwork::builder()
        .node_id(2)
        .heartbeat(ms(20))
        .master_timeout(ms(50))
        .sync(ms(10))
        .pair(0x10, 0x50)
        .pair_heartbeat(ms(25))
        .pair_timeout(ms(80))
        .peer_master(1)
        .open_named("sim")
        .unwrap();
    let events = all_events(&net).await;
    let failovers: Vec<String> = events
        .iter()
        .filter(|e| e.is_failover())
        .map(ToString::to_string)
        .collect();
    assert_eq!(
        failovers,
        ["bus 1: failed", "this master: active", "pair 0x10/0x50: B active"],
        "{events:#?}"
    );
    for e in &events {
        println!("{:?} {e}", e.at());
    }
}
#[test]
fn size() {
    println!("SIZE {}", std::mem::size_of::<duocan_redundancy::LogicalNetwork<duocan::od::DynamicDictionary>>());
}
