//! CAN FD frames through the dual-bus layer on two simulated FD buses: a frame sent once
//! arrives once at the other end, with one bus cut it still arrives, port health counts FD
//! traffic as classic traffic, and a link with a classic-only port refuses to send FD; a
//! redundant master on FD buses sends and receives FD frames through its layer, and its
//! supervisor passes them to its CiA 302-2 master, whose node serves USDO.

use super::fd_end::FdEnd;
use duocan::cia1301::usdo::UsdoClient;
use duocan::frame::FdFrame;
use duocan::machine::BusLink;
use duocan::master::{objects, Master, MasterConfig, MasterSdoClient};
use duocan::od::comm;
use duocan::profile::Predefined;
use duocan::sdo::DEFAULT_LIMIT;
use duocan::sim::{BusConfig, BusId, DevId, SimError, SimNetwork};
use duocan::{Frame, Id, Instant, NodeConfig, NodeId};
use duocan_redundancy::link::dual_bus::FdSendError;
use duocan_redundancy::{
    DualBus, DualBusConfig, PortState, RedundantMaster, Supervisor, SupervisorConfig,
};

/// Two FD buses (500 kbit/s nominal, 2 Mbit/s data) with a sender and a receiver on both.
fn rig() -> (SimNetwork, [BusId; 2], DevId<FdEnd>, DevId<FdEnd>) {
    let mut sim = SimNetwork::new(35);
    let buses = [
        sim.add_bus(BusConfig::new("canfd0", 500_000).fd(2_000_000)),
        sim.add_bus(BusConfig::new("canfd1", 500_000).fd(2_000_000)),
    ];
    let a = sim.add_device("a", FdEnd::new(), &buses).unwrap();
    let b = sim.add_device("b", FdEnd::new(), &buses).unwrap();
    (sim, buses, a, b)
}

fn fd(id: u16, fill: u8, len: usize) -> FdFrame {
    FdFrame::new(Id::Standard(id), &vec![fill; len])
        .unwrap()
        .with_brs(true)
}

fn send(sim: &mut SimNetwork, from: DevId<FdEnd>, f: &FdFrame) {
    let now = sim.now();
    sim.device_mut(from).link.send_fd(now, f).unwrap();
}

#[test]
fn an_fd_frame_sent_once_arrives_once_from_two_buses() {
    let (mut sim, _, a, b) = rig();
    let f = fd(0x185, 0xA5, 64);
    send(&mut sim, a, &f);
    sim.run_for(duocan::Duration::from_millis(10));
    let end = sim.device(b);
    assert_eq!(end.got, [f], "once, bytes and flags as sent");
    assert_eq!(end.link.merger().stats().duplicates, 1, "its twin dropped");
    // Port health counts it on both ports of both ends, as a classic frame.
    let [c0, c1] = [end.link.port(0).counters(), end.link.port(1).counters()];
    assert_eq!(
        (c0.delivered + c1.delivered, c0.duplicates + c1.duplicates),
        (1, 1)
    );
    for p in 0..2 {
        let rx = end.link.port(p).counters();
        assert_eq!(rx.rx, 1);
        let tx = sim.device(a).link.port(p).counters();
        assert_eq!((tx.tx, tx.tx_ok), (1, 1), "port {p}");
        assert_eq!(sim.device(a).link.port_state(p), PortState::Ok);
    }
}

#[test]
fn with_one_bus_cut_every_fd_frame_still_arrives_once_in_order() {
    let (mut sim, buses, a, b) = rig();
    let ms = duocan::Duration::from_millis;
    let mut sent = vec![];
    for k in 0..40u8 {
        if k == 10 {
            sim.bus_down(buses[1]);
        }
        // Classic and FD frames of one identifier and the same first bytes: different frames.
        let f = fd(0x190, k, [8, 12, 64][k as usize % 3]);
        send(&mut sim, a, &f);
        sent.push(f);
        let now = sim.now();
        let c = Frame::new(Id::Standard(0x190), &[k; 8]).unwrap();
        sim.device_mut(a).link.send(now, &c);
        sim.run_for(ms(5));
    }
    sim.run_for(ms(200));
    let end = sim.device(b);
    assert_eq!(end.got, sent);
    assert_eq!(end.got_classic.len(), 40);
    assert_eq!(
        end.link.port(1).counters().rx,
        20,
        "ten of each kind before the cut"
    );
    assert_eq!(end.link.port(0).counters().rx, 80);
    // Unacknowledged FD frames tell port health of the cut, as classic ones do.
    assert_ne!(sim.device(a).link.port_state(1), PortState::Ok);
    assert!(sim.device(a).link.port(1).counters().tx_failed > 0);
}

