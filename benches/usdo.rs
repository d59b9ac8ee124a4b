//! USDO (CANopen FD, CiA 1301) against classic SDO block transfer: throughput in simulated time
//! on an FD bus at 1 Mbit/s nominal with a 2 and a 5 Mbit/s data phase, each against its
//! bus-time bound (printed first), and the CPU cost per transfer of server and client
//! (criterion).
//!
//! A USDO transfer moves 56 bytes in one expedited round trip, or 60 bytes a segment with one
//! round trip per segment; an SDO block transfer streams 7 bytes a classic frame and confirms
//! every 127 of them. On an FD bus the data phase speeds up only the FD frames: the classic
//! SDO frames take the same wire time at any data bit rate. Which of the two is faster is
//! therefore a question of bit rates, and this bench answers it on the simulated wire.
//!
//! The bound of a transfer is the wire time of the frames it exchanges when nothing is lost
//! (recorded by running client and server against each other without a bus): the fastest any
//! implementation of the protocol can go on that bus. The simulated figures are deterministic.

use criterion::{criterion_group, Criterion, Throughput};
use duocan::cia1301::usdo::{UsdoClient, UsdoEvent};
use duocan::machine::{PortStatus, SinglePort};
use duocan::nmt::{command_frame, NmtCommand, NmtTarget};
use duocan::od::{comm, DataType, DynamicDictionary, ObjectDef};
use duocan::sdo::{DefaultBuffer, SdoClient, SdoOptions, TransferMode};
use duocan::sim::{timing, BusConfig, SimNetwork};
use duocan::{
    Device, Duration, FdFrame, Frame, Id, Instant, Machine, Node, NodeConfig, NodeId, Station,
};
use std::hint::black_box;

const NOMINAL: u32 = 1_000_000;
const DATA_RATES: [u32; 2] = [2_000_000, 5_000_000];
const DOMAIN: u16 = 0x2000;
const S: NodeId = NodeId::must(5);
const C: NodeId = NodeId::must(1);
const T: Duration = Duration::from_secs(5);
const LARGE: usize = 64 * 1024;

/// Node 5 serving SDO and USDO, started, with a 70,000-byte domain.
fn server() -> Station<SinglePort, Node<DynamicDictionary>> {
    let mut od = comm::standard_dictionary(S.raw(), comm::Identity::default());
    od.insert(ObjectDef::bytes(DOMAIN, 0, DataType::Domain, 70_000))
        .unwrap();
    let node = Node::new(NodeConfig::slave(S).with_fd(true), od);
    let mut dev = Station::new(SinglePort::fd(), node);
    dev.machine.boot(Instant::ZERO);
    let start = command_frame(Id::Standard(0), NmtCommand::Start, NmtTarget::All);
    dev.handle_rx(Instant::ZERO, 0, &start);
    while dev.poll_transmit().is_some() {}
    dev
}

fn data(len: usize) -> Vec<u8> {
    (0..len).map(|i| (i * 131 % 251) as u8).collect()
}

/// A USDO client of node 1 as a device on one FD port.
struct UsdoEnd {
    client: UsdoClient,
}

impl Device for UsdoEnd {
    type Event = UsdoEvent<DefaultBuffer>;
    fn port_count(&self) -> usize {
        1
    }
    fn fd_capable(&self) -> bool {
        true
    }
    fn handle_rx(&mut self, _: Instant, _: usize, _: &Frame) {}
    fn handle_rx_fd(&mut self, now: Instant, _: usize, frame: &FdFrame, _: Instant) {
        self.client.handle_frame(now, frame);
    }
    fn handle_port_status(&mut self, _: Instant, _: usize, _: PortStatus) {}
    fn handle_timeout(&mut self, now: Instant) {
        self.client.handle_timeout(now);
    }
    fn poll_transmit(&mut self) -> Option<(usize, Frame)> {
        None
    }
    fn poll_transmit_fd(&mut self) -> Option<(usize, FdFrame)> {
        self.client.poll_transmit().map(|f| (0, f))
    }
    fn poll_timeout(&self) -> Option<Instant> {
        self.client.poll_timeout()
    }
    fn poll_event(&mut self) -> Option<Self::Event> {
        self.client.poll_event()
    }
}

