//! Program download through a remote node (`download_program`): an image larger than one
//! whole transfer of the network streams to the node's store and runs; a store that refuses
//! it leaves the node on its program.

use crate::door_checks::{store, STORE};
use duocan::cia302::program::ProgramDictionary;
use duocan::net::{NetOptions, Network};
use duocan::port::mem::MemBus;
use duocan::runtime::Runtime;
use duocan::sdo::SdoServerConfig;
use duocan::{Node, NodeConfig, NodeId};
use std::time::Duration;

#[tokio::test(start_paused = true)]
async fn an_image_streams_to_the_node_and_runs_and_a_refused_one_leaves_it_as_it_was() {
    let bus = MemBus::new("mem");
    let opts = NetOptions::default().with_sdo_timeout(Duration::from_millis(300));
    let net = Network::open_with(bus.port(), opts).unwrap();
    let base = duocan::od::comm::standard_dictionary(4, Default::default());
    let od = ProgramDictionary::new(base, store());
    let mut n = Node::new(NodeConfig::slave(NodeId::must(4)), od);
    n.sdo_server_mut()
        .set_config(SdoServerConfig::default().with_max_transfer(STORE));
    n.boot(duocan::Instant::ZERO);
    let s = Runtime::new(duocan::Station::single(n))
        .port(bus.port())
        .spawn()
        .unwrap();

    crate::door_checks::program_download(&net, 4).await;
    net.close().await;
    s.shutdown().await;
}
