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

#[test]
fn a_node_on_a_borrowed_dictionary_carries_a_pointer_and_writes_through_it() {
    use duocan::od::ObjectDictionary;
    use duocan::Instant;
    let mut od = SlaveOd::new();
    od.load(5, &[&COMM, &IDENT, &HB, &HIST])
        .expect("tables fit");
    let owning: Slave = Node::with_profile(
        NodeConfig::slave(NodeId::must(5)),
        SlaveOd::new(),
        Predefined,
    );
    {
        let mut node: Node<&mut SlaveOd, Predefined, 0> =
            Node::with_profile(NodeConfig::slave(NodeId::must(5)), &mut od, Predefined);
        // The dictionary's kilobytes stay where they are.
        let saved = std::mem::size_of_val(&owning) - std::mem::size_of_val(&node);
        assert_eq!(
            saved + std::mem::size_of::<usize>(),
            std::mem::size_of::<SlaveOd>()
        );
        node.boot(Instant::ZERO);
        node.set(Instant::ZERO, comm::HEARTBEAT_PRODUCER, 0, 250u16)
            .expect("the node writes its producer time");
        assert_eq!(
            node.od().get_value::<u16>(comm::HEARTBEAT_PRODUCER, 0),
            Ok(250)
        );
        // Checks and hooks are the dictionary's own: a const entry stays read-only.
        assert!(node
            .od_mut()
            .write_local(comm::IDENTITY, 1, &[9, 0, 0, 0])
            .is_err());
    }
    assert_eq!(od.get_value::<u16>(comm::HEARTBEAT_PRODUCER, 0), Ok(250));
}
