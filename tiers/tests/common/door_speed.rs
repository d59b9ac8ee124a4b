//! One-at-a-time SDO reads through the front door (`duocan::net::Network`) against the bare
//! transport's ping-pong, side by side in one run, on one python-can UDP bus and on two (the
//! redundant door: `duocan_redundancy::net::open_dual`). Shared by the python side-by-side
//! benchmark and the door's own tier benchmark (`door_speed`): what each prints is the ratio of
//! the door's reads per second to the bare round trips per second, the ceiling of reads that
//! wait for each other's answer.

use duocan::machine::Station;
use duocan::net::{NetOptions, Network};
use duocan::port::udp::{UdpBusConfig, UdpPort};
use duocan::runtime::{Handle, Runtime};
use std::time::Instant as StdInstant;

/// The server node the door reads (0x1018:01, expedited).
pub const DOOR_SERVER: u8 = 0x42;

/// What one side-by-side measurement holds: one row each.
pub struct DoorSpeed {
    /// Bare ping-pong round trips per second on one bus.
    pub bare: Vec<f64>,
    /// Reads per second through the door on one bus.
    pub one: Vec<f64>,
    /// Reads per second through the redundant door on two buses.
    pub two: Vec<f64>,
    /// Bare round trips per second on two buses at once: a ping on each, both pongs awaited
    /// (what the redundant door's transport carries for each read).
    pub bare_two: Vec<f64>,
}

/// The bare round trip on two buses at once: one thread pings on both (0x100), one thread per
/// bus answers (0x101), and both answers are awaited; round trips per second over `n`.
fn round_trip_two(a: &UdpBusConfig, b: &UdpBusConfig, n: u32) -> f64 {
    use duocan::{Frame, Id};
    let echo = |cfg: &UdpBusConfig| {
        let mut answer = super::wire::Wire::open(cfg);
        std::thread::spawn(move || {
            for _ in 0..n {
                match answer.recv() {
                    Some(f) if f.id() == Id::Standard(0x100) => {
                        answer.send(&Frame::new(Id::Standard(0x101), f.data()).unwrap());
                    }
                    _ => return,
                }
            }
        })
    };
    let mut ask = [super::wire::Wire::open(a), super::wire::Wire::open(b)];
    let echoes = [echo(a), echo(b)];
    let start = StdInstant::now();
    for i in 0..n {
        let ping = Frame::new(Id::Standard(0x100), &i.to_le_bytes()).unwrap();
        for w in &mut ask {
            w.send(&ping);
        }
        for w in &mut ask {
            while w.recv().expect("the bare echo answers").id() != Id::Standard(0x101) {}
        }
    }
    let per_s = f64::from(n) / start.elapsed().as_secs_f64();
    for e in echoes {
        e.join().expect("the bare echo ran");
    }
    per_s
}

/// A tokio runtime of one worker whose threads are named `name` (their CPU is counted by it).
pub fn runtime(name: &str) -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .thread_name(name)
        .enable_all()
        .build()
        .unwrap()
}

fn port(rt: &tokio::runtime::Runtime, cfg: &UdpBusConfig) -> UdpPort {
    let _in = rt.enter();
    UdpPort::open(cfg.clone()).expect("open the UDP bus (inside unshare -n?)")
}

/// A duocan server node on `cfg`'s bus under the runtime of `rt`.
fn server(
    rt: &tokio::runtime::Runtime,
    cfg: &UdpBusConfig,
) -> Handle<Station<duocan::machine::SinglePort, super::rt::TestNode>> {
    let p = port(rt, cfg);
    let _in = rt.enter();
    let h = Runtime::new(Station::single(super::rt::sdo_node(
        DOOR_SERVER,
        false,
        0,
        &[],
    )))
    .port(p)
    .spawn()
    .unwrap();
    rt.block_on(h.boot()).unwrap();
    h
}

/// `n` reads of 0x1018:01 one after the other through `net`, on its runtime: reads/s.
fn reads(rt: &tokio::runtime::Runtime, net: &Network, n: usize) -> f64 {
    let node = net.node(DOOR_SERVER);
    let t = StdInstant::now();
    rt.block_on(rt.spawn(async move {
        for _ in 0..n {
            let _: u32 = node.sdo().read(0x1018, 1).await.unwrap();
        }
    }))
    .unwrap();
    n as f64 / t.elapsed().as_secs_f64()
}

