//! Program download (CiA 302-3) and by-name SDO through both doors, to a node on both buses
//! that takes program download and carries duocan's simulated dictionary: the checks duocan's
//! own tests run on one port (`tests/net/door_checks.rs`), unchanged.

use crate::door_checks::{names_resolve, program_download, store, STORE};
use crate::doors::{on_both, open, BOTH};
use duocan::cia302::program::{ProgramDictionary, RamStore};
use duocan::net::sim_dictionary;
use duocan::od::DynamicDictionary;
use duocan::port::mem::MemBus;
use duocan::runtime::Handle;
use duocan::sdo::SdoServerConfig;
use duocan::{Instant, Node, NodeConfig, NodeId, Station};
use duocan_redundancy::DualBus;

type ProgramNode = Station<DualBus, Node<ProgramDictionary<DynamicDictionary, RamStore>>>;

/// Node 5 on both buses: the simulated dictionary with program download, taking transfers as
/// large as its store.
fn program_node(buses: &[MemBus; 2]) -> Handle<ProgramNode> {
    let id = NodeId::must(5);
    let od = ProgramDictionary::new(sim_dictionary(id), store());
    let mut n = Node::new(NodeConfig::slave(id), od);
    n.sdo_server_mut()
        .set_config(SdoServerConfig::default().with_max_transfer(STORE));
    n.boot(Instant::ZERO);
    on_both(n, buses)
}

#[tokio::test(start_paused = true)]
async fn program_download_and_names_through_both_doors() {
    for door in BOTH {
        let buses = [MemBus::new("bus1"), MemBus::new("bus2")];
        let net = open(door, &buses).await;
        let node = program_node(&buses);
        program_download(&net, 5).await;
        names_resolve(&net).await;
        net.close().await;
        node.shutdown().await;
    }
}
