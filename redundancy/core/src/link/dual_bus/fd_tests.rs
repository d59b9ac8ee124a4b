//! A node serving USDO (CiA 1301) in a station on the layer: every CAN FD request reaches it
//! once though both buses carry it, every answer leaves on both, and a transfer completes
//! when one bus is cut in its middle.

use super::*;
use duocan_core::cia1301::usdo::UsdoClient;
use duocan_core::cia301::sdo::TransferBuffer;
use duocan_core::machine::Device;
use duocan_core::nmt::{command_frame, NmtCommand, NmtTarget};
use duocan_core::od::{comm, DataType, DynamicDictionary, ObjectDef};
use duocan_core::{Id, Node, NodeConfig, NodeId, Station};
use std::vec::Vec;

const SERVER: NodeId = NodeId::must(5);
const DOMAIN: u16 = 0x2001;
const T: Duration = Duration::from_millis(100);

type FdNode = Station<DualBus, Node<DynamicDictionary>>;

/// Node 5 serving USDO on a layer whose two ports are FD, booted and started.
fn node() -> FdNode {
    let mut od = comm::standard_dictionary(SERVER.raw(), Default::default());
    od.insert_all(&[ObjectDef::bytes(DOMAIN, 0, DataType::Domain, 1024)])
        .unwrap();
    let mut link = DualBus::new(DualBusConfig::default());
    link.set_port_fd(0, true);
    link.set_port_fd(1, true);
    let mut dev = Station::new(link, Node::new(NodeConfig::slave(SERVER).with_fd(true), od));
    dev.machine.boot(Instant::ZERO);
    let start = command_frame(Id::Standard(0), NmtCommand::Start, NmtTarget::All);
    dev.handle_rx(Instant::ZERO, 0, &start);
    dev.handle_rx(Instant::ZERO, 1, &start);
    while dev.poll_transmit().is_some() {}
    dev
}

/// A client and the node one millisecond apart per step, each request on both buses (bus 2's
/// copy 100 µs later) unless bus 1 is cut from step `cut_at` on. Returns the client's result
/// and the node's answers per port.
fn run(
    dev: &mut FdNode,
    client: &mut UsdoClient,
    cut_at: usize,
) -> (Result<Vec<u8>, ()>, [Vec<FdFrame>; 2]) {
    let mut answers: [Vec<FdFrame>; 2] = Default::default();
    let mut now = Instant::from_millis(1);
    for step in 0..1000 {
        if let Some(e) = client.poll_event() {
            let r = e.result.map(|b| b.as_slice().to_vec()).map_err(drop);
            return (r, answers);
        }
        now += Duration::from_millis(1);
        let cut = step >= cut_at;
        while let Some(f) = client.poll_transmit() {
            if !cut {
                dev.handle_rx_fd(now, 0, &f, now);
            }
            let later = now + Duration::from_micros(100);
            dev.handle_rx_fd(later, 1, &f, later);
        }
        while let Some((port, f)) = dev.poll_transmit_fd() {
            answers[port].push(f);
            // The client hears bus 2 (bus 1 may be cut).
            if port == 1 {
                client.handle_frame(now, &f);
            }
        }
        while dev.poll_transmit().is_some() {}
        if dev.poll_timeout().is_some_and(|t| t <= now) {
            dev.handle_timeout(now);
        }
        if client.poll_timeout().is_some_and(|t| t <= now) {
            client.handle_timeout(now);
        }
    }
    panic!("no result");
}

#[test]
fn a_node_on_two_fd_buses_serves_each_usdo_request_once_and_answers_on_both() {
    let mut dev = node();
    assert!(dev.fd_capable());
    let mut client = UsdoClient::new(NodeId::must(1), 4096);
    let data: Vec<u8> = (0..700u32).map(|i| i as u8).collect();
    client
        .download(Instant::from_millis(1), SERVER, DOMAIN, 0, 0, &data, T)
        .unwrap();
    let (r, answers) = run(&mut dev, &mut client, usize::MAX);
    assert_eq!(r, Ok(Vec::new()));
    assert!(!answers[0].is_empty());
    assert_eq!(answers[0], answers[1], "every answer on both buses");
    client
        .upload(Instant::from_millis(1), SERVER, DOMAIN, 0, T)
        .unwrap();
    let (r, answers) = run(&mut dev, &mut client, usize::MAX);
    assert_eq!(r, Ok(data));
    assert_eq!(answers[0], answers[1]);
    let u = dev.machine.usdo_server().unwrap().stats();
    // No second copy reached the server (it would ignore a repeated segment request).
    assert_eq!((u.completed, u.aborted, u.busy, u.repeats), (2, 0, 0, 0));
    assert_eq!(dev.link.stats().fd_refused, 0);
}

#[test]
fn a_usdo_transfer_completes_with_bus_1_cut_in_its_middle() {
    let mut dev = node();
    let mut client = UsdoClient::new(NodeId::must(1), 4096);
    let data: Vec<u8> = (0..700u32).map(|i| (i * 7) as u8).collect();
    client
        .download(Instant::from_millis(1), SERVER, DOMAIN, 0, 0, &data, T)
        .unwrap();
    // A 700-byte download takes more than three steps: bus 1 is cut after the third.
    let (r, _) = run(&mut dev, &mut client, 3);
    assert_eq!(r, Ok(Vec::new()));
    assert_eq!(dev.machine.od().get(DOMAIN, 0).unwrap().data, data);
    let u = dev.machine.usdo_server().unwrap().stats();
    assert_eq!((u.completed, u.aborted, u.busy, u.repeats), (1, 0, 0, 0));
}

#[test]
fn a_layer_with_a_classic_port_drops_the_machines_fd_frames_counted() {
    let mut link: DualBus = DualBus::new(DualBusConfig::default());
    link.set_port_fd(0, true);
    let f = FdFrame::new(Id::Standard(0x585), &[0; 12]).unwrap();
    BusLink::send_fd(&mut link, Instant::from_millis(1), &f);
    assert!(!BusLink::fd_capable(&link));
    assert_eq!(BusLink::poll_transmit_fd(&mut link), None);
    assert_eq!(link.stats().fd_refused, 1);
}
