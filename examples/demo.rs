//! The demo: a master and two slaves with heartbeat on a simulated 500 kbit/s bus; one slave is
//! killed and the master reports the timeout at exactly its last heartbeat + consumer time.
//!
//! `cargo run --release --example demo`

use duocan::machine::StationEvent;
use duocan::node::NodeEventKind;
use duocan::od::comm;
use duocan::sim::{BusConfig, SimNetwork};
use duocan::{Duration, Instant, NmtCommand, NmtTarget, Node, NodeConfig, NodeId, Station};

fn main() {
    let mut sim = SimNetwork::new(2026);
    let bus = sim.add_bus(BusConfig::new("can0", 500_000));

    let node = |id: u8, master: bool| {
        let nid = NodeId::new(id).expect("node-ID in 1..=127");
        let od = comm::standard_dictionary(
            id,
            comm::Identity {
                vendor: 0xD0CA,
                product: id as u32,
                ..Default::default()
            },
        );
        let cfg = if master {
            NodeConfig::master(nid)
        } else {
            NodeConfig::slave(nid)
        };
        Station::single(Node::new(cfg, od))
    };
    let master = sim
        .add_device("master", node(1, true), &[bus])
        .expect("one port");
    let slaves = [2u8, 3].map(|id| {
        sim.add_device(format!("slave {id}"), node(id, false), &[bus])
            .expect("one port")
    });

    // Configure: slaves beat every 100 ms, the master watches each with a 250 ms consumer time.
    let t0 = sim.now();
    for (i, s) in slaves.iter().enumerate() {
        let n = &mut sim.device_mut(*s).machine;
        n.boot(t0);
        n.set(t0, comm::HEARTBEAT_PRODUCER, 0, 100u16)
            .expect("0x1017 is writable");
        let m = &mut sim.device_mut(master).machine;
        let id = (i + 2) as u32;
        m.set(
            t0,
            comm::HEARTBEAT_CONSUMER,
            (i + 1) as u8,
            (id << 16) | 250,
        )
        .expect("0x1016 entry");
    }
    sim.device_mut(master).machine.boot(t0);
    sim.device_mut(master)
        .machine
        .nmt_command(t0, NmtCommand::Start, NmtTarget::All)
        .expect("queue has room");

    sim.run_until(Instant::from_millis(2_030));
    println!("{}  slave 3 loses power", sim.now());
    sim.power_off(slaves[1].erased());
    sim.run_until(Instant::from_secs(3));

    println!("\nmaster's view, in simulated time:");
    let mut timeout = None;
    for (at, ev) in sim.events(master) {
        let StationEvent::Machine(ev) = ev else {
            continue;
        };
        match ev.kind {
            NodeEventKind::BootUp { node } => println!("{at}  {node} booted"),
            NodeEventKind::RemoteState { node, to, .. } => println!("{at}  {node} is {to}"),
            NodeEventKind::HeartbeatTimeout { node, last } => {
                println!(
                    "{at}  HEARTBEAT TIMEOUT of {node}: last heard {last}, {} later",
                    ev.at - last
                );
                timeout = Some((ev.at, last));
            }
            _ => {}
        }
    }
    let (at, last) = timeout.expect("the master must report slave 3's heartbeat timeout");
    assert_eq!(
        at - last,
        Duration::from_millis(250),
        "timeout fires at last heartbeat + consumer time"
    );
    println!(
        "\nframes on can0: {}, bus load {:.1} %",
        sim.bus_stats(bus).delivered,
        100.0 * sim.bus_load(bus)
    );
}