#[test]
fn a_link_with_a_classic_only_port_refuses_fd_frames() {
    let mut link = DualBus::new(DualBusConfig::default());
    let f = fd(0x185, 1, 12);
    let t = Instant::from_millis(1);
    assert_eq!(
        link.send_fd(t, &f),
        Err(FdSendError::ClassicPort { port: 0 })
    );
    link.set_port_fd(0, true);
    assert!(!link.fd_capable());
    let err = link.send_fd(t, &f).unwrap_err();
    assert_eq!(err, FdSendError::ClassicPort { port: 1 });
    assert!(err.to_string().contains("port 1 is classic-only"));
    // Nothing queued for either port, nothing counted.
    assert_eq!(link.poll_transmit_fd(), None);
    assert_eq!(link.port(0).counters().tx, 0);
    link.set_port_fd(1, true);
    link.set_port_fd(7, true);
    assert!(link.fd_capable());
    assert_eq!(link.send_fd(t, &f), Ok(()));
    let out: Vec<_> = std::iter::from_fn(|| link.poll_transmit_fd()).collect();
    assert_eq!(out, [(0, f), (1, f)]);
    // Receiving needs no rule, and a bad port index is counted, not a panic.
    assert_eq!(link.handle_rx_fd(t, 9, &f), None);
    assert_eq!(link.stats().bad_port, 1);
}

/// A redundant master (supervisor and CiA 302-2 master, node 1) whose layer's ports are
/// FD-capable or not.
fn master(fd: bool) -> RedundantMaster {
    master_serving(fd, false)
}

/// [`master`], its node serving USDO (a CANopen FD network's master) if `usdo`.
fn master_serving(fd: bool, usdo: bool) -> RedundantMaster {
    let ms = duocan::Duration::from_millis;
    let nid = NodeId::must(1);
    let od = objects::master_dictionary(1, comm::Identity::default());
    let config = MasterConfig::new();
    let sdo = MasterSdoClient::with_sessions(DEFAULT_LIMIT, config.sdo_sessions);
    let node = NodeConfig::master(nid).with_fd(usdo);
    let master = Master::with_parts(node, od, Predefined, sdo, config).unwrap();
    let cfg = SupervisorConfig::new(0, nid, ms(20), ms(50), ms(10));
    let sup = Supervisor::new(master, cfg, Instant::ZERO);
    let mut link = DualBus::new(DualBusConfig::default());
    link.set_port_fd(0, fd);
    link.set_port_fd(1, fd);
    RedundantMaster::new(link, sup).unwrap()
}

#[test]
fn a_redundant_master_on_fd_buses_exchanges_fd_frames_once_with_one_bus_cut() {
    let ms = duocan::Duration::from_millis;
    let mut sim = SimNetwork::new(351);
    let buses = [
        sim.add_bus(BusConfig::new("canfd0", 500_000).fd(2_000_000)),
        sim.add_bus(BusConfig::new("canfd1", 500_000).fd(2_000_000)),
    ];
    // A master whose layer has classic-only ports is refused on FD buses, at start.
    assert!(matches!(
        sim.add_device("classic master", master(false), &buses),
        Err(SimError::ClassicOnFdBus { .. })
    ));
    let m = sim.add_device("master", master(true), &buses).unwrap();
    let d = sim.add_device("fd device", FdEnd::new(), &buses).unwrap();
    sim.run_for(ms(200));
    let mut from_device = vec![];
    let mut from_master = vec![];
    let mut got = vec![];
    for k in 0..20u8 {
        if k == 10 {
            sim.bus_down(buses[0]);
        }
        let up = fd(0x191, k, 64);
        send(&mut sim, d, &up);
        from_device.push(up);
        let down = fd(0x211, k, 16);
        let now = sim.now();
        sim.device_mut(m).send_fd(now, &down).unwrap();
        from_master.push(down);
        sim.run_for(ms(10));
        // Taken as they come: the station holds 16 for the application.
        got.extend(std::iter::from_fn(|| sim.device_mut(m).poll_fd_frame()));
    }
    sim.run_for(ms(100));
    got.extend(std::iter::from_fn(|| sim.device_mut(m).poll_fd_frame()));
    assert_eq!(got, from_device, "each once, in order, through the cut");
    assert_eq!(sim.device(m).fd_frames_dropped(), 0);
    assert_eq!(sim.device(d).got, from_master);
    // The master's own classic traffic (heartbeats, SYNC) went on beside.
    assert!(sim.device(d).got_classic.len() > 10);
    // Frames the application leaves are counted once the queue is full, never grown.
    for k in 0..20u8 {
        send(&mut sim, d, &fd(0x191, k, 8));
        sim.run_for(ms(2));
    }
    sim.run_for(ms(50));
    assert_eq!(sim.device(m).fd_frames_dropped(), 4);
    let left: Vec<_> = std::iter::from_fn(|| sim.device_mut(m).poll_fd_frame()).collect();
    assert_eq!(left.len(), 16);
    assert_eq!(left[15].data()[0], 15, "the oldest kept, in order");
}

