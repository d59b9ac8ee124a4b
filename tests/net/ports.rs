//! The network's link seen from the front door on one port: `ports()` with the state the
//! driver reported, no reach, the link and port count checked, and what closes with the
//! network.

use duocan::frame::Frame;
use duocan::machine::ErrorCause;
use duocan::net::{NetError, NetOptions, Network};
use duocan::port::mem::MemBus;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

/// Every simulated network has a name saying what it holds; a bare `sim`, or another door's
/// simulated network, is an error that names them all.
#[tokio::test(start_paused = true)]
async fn sim_nodes_is_the_one_bus_simulated_network_and_sim_names_no_port() {
    let net = Network::open_named("sim-nodes").unwrap();
    let vendor: u32 = net.node(10).sdo().read(0x1018, 1).await.unwrap();
    assert_eq!(vendor, duocan::net::SIM_VENDOR);
    assert_eq!(net.ports().await.unwrap()[0].name, "sim-nodes");
    net.close().await;
    for name in ["sim", "sim-station", "sim-pairs", "sim:faults"] {
        let Err(NetError::Port(why)) = Network::open_named(name) else {
            panic!("{name} opened");
        };
        assert!(why.contains("not a port of one bus"), "{name}: {why}");
        assert!(why.contains(duocan::net::SIM_NAMES), "{name}: {why}");
    }
}

/// `:fd` after a name opens a CANopen FD network there: `sim-nodes:fd` is the simulated nodes
/// on an FD bus (their USDO answers the typed read), a simulated name that is no port of one
/// bus stays an error with `:fd`, and a SocketCAN name is the interface without the suffix.
#[tokio::test(start_paused = true)]
async fn a_name_with_fd_after_it_is_a_canopen_fd_network() {
    let net = Network::open_named("sim-nodes:fd").unwrap();
    assert_eq!(net.fd_client(), Some(duocan::net::FD_CLIENT));
    let vendor: u32 = net.node(10).sdo().read(0x1018, 1).await.unwrap();
    assert_eq!(vendor, duocan::net::SIM_VENDOR);
    net.close().await;
    assert_eq!(Network::open_named("sim-nodes").unwrap().fd_client(), None);
    for name in ["sim:fd", "sim-pairs:fd", "sim-nodes:fd:fd"] {
        let Err(NetError::Port(why)) = Network::open_named(name) else {
            panic!("{name} opened");
        };
        assert!(why.contains(duocan::net::SIM_NAMES), "{name}: {why}");
    }
    #[cfg(all(feature = "socketcan", target_os = "linux"))]
    {
        let Err(NetError::Port(why)) = Network::open_named("nosuchcan9:fd") else {
            panic!("nosuchcan9 opened");
        };
        assert!(
            why.contains("nosuchcan9") && !why.contains("nosuchcan9:fd"),
            "{why}"
        );
    }
}

#[tokio::test(start_paused = true)]
async fn one_port_shows_its_counters_and_the_state_its_driver_reported() {
    let bus = MemBus::new("mem0");
    let (port, cut) = bus.plugged_port();
    let opts = NetOptions::default().with_sdo_timeout(Duration::from_millis(100));
    let net = Network::open_with(port, opts).unwrap();
    let _nodes = Network::simulated_on(&bus, [5], NetOptions::default()).unwrap();
    let vendor: u32 = net.node(5).sdo().read(0x1018, 1).await.unwrap();
    assert_eq!(vendor, duocan::net::SIM_VENDOR);
    let ports = net.ports().await.unwrap();
    assert_eq!(ports.len(), 1);
    let p = &ports[0];
    assert_eq!((p.index, p.name.as_str(), p.state), (0, "mem0", "ok"));
    assert_eq!(p.last_error, None);
    assert!(p.counters.rx_frames >= 2, "boot-up and the answer: {p:?}");
    assert!(p.counters.tx_frames >= 1, "the request: {p:?}");
    // No reach on one port: the question has no answer.
    assert_eq!(net.heard_on(5).await.unwrap(), None);
    assert!(matches!(
        net.heard_on(128).await,
        Err(NetError::NoSuchNode(128))
    ));

    cut.pull();
    assert!(cut.is_pulled());
    tokio::time::sleep(Duration::from_millis(50)).await;
    let p = &net.ports().await.unwrap()[0];
    assert_eq!(p.state, "down");
    assert_eq!(p.last_error, Some(ErrorCause::InterfaceDown));
    assert!(net.node(5).sdo().read::<u32>(0x1018, 1).await.is_err());
    net.close().await;
    _nodes.close().await;
}

#[tokio::test(start_paused = true)]
async fn a_link_takes_as_many_ports_as_it_has() {
    let bus = MemBus::new("mem");
    // Two ports for the one-port link of a plain network is refused, naming the ports.
    let link: Box<dyn duocan::net::NetLink> = Box::new(OnePortLink::default());
    let e = match Network::open_link(link, (bus.port(), bus.port()), NetOptions::default()) {
        Err(e) => e,
        Ok(_) => panic!("opened with a port too many"),
    };
    assert!(
        matches!(&e, NetError::Port(why) if why.contains("2 ports given to a link of 1")),
        "{e}"
    );
}

#[tokio::test(start_paused = true)]
async fn what_was_given_to_on_close_stops_with_the_network() {
    let net = Network::simulated([3], NetOptions::default()).unwrap();
    let stopped = Arc::new(AtomicBool::new(false));
    let s = stopped.clone();
    net.on_close(move || async move { s.store(true, Ordering::SeqCst) });
    assert!(!stopped.load(Ordering::SeqCst));
    net.close().await;
    assert!(stopped.load(Ordering::SeqCst));
}