/// A classic SDO client as a device on one FD-capable port (it sends classic frames only).
struct SdoEnd {
    client: SdoClient,
}

impl Device for SdoEnd {
    type Event = duocan::sdo::SdoEvent;
    fn port_count(&self) -> usize {
        1
    }
    fn fd_capable(&self) -> bool {
        true
    }
    fn handle_rx(&mut self, now: Instant, _: usize, frame: &Frame) {
        self.client.handle_frame(now, frame);
    }
    fn handle_port_status(&mut self, _: Instant, _: usize, _: PortStatus) {}
    fn handle_timeout(&mut self, now: Instant) {
        self.client.handle_timeout(now);
    }
    fn poll_transmit(&mut self) -> Option<(usize, Frame)> {
        self.client.poll_transmit().map(|f| (0, f))
    }
    fn poll_timeout(&self) -> Option<Instant> {
        self.client.poll_timeout()
    }
    fn poll_event(&mut self) -> Option<Self::Event> {
        self.client.poll_event()
    }
}

#[derive(Clone, Copy, Debug)]
enum Kind {
    /// USDO download: expedited up to 56 bytes, segmented past it.
    Usdo,
    /// Classic SDO block download.
    SdoBlock,
}

fn start_usdo(c: &mut UsdoClient, now: Instant, payload: &[u8]) {
    c.download(now, S, DOMAIN, 0, 0, payload, T).unwrap();
}

fn start_sdo(c: &mut SdoClient, now: Instant, payload: &[u8]) {
    c.download(
        now,
        S,
        DOMAIN,
        0,
        payload,
        SdoOptions::mode(TransferMode::Block),
    )
    .unwrap();
}

/// One download on a simulated FD bus at 1 Mbit/s nominal and `data_rate` in the data phase:
/// how long it took, from the request's queueing to the client's result.
fn simulated(kind: Kind, data_rate: u32, payload: &[u8]) -> Duration {
    let mut sim = SimNetwork::new(1);
    let bus = sim.add_bus(BusConfig::new("canfd0", NOMINAL).fd(data_rate));
    let _slave = sim.add_device("slave", server(), &[bus]).unwrap();
    sim.run_for(Duration::from_millis(1));
    let t0 = sim.now();
    let took = match kind {
        Kind::Usdo => {
            let m = sim
                .add_device(
                    "client",
                    UsdoEnd {
                        client: UsdoClient::new(C, 70_000),
                    },
                    &[bus],
                )
                .unwrap();
            start_usdo(&mut sim.device_mut(m).client, t0, payload);
            loop {
                sim.step().expect("a result");
                if let Some((_, e)) = sim.take_events(m).into_iter().next() {
                    assert!(e.result.is_ok(), "{:?}", e.result.err());
                    break e.at - t0;
                }
            }
        }
        Kind::SdoBlock => {
            let m = sim
                .add_device(
                    "client",
                    SdoEnd {
                        client: SdoClient::new(70_000),
                    },
                    &[bus],
                )
                .unwrap();
            start_sdo(&mut sim.device_mut(m).client, t0, payload);
            loop {
                sim.step().expect("a result");
                if let Some((_, e)) = sim.take_events(m).into_iter().next() {
                    assert!(e.result.is_ok(), "{:?}", e.result.err());
                    break e.at - t0;
                }
            }
        }
    };
    took
}

/// The frames of one transfer with nothing lost, in the order they cross the bus.
enum Recording {
    Usdo {
        from_client: Vec<FdFrame>,
        from_server: Vec<FdFrame>,
    },
    Sdo {
        from_client: Vec<Frame>,
        from_server: Vec<Frame>,
    },
}

