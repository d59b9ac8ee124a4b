//! A board with LSS and a node (`duocan::node::LssNode`): silent but for LSS until it has a
//! node-ID, then booting with the node-ID the master gave it, and rebuilt for a new one at
//! reset-communication.

use super::wire::addr;
use duocan::cia305::{LssMaster, LssMasterConfig, LssMode, LssPlan, LssSlave};
use duocan::frame::instant::earliest;
use duocan::node::{LssNode, LssNodeEvent};
use duocan::od::comm;
use duocan::{Duration, Frame, Id, Instant, Machine, Node, NodeConfig, NodeId};

/// Runs two machines against each other until `until`; returns every frame with its sender
/// (0 or 1) and time in ms.
fn run(
    a: &mut impl Machine,
    b: &mut impl Machine,
    from: Instant,
    until: Instant,
) -> Vec<(u64, u8, Frame)> {
    let mut log = Vec::new();
    let mut now = from;
    loop {
        loop {
            let mut moved = false;
            while let Some(f) = a.poll_transmit() {
                log.push((now.as_micros() / 1000, 0, f));
                b.handle_frame(now, &f);
                moved = true;
            }
            while let Some(f) = b.poll_transmit() {
                log.push((now.as_micros() / 1000, 1, f));
                a.handle_frame(now, &f);
                moved = true;
            }
            if !moved {
                break;
            }
        }
        match earliest(a.poll_timeout(), b.poll_timeout()) {
            Some(t) if t <= until => {
                now = now.max(t);
                a.handle_timeout(now);
                b.handle_timeout(now);
            }
            _ => return log,
        }
    }
}

fn board(
    node: u8,
) -> LssNode<
    Node<duocan::od::DynamicDictionary>,
    impl FnMut(NodeId, Instant) -> Node<duocan::od::DynamicDictionary>,
    duocan::cia305::NoMedium,
> {
    let address = addr(0x2A, 7, 1, 0x1234);
    LssNode::new(
        Instant::ZERO,
        LssSlave::new(address, node),
        move |id: NodeId, now| {
            let ident = comm::Identity {
                vendor: 0x2A,
                product: 7,
                revision: 1,
                serial: 0x1234,
                ..Default::default()
            };
            let mut n = Node::new(
                NodeConfig::slave(id),
                comm::standard_dictionary(id.raw(), ident),
            );
            n.set(now, comm::HEARTBEAT_PRODUCER, 0, 100u16).unwrap();
            n.boot(now);
            n
        },
    )
}

#[test]
fn a_board_without_node_id_is_silent_until_fastscan_gives_it_one_then_boots() {
    let mut dev = board(0xFF);
    assert!(dev.node().is_none());
    let mut master: LssMaster =
        LssMaster::new(LssMasterConfig::default().with_timeout(Duration::from_millis(10)));
    // A second of nothing: no boot-up, no heartbeat.
    assert!(run(&mut master, &mut dev, Instant::ZERO, Instant::from_secs(1)).is_empty());
    let t0 = Instant::from_secs(1);
    master
        .fastscan(t0, LssPlan::new().with_free([NodeId::must(7)]))
        .unwrap();
    let log = run(&mut master, &mut dev, t0, Instant::from_secs(4));
    // Until the switch back to waiting only LSS frames; right after it, the boot-up of node 7.
    let switch = log
        .iter()
        .position(|(_, _, f)| f.id().raw() == 0x7E5 && f.data()[..2] == [0x04, 0])
        .unwrap();
    assert!(log[..switch]
        .iter()
        .all(|(_, _, f)| matches!(f.id().raw(), 0x7E4 | 0x7E5)));
    let (t_switch, _, _) = log[switch];
    let first_node_frame = log
        .iter()
        .find(|(_, who, f)| *who == 1 && f.id().raw() != 0x7E4)
        .unwrap();
    assert_eq!(
        *first_node_frame,
        (t_switch, 1, Frame::from_array(Id::Standard(0x707), [0x00]))
    );
    // Heartbeats every 100 ms from there, pre-operational.
    let beats: Vec<u64> = log
        .iter()
        .filter(|(_, _, f)| f.id().raw() == 0x707 && f.data() == [0x7F])
        .map(|(t, _, _)| *t)
        .collect();
    assert_eq!(beats[..3], [t_switch + 100, t_switch + 200, t_switch + 300]);
    assert_eq!(dev.node().unwrap().id(), NodeId::must(7));
    let lss_events: Vec<_> = std::iter::from_fn(|| dev.poll_event())
        .filter_map(|e| match e {
            LssNodeEvent::Lss(e) => Some(e.kind),
            LssNodeEvent::Node(_) => None,
        })
        .collect();
    assert!(
        lss_events.contains(&duocan::cia305::LssSlaveEventKind::ResetCommunication(
            NodeId::must(7)
        ))
    );
}

#[test]
fn a_configured_board_given_a_new_node_id_changes_at_reset_communication() {
    let mut dev = board(7);
    let mut master: LssMaster = LssMaster::default();
    let t = Instant::ZERO;
    let boot = run(&mut master, &mut dev, t, t);
    assert_eq!(boot[0].2, Frame::from_array(Id::Standard(0x707), [0x00]));
    master.switch_global(t, LssMode::Configuration).unwrap();
    run(&mut master, &mut dev, t, t);
    master.configure_node_id(t, 9).unwrap();
    run(&mut master, &mut dev, t, t);
    master.switch_global(t, LssMode::Waiting).unwrap();
    run(&mut master, &mut dev, t, t);
    // Still node 7 until the reset.
    assert_eq!(dev.node().unwrap().id(), NodeId::must(7));
    let t1 = Instant::from_millis(50);
    dev.handle_frame(t1, &Frame::from_array(Id::Standard(0), [0x82, 7]));
    let log = run(&mut master, &mut dev, t1, t1);
    assert_eq!(dev.node().unwrap().id(), NodeId::must(9));
    assert!(
        log.iter()
            .any(|(_, _, f)| *f == Frame::from_array(Id::Standard(0x709), [0x00])),
        "{log:?}"
    );
    // The node-ID made 0xFF and a reset: LSS only again, nothing more from the board.
    master.switch_global(t1, LssMode::Configuration).unwrap();
    run(&mut master, &mut dev, t1, t1);
    master.configure_node_id(t1, 0xFF).unwrap();
    run(&mut master, &mut dev, t1, t1);
    dev.handle_frame(t1, &Frame::from_array(Id::Standard(0), [0x81, 0]));
    assert!(dev.node().is_none());
    let quiet = run(&mut master, &mut dev, t1, Instant::from_secs(2));
    assert!(quiet.is_empty(), "{quiet:?}");
}