/// The simplest link a user could write: one port passed through.
#[derive(Default)]
struct OnePortLink(duocan::machine::SinglePort);

impl duocan::BusLink for OnePortLink {
    type Event = duocan::net::NetEvent;
    type Command = core::convert::Infallible;
    fn port_count(&self) -> usize {
        1
    }
    fn handle_rx(&mut self, now: duocan::Instant, port: usize, f: &Frame) -> Option<Frame> {
        self.0.handle_rx(now, port, f)
    }
    fn handle_port_status(&mut self, now: duocan::Instant, port: usize, s: duocan::PortStatus) {
        self.0.handle_port_status(now, port, s);
    }
    fn send(&mut self, now: duocan::Instant, f: &Frame) {
        self.0.send(now, f);
    }
    fn poll_transmit(&mut self) -> Option<(usize, Frame)> {
        self.0.poll_transmit()
    }
    fn handle_timeout(&mut self, _: duocan::Instant) {}
    fn poll_timeout(&self) -> Option<duocan::Instant> {
        None
    }
    fn poll_event(&mut self) -> Option<duocan::net::NetEvent> {
        None
    }
}

impl duocan::net::NetLink for OnePortLink {}

/// A link that carries a bus of its own (as the redundancy crate's simulated station does)
/// hands what its port read to the network itself ([`NetLink::poll_input`]): an SDO server's
/// answer made by the link, and a status of its port, reach the network as a port's would.
#[tokio::test(start_paused = true)]
async fn what_a_link_reads_itself_reaches_the_network_as_its_ports_input() {
    let bus = MemBus::new("quiet");
    let answering = Answering::default();
    let stamps = answering.stamps.clone();
    let link: Box<dyn duocan::net::NetLink> = Box::new(answering);
    let net = Network::open_link(link, bus.port(), NetOptions::default()).unwrap();
    let v: u32 = net.node(5).sdo().read(0x1018, 1).await.unwrap();
    assert_eq!(v, 0x0102_0304);
    // The answer reached the link with the stamp the link gave it, not as a stamp-less frame.
    let (stamped, unstamped) = *stamps.lock().unwrap();
    assert_eq!((stamped, unstamped), (1, 0));
    let p = &net.ports().await.unwrap()[0];
    assert_eq!(p.state, "error warning");
    assert_eq!(p.last_error, Some(ErrorCause::ErrorWarning));
    net.close().await;
}

/// Answers every SDO upload request to node 5 with 0x01020304 itself, and reports its port
/// at the error-warning level when it does.
#[derive(Default)]
struct Answering {
    link: OnePortLink,
    inputs: std::collections::VecDeque<(usize, duocan::port::PortInput<duocan::Instant>)>,
    now: duocan::Instant,
    /// Frames received with the stamp this link gave them, and received without a stamp.
    stamps: std::sync::Arc<std::sync::Mutex<(usize, usize)>>,
    /// The stamp of the last answer.
    stamp: duocan::Instant,
}

impl duocan::BusLink for Answering {
    type Event = duocan::net::NetEvent;
    type Command = core::convert::Infallible;
    fn port_count(&self) -> usize {
        1
    }
    fn handle_rx(&mut self, now: duocan::Instant, port: usize, f: &Frame) -> Option<Frame> {
        self.stamps.lock().unwrap().1 += 1;
        self.link.handle_rx(now, port, f)
    }
    fn handle_rx_at(
        &mut self,
        now: duocan::Instant,
        port: usize,
        f: &Frame,
        at: duocan::Instant,
    ) -> Option<Frame> {
        if at == self.stamp {
            self.stamps.lock().unwrap().0 += 1;
        }
        self.link.handle_rx(now, port, f)
    }
    fn handle_port_status(&mut self, now: duocan::Instant, port: usize, s: duocan::PortStatus) {
        self.link.handle_port_status(now, port, s);
    }
    fn send(&mut self, now: duocan::Instant, f: &Frame) {
        use duocan::port::PortInput;
        self.now = now;
        let d = f.data();
        if f.id() == duocan::Id::Standard(0x605) && d[0] == 0x40 {
            let answer = [0x43, d[1], d[2], d[3], 0x04, 0x03, 0x02, 0x01];
            let answer = Frame::new(duocan::Id::Standard(0x585), &answer).unwrap();
            let warning = duocan::PortStatus::Error(ErrorCause::ErrorWarning);
            self.inputs.push_back((0, PortInput::Status(warning)));
            // Stamped with the instant the request went out: the answer was on the wire then.
            self.stamp = now;
            self.inputs
                .push_back((0, PortInput::Frame(answer, Some(now))));
        }
    }
    fn poll_transmit(&mut self) -> Option<(usize, Frame)> {
        None
    }
    fn handle_timeout(&mut self, now: duocan::Instant) {
        self.now = now;
    }
    fn poll_timeout(&self) -> Option<duocan::Instant> {
        (!self.inputs.is_empty()).then_some(self.now)
    }
    fn poll_event(&mut self) -> Option<duocan::net::NetEvent> {
        None
    }
}

impl duocan::net::NetLink for Answering {
    fn poll_input(&mut self) -> Option<(usize, duocan::port::PortInput<duocan::Instant>)> {
        self.inputs.pop_front()
    }
}