/// Runs client and server against each other without a bus and records their frames.
fn record(kind: Kind, payload: &[u8]) -> Recording {
    let mut n = server();
    match kind {
        Kind::Usdo => {
            let mut c: UsdoClient = UsdoClient::new(C, 70_000);
            start_usdo(&mut c, Instant::ZERO, payload);
            let (mut fc, mut fs) = (vec![], vec![]);
            loop {
                let mut moved = false;
                while let Some(f) = c.poll_transmit() {
                    moved = true;
                    fc.push(f);
                    n.handle_rx_fd(Instant::ZERO, 0, &f, Instant::ZERO);
                }
                while let Some((_, f)) = n.poll_transmit_fd() {
                    moved = true;
                    fs.push(f);
                    c.handle_frame(Instant::ZERO, &f);
                }
                if !moved {
                    break;
                }
            }
            assert!(c.poll_event().unwrap().result.is_ok());
            Recording::Usdo {
                from_client: fc,
                from_server: fs,
            }
        }
        Kind::SdoBlock => {
            let mut c: SdoClient = SdoClient::new(70_000);
            start_sdo(&mut c, Instant::ZERO, payload);
            let (mut fc, mut fs) = (vec![], vec![]);
            loop {
                let mut moved = false;
                while let Some(f) = c.poll_transmit() {
                    moved = true;
                    fc.push(f);
                    n.handle_rx(Instant::ZERO, 0, &f);
                }
                while let Some((_, f)) = n.poll_transmit() {
                    moved = true;
                    fs.push(f);
                    c.handle_frame(Instant::ZERO, &f);
                }
                if !moved {
                    break;
                }
            }
            assert!(c.poll_event().unwrap().result.is_ok());
            Recording::Sdo {
                from_client: fc,
                from_server: fs,
            }
        }
    }
}

impl Recording {
    /// The wire time of every frame of the transfer, and how many there are.
    fn bus_time(&self, data_rate: u32) -> (Duration, usize) {
        match self {
            Recording::Usdo {
                from_client,
                from_server,
            } => {
                let all = from_client.iter().chain(from_server);
                let t = all.clone().fold(Duration::ZERO, |t, f| {
                    t + timing::fd_frame_duration(f, NOMINAL, data_rate)
                });
                (t, all.count())
            }
            Recording::Sdo {
                from_client,
                from_server,
            } => {
                let all = from_client.iter().chain(from_server);
                let t = all.clone().fold(Duration::ZERO, |t, f| {
                    t + timing::frame_duration(f, NOMINAL)
                });
                (t, all.count())
            }
        }
    }
}

fn print_simulated_throughput() {
    let small = data(56);
    let large = data(LARGE);
    let kib = |len: usize, d: Duration| len as f64 / 1024.0 / (d.as_micros() as f64 / 1e6);
    for rate in DATA_RATES {
        let mbit = rate / 1_000_000;
        let mut rates = vec![];
        for (what, kind, payload) in [
            ("usdo expedited 56 B", Kind::Usdo, &small),
            ("sdo block 56 B", Kind::SdoBlock, &small),
            ("usdo segmented 64 KiB", Kind::Usdo, &large),
            ("sdo block 64 KiB", Kind::SdoBlock, &large),
        ] {
            let took = simulated(kind, rate, payload);
            let (bound, frames) = record(kind, payload).bus_time(rate);
            let got = kib(payload.len(), took);
            rates.push(got);
            println!(
                "fd 1/{mbit} Mbit/s {what} download (simulated): {got:.1} KiB/s in {took}; \
                 bus-time bound {:.1} KiB/s ({bound}, {frames} frames): {:.3}x the bound",
                kib(payload.len(), bound),
                bound.as_micros() as f64 / took.as_micros() as f64,
            );
        }
        println!(
            "fd 1/{mbit} Mbit/s usdo against sdo block: 56 B {:.2}x, 64 KiB {:.2}x",
            rates[0] / rates[1],
            rates[2] / rates[3],
        );
    }
}

// ----- CPU cost per transfer -----

/// 889 bytes: 15 USDO segments, 127 SDO block segments.
const MEDIUM: usize = 889;