/// `rounds` rounds of: the bare ping-pong on `buses[0]`, `n` reads through the door on
/// `buses[1]`, `n` reads through the redundant door on `buses[2]` and `buses[3]` (a server
/// node on each bus answers), the bare ping-pong on `buses[0]` and `buses[4]` at once. Each
/// runs on buses of its own: every socket on a bus receives every datagram, so a door idle on
/// the bus measured would cost the measured one its reads.
pub fn measure(buses: &[UdpBusConfig; 5], n: usize, rounds: usize) -> DoorSpeed {
    let [bare, a, b, c, bare2] = buses;
    let (srv, cli) = (runtime("door-srv"), runtime("door-cli"));
    let servers = [server(&srv, a), server(&srv, b), server(&srv, c)];
    let one = {
        let p = port(&cli, a);
        let _in = cli.enter();
        Network::open(p).unwrap()
    };
    let two = {
        let (pa, pb) = (port(&cli, b), port(&cli, c));
        let _in = cli.enter();
        duocan_redundancy::net::open_dual(pa, pb, NetOptions::default()).unwrap()
    };
    // A first read each: the sockets, the sessions and the caches warm, not measured.
    reads(&cli, &one, 100);
    reads(&cli, &two, 100);
    let mut m = DoorSpeed {
        bare: Vec::new(),
        one: Vec::new(),
        two: Vec::new(),
        bare_two: Vec::new(),
    };
    // `DUOCAN_BENCH_ONLY=bare|one|two|bare_two` runs one of them alone (to profile it); the report
    // then has no ratio.
    let only = std::env::var("DUOCAN_BENCH_ONLY").unwrap_or_default();
    let runs = |what: &str| only.is_empty() || only == what;
    for _ in 0..rounds {
        if runs("bare") {
            m.bare
                .push(1e6 / super::wire::round_trip(bare, n.try_into().unwrap()));
        }
        if runs("one") {
            m.one.push(reads(&cli, &one, n));
        }
        if runs("two") {
            m.two.push(reads(&cli, &two, n));
        }
        if runs("bare_two") {
            m.bare_two
                .push(round_trip_two(bare, bare2, n.try_into().unwrap()));
        }
    }
    cli.block_on(one.close());
    cli.block_on(two.close());
    for s in &servers {
        srv.block_on(s.shutdown());
    }
    m
}

fn median(mut xs: Vec<f64>) -> f64 {
    xs.sort_by(f64::total_cmp);
    xs.get(xs.len() / 2).copied().unwrap_or(f64::NAN)
}

impl DoorSpeed {
    /// The door's medians over the bare median, and each round's own ratios.
    pub fn report(&self) -> String {
        let bare = median(self.bare.clone());
        let per_round = |d: &[f64], b: &[f64]| {
            d.iter()
                .zip(b)
                .map(|(d, b)| format!("{:.2}", d / b))
                .collect::<Vec<_>>()
                .join(", ")
        };
        let (one, two) = (median(self.one.clone()), median(self.two.clone()));
        let bare_two = median(self.bare_two.clone());
        format!(
            "one-at-a-time SDO reads through the door against the bare ping-pong, {} rounds (medians; each round's ratio in brackets):\n\
             bare socket ping-pong, one bus: {bare:.0} round trips/s\n\
             door, one bus: {one:.0} reads/s, {:.2} of the ping-pong ({})\n\
             door, two buses (redundant): {two:.0} reads/s, {:.2} of the one-bus ping-pong ({})\n\
             bare socket ping-pong on two buses at once (both answers awaited): {bare_two:.0} round trips/s; the redundant door {:.2} of it ({})",
            self.bare.len().max(self.one.len()),
            one / bare,
            per_round(&self.one, &self.bare),
            two / bare,
            per_round(&self.two, &self.bare),
            two / bare_two,
            per_round(&self.two, &self.bare_two),
        )
    }
}
