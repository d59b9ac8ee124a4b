//! The two doors a test runs over, on the same two in-memory buses: duocan's plain door over
//! the dual link, and the redundant master's door. What a door does is written once above its
//! core, so the same test body must pass on both.

use duocan::machine::Device;
use duocan::net::{NetOptions, Network};
use duocan::port::mem::MemBus;
use duocan::runtime::{Handle, Runtime};
use duocan::Station;
use duocan_redundancy::net::{open_dual, RedundantNetwork};
use duocan_redundancy::supervisor::flying_master::MasterRole;
use duocan_redundancy::{DualBus, DualBusConfig};
use std::time::Duration;

/// Which door a test runs on.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Door {
    /// duocan's plain door (an observer and an SDO client, no master) over the dual link.
    Plain,
    /// The redundant master's door: master 7, alone on the buses, so active.
    Redundant,
}

/// Both doors, for a test's loop.
pub(crate) const BOTH: [Door; 2] = [Door::Plain, Door::Redundant];

/// The network on `door`, on both buses; the redundant one once it is active (after the
/// power-on negotiation, 2 s on the paused clock).
pub(crate) async fn open(door: Door, buses: &[MemBus; 2]) -> Network {
    match door {
        Door::Plain => {
            let opts = NetOptions::default().with_sdo_timeout(Duration::from_millis(200));
            open_dual(buses[0].port(), buses[1].port(), opts).unwrap()
        }
        Door::Redundant => {
            let net = RedundantNetwork::builder()
                .node_id(7)
                .heartbeat(duocan::Duration::from_millis(20))
                .master_timeout(duocan::Duration::from_millis(50))
                .open(buses[0].port(), buses[1].port())
                .unwrap();
            tokio::time::sleep(Duration::from_secs(2)).await;
            assert_eq!(net.role().await.unwrap(), MasterRole::Active);
            // The door itself: the network runs while a clone of it lives.
            (*net).clone()
        }
    }
}

/// `machine` (a node, a board) on both buses through its own dual-bus layer.
pub(crate) fn on_both<M: duocan::Machine>(
    machine: M,
    buses: &[MemBus; 2],
) -> Handle<Station<DualBus, M>>
where
    Station<DualBus, M>: Device + Send + 'static,
    <Station<DualBus, M> as Device>::Event: Clone + Send + std::fmt::Debug + 'static,
{
    Runtime::new(Station::new(
        DualBus::new(DualBusConfig::default()),
        machine,
    ))
    .port(buses[0].port())
    .port(buses[1].port())
    .spawn()
    .unwrap()
}