fn server_per_transfer(c: &mut Criterion) {
    let mut g = c.benchmark_group("usdo_server");
    g.throughput(Throughput::Elements(1));
    for (name, kind, len) in [
        ("usdo_expedited_download_56", Kind::Usdo, 56),
        ("usdo_segmented_download_889", Kind::Usdo, MEDIUM),
        ("sdo_block_download_56", Kind::SdoBlock, 56),
        ("sdo_block_download_889", Kind::SdoBlock, MEDIUM),
    ] {
        let rec = record(kind, &data(len));
        let mut n = server();
        g.bench_function(name, |b| match &rec {
            Recording::Usdo { from_client, .. } => b.iter(|| {
                for f in from_client {
                    n.handle_rx_fd(Instant::ZERO, 0, black_box(f), Instant::ZERO);
                    while let Some(out) = n.poll_transmit_fd() {
                        black_box(out);
                    }
                }
                while n.poll_event().is_some() {}
            }),
            Recording::Sdo { from_client, .. } => b.iter(|| {
                for f in from_client {
                    n.handle_rx(Instant::ZERO, 0, black_box(f));
                    while let Some(out) = n.poll_transmit() {
                        black_box(out);
                    }
                }
                while n.poll_event().is_some() {}
            }),
        });
        // Every replay was a complete, successful transfer.
        match &rec {
            Recording::Usdo { .. } => {
                let st = n.machine.usdo_server().expect("a USDO server").stats();
                assert!(
                    st.completed > 0
                        && st.aborted == 0
                        && st.repeats == 0
                        && st.malformed == 0
                        && st.tx_dropped == 0,
                    "{name}: {st:?}"
                );
            }
            Recording::Sdo { .. } => {
                let st = n.machine.sdo_server().stats();
                assert!(
                    st.completed > 0 && st.aborted == 0 && st.client_aborts == 0,
                    "{name}: {st:?}"
                );
            }
        }
    }
    g.finish();
}

fn client_per_transfer(c: &mut Criterion) {
    let mut g = c.benchmark_group("usdo_client");
    g.throughput(Throughput::Elements(1));
    for (name, kind, len) in [
        ("usdo_expedited_download_56", Kind::Usdo, 56),
        ("usdo_segmented_download_889", Kind::Usdo, MEDIUM),
        ("sdo_block_download_56", Kind::SdoBlock, 56),
        ("sdo_block_download_889", Kind::SdoBlock, MEDIUM),
    ] {
        let payload = data(len);
        match record(kind, &payload) {
            Recording::Usdo { from_server, .. } => {
                // Each replayed transfer runs in a session of its own; the answers recorded
                // carry session 1, so the client is rebuilt for every transfer (its cost is in
                // the figure, as a client's start is).
                g.bench_function(name, |b| {
                    b.iter(|| {
                        let mut client: UsdoClient = UsdoClient::new(C, 70_000);
                        start_usdo(&mut client, Instant::ZERO, &payload);
                        while let Some(out) = client.poll_transmit() {
                            black_box(out);
                        }
                        for f in &from_server {
                            client.handle_frame(Instant::ZERO, black_box(f));
                            while let Some(out) = client.poll_transmit() {
                                black_box(out);
                            }
                        }
                        let e = client.poll_event().expect("result");
                        assert!(e.result.is_ok());
                    })
                });
            }
            Recording::Sdo { from_server, .. } => {
                let mut client: SdoClient = SdoClient::new(70_000);
                g.bench_function(name, |b| {
                    b.iter(|| {
                        start_sdo(&mut client, Instant::ZERO, &payload);
                        while let Some(out) = client.poll_transmit() {
                            black_box(out);
                        }
                        for f in &from_server {
                            client.handle_frame(Instant::ZERO, black_box(f));
                            while let Some(out) = client.poll_transmit() {
                                black_box(out);
                            }
                        }
                        let e = client.poll_event().expect("result");
                        assert!(e.result.is_ok());
                    })
                });
            }
        }
    }
    g.finish();
}

criterion_group!(benches, server_per_transfer, client_per_transfer);

fn main() {
    print_simulated_throughput();
    benches();
    Criterion::default().configure_from_args().final_summary();
}