#[test]
fn a_redundant_masters_supervisor_passes_usdo_to_its_master_each_request_once_with_one_bus_cut() {
    let ms = duocan::Duration::from_millis;
    let mut sim = SimNetwork::new(352);
    let buses = [
        sim.add_bus(BusConfig::new("canfd0", 500_000).fd(2_000_000)),
        sim.add_bus(BusConfig::new("canfd1", 500_000).fd(2_000_000)),
    ];
    let m = sim
        .add_device("master", master_serving(true, true), &buses)
        .unwrap();
    let d = sim.add_device("tool", FdEnd::new(), &buses).unwrap();
    sim.run_for(ms(200));
    // A tool's USDO client, node-ID 0x7F, on both buses through its own layer.
    let mut client = UsdoClient::new(NodeId::must(0x7F), 1024);
    let server = NodeId::must(1);
    let mut transfer = |sim: &mut SimNetwork, start: &dyn Fn(&mut UsdoClient, Instant)| {
        start(&mut client, sim.now());
        while let Some(f) = client.poll_transmit() {
            send(sim, d, &f);
        }
        for _ in 0..20 {
            sim.run_for(ms(2));
            let answers: Vec<FdFrame> = sim.device_mut(d).got.drain(..).collect();
            for a in answers {
                client.handle_frame(sim.now(), &a);
                while let Some(f) = client.poll_transmit() {
                    send(sim, d, &f);
                }
            }
            if let Some(e) = client.poll_event() {
                return e.data().map(<[u8]>::to_vec).ok_or(e.result.err());
            }
        }
        panic!("no answer");
    };
    // The master's heartbeat producer time (the supervisor's 20 ms), read from its dictionary.
    let hb = transfer(&mut sim, &|c, now| {
        c.upload(now, server, 0x1017, 0, ms(100)).unwrap();
    });
    assert_eq!(hb.unwrap(), 20u16.to_le_bytes());
    // Bus 1 cut: a write and its read-back over bus 2.
    sim.bus_down(buses[0]);
    let written = transfer(&mut sim, &|c, now| {
        c.download(now, server, 0x1017, 0, 0, &30u16.to_le_bytes(), ms(100))
            .unwrap();
    });
    assert_eq!(written.unwrap(), Vec::<u8>::new());
    let read = transfer(&mut sim, &|c, now| {
        c.upload(now, server, 0x1017, 0, ms(100)).unwrap();
    });
    assert_eq!(read.unwrap(), 30u16.to_le_bytes());
    // Each request served once (the layer merged the two copies before the supervisor).
    let st = sim.device(m).sup().node().usdo_server().unwrap().stats();
    assert_eq!((st.completed, st.aborted, st.repeats), (3, 0, 0));
    // The supervisor's master took the write with an SDO write's reactions.
    let od = sim.device(m).sup().node().od();
    assert_eq!(
        duocan::od::ObjectDictionary::get_u32(od, 0x1017, 0),
        Some(30)
    );
    // The application's queue got each request once too (what else an FD frame is for is
    // the application's).
    let queued: Vec<_> = std::iter::from_fn(|| sim.device_mut(m).poll_fd_frame()).collect();
    assert_eq!(queued.len(), 3, "{queued:?}");
    assert!(queued.iter().all(|f| f.id() == Id::Standard(0x600 + 0x7F)));
}
