//! Static RAM of a no_std slave: a node with a static dictionary holding the communication
//! objects (127-entry heartbeat consumer table included). Budget: 16 KiB.

use duocan::od::{comm, ObjectDef, StaticDictionary};
use duocan::profile::Predefined;
use duocan::{Node, NodeConfig, NodeId};

static COMM: [ObjectDef; comm::COMM_LEN] = comm::communication();
static IDENT: [ObjectDef; 6] = comm::identity(0x191, 1, 2, 3, 4);
static HB: [ObjectDef; 128] = comm::heartbeat_consumers::<128>();
static HIST: [ObjectDef; 9] = comm::error_history::<9>();

/// The dictionary of a small slave: room for the tables above plus a few application entries.
pub type SlaveOd = StaticDictionary<256, 1024>;
/// A slave guards nobody.
pub type Slave = Node<SlaveOd, Predefined, 0>;

#[test]
fn no_std_slave_fits_in_16_kib() {
    let mut od = SlaveOd::new();
    od.load(5, &[&COMM, &IDENT, &HB, &HIST])
        .expect("tables fit");
    let node: Slave = Node::with_profile(NodeConfig::slave(NodeId::must(5)), od, Predefined);
    let total = std::mem::size_of_val(&node);
    println!("no_std slave node incl. dictionary: {total} bytes of static RAM");
    assert!(total <= 16 * 1024, "{total} bytes > 16 KiB");
}
