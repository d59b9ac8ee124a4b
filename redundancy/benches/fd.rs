//! A 64-byte CAN FD frame through the dual bus: its end-to-end latency in simulated time (sent
//! once through one device's `DualBus`, delivered once by the other's) against its wire time,
//! on two FD buses at 1 Mbit/s nominal with a 2 and a 5 Mbit/s data phase, both buses up and
//! one cut (printed first); and the CPU cost per frame of the receiving layer, which takes a
//! frame's two copies and delivers one (criterion).
//!
//! The dual-bus layer adds no simulated time of its own: a frame is delivered when its first
//! copy has crossed the wire, so the latency's bound is the frame's wire time, and a cut bus
//! changes nothing while the other carries the frame.

use criterion::{criterion_group, Criterion, Throughput};
use duocan::frame::FdFrame;
use duocan::machine::{BusLink, Device, PortRequest, PortStatus};
use duocan::sim::{timing, BusConfig, SimNetwork};
use duocan::{Duration, Frame, Id, Instant};
use duocan_redundancy::{DualBus, DualBusConfig, LinkEvent};
use std::hint::black_box;

const NOMINAL: u32 = 1_000_000;

/// A device on two FD ports through a [`DualBus`]: sends what it is given, records what the
/// layer delivers and when.
struct FdEnd {
    link: DualBus,
    got: Vec<(Instant, FdFrame)>,
}

impl FdEnd {
    fn new() -> Self {
        let mut link = DualBus::new(DualBusConfig::default());
        link.set_port_fd(0, true);
        link.set_port_fd(1, true);
        FdEnd { link, got: vec![] }
    }
}

impl Device for FdEnd {
    type Event = LinkEvent;
    fn port_count(&self) -> usize {
        2
    }
    fn fd_capable(&self) -> bool {
        self.link.fd_capable()
    }
    fn handle_rx(&mut self, now: Instant, port: usize, frame: &Frame) {
        let _ = self.link.handle_rx(now, port, frame);
    }
    fn handle_rx_fd(&mut self, now: Instant, port: usize, frame: &FdFrame, at: Instant) {
        if let Some(f) = self.link.handle_rx_fd_at(now, port, frame, at) {
            self.got.push((now, f));
        }
    }
    fn handle_port_status(&mut self, now: Instant, port: usize, status: PortStatus) {
        self.link.handle_port_status(now, port, status);
    }
    fn handle_timeout(&mut self, now: Instant) {
        self.link.handle_timeout(now);
    }
    fn poll_transmit(&mut self) -> Option<(usize, Frame)> {
        self.link.poll_transmit()
    }
    fn poll_transmit_fd(&mut self) -> Option<(usize, FdFrame)> {
        self.link.poll_transmit_fd()
    }
    fn poll_port_request(&mut self) -> Option<(usize, PortRequest)> {
        self.link.poll_port_request()
    }
    fn poll_timeout(&self) -> Option<Instant> {
        self.link.poll_timeout()
    }
    fn poll_event(&mut self) -> Option<LinkEvent> {
        self.link.poll_event()
    }
}

fn fd(id: u16, k: u8) -> FdFrame {
    let data: Vec<u8> = (0..64).map(|i| k.wrapping_add(i)).collect();
    FdFrame::new(Id::Standard(id), &data)
        .unwrap()
        .with_brs(true)
}

/// 64-byte frames sent one at a time 10 ms apart, over `n` frames: the worst latency from
/// `send_fd` to delivery, its mean, and the worst ratio of a frame's latency to its own wire
/// time (frames of other bytes take other wire times: stuff bits).
fn latency(data_rate: u32, cut: bool, n: u8) -> (Duration, Duration, f64) {
    let mut sim = SimNetwork::new(35);
    let buses = [
        sim.add_bus(BusConfig::new("canfd0", NOMINAL).fd(data_rate)),
        sim.add_bus(BusConfig::new("canfd1", NOMINAL).fd(data_rate)),
    ];
    let a = sim.add_device("a", FdEnd::new(), &buses).unwrap();
    let b = sim.add_device("b", FdEnd::new(), &buses).unwrap();
    sim.run_for(Duration::from_millis(10));
    if cut {
        sim.bus_down(buses[1]);
        sim.run_for(Duration::from_millis(10));
    }
    let (mut worst, mut sum, mut ratio) = (Duration::ZERO, Duration::ZERO, 0f64);
    for k in 0..n {
        let f = fd(0x185, k);
        let t0 = sim.now();
        sim.device_mut(a).link.send_fd(t0, &f).unwrap();
        sim.run_for(Duration::from_millis(10));
        let got = std::mem::take(&mut sim.device_mut(b).got);
        assert_eq!(got.len(), 1, "frame {k} delivered once");
        assert_eq!(got[0].1, f, "frame {k} as sent");
        let l = got[0].0 - t0;
        let wire = timing::fd_frame_duration(&f, NOMINAL, data_rate);
        ratio = ratio.max(l.as_micros() as f64 / wire.as_micros() as f64);
        worst = worst.max(l);
        sum = sum + l;
    }
    let mean = Duration::from_micros(sum.as_micros() / u64::from(n));
    (worst, mean, ratio)
}

fn print_latency() {
    for rate in [2_000_000, 5_000_000] {
        let wire = (0..100u8)
            .map(|k| timing::fd_frame_duration(&fd(0x185, k), NOMINAL, rate))
            .max()
            .unwrap_or(Duration::ZERO);
        for cut in [false, true] {
            let (worst, mean, ratio) = latency(rate, cut, 100);
            println!(
                "dual bus fd 1/{} Mbit/s, 64-byte frame, {} (simulated): latency worst {worst}, \
                 mean {mean}; wire time up to {wire}: {ratio:.3}x the frame's own wire time at worst",
                rate / 1_000_000,
                if cut { "one bus cut" } else { "both buses" },
            );
        }
    }
}

/// `n` 64-byte FD frames (440 identifiers, values that change rarely), each arriving on both ports (up to 2 ms apart, either first): (time
/// µs, port, frame), in time order; one every 140 µs (about two buses' worth at 1/5 Mbit/s).
fn traffic(n: usize) -> Vec<(u64, usize, FdFrame)> {
    let mut rng = 0x2545_F491_4F6C_DD1Du64;
    let mut next = move || {
        rng ^= rng << 13;
        rng ^= rng >> 7;
        rng ^= rng << 17;
        rng
    };
    let mut v = Vec::with_capacity(n * 2);
    for i in 0..n {
        let t = i as u64 * 140;
        let id = 0x180 + 0x100 * (next() % 4) as u16 + (next() % 110) as u16 + 1;
        let f = fd(id, (next() % 4) as u8);
        let skew = next() % 2_000;
        let (first, second) = if next() % 2 == 0 { (0, 1) } else { (1, 0) };
        v.push((t, first, f));
        v.push((t + skew, second, f));
    }
    v.sort_by_key(|x| x.0);
    v
}

fn merge_per_frame(c: &mut Criterion) {
    const FRAMES: usize = 10_000;
    let arrivals = traffic(FRAMES);
    // The same traffic as classic 8-byte frames (the first 8 bytes): the classic path beside it.
    let classic: Vec<(u64, usize, Frame)> = arrivals
        .iter()
        .map(|(t, p, f)| (*t, *p, Frame::new(f.id(), &f.data()[..8]).unwrap()))
        .collect();
    let fd_link = || {
        let mut l = DualBus::new(DualBusConfig::default());
        l.set_port_fd(0, true);
        l.set_port_fd(1, true);
        l
    };
    let mut g = c.benchmark_group("dual_bus_fd");
    g.throughput(Throughput::Elements(FRAMES as u64));
    g.bench_function("handle_rx_fd_64_bytes_per_frame", |b| {
        b.iter(|| {
            let mut l = fd_link();
            let mut delivered = 0u32;
            for (t, p, f) in &arrivals {
                let at = Instant::from_micros(*t);
                if l.handle_rx_fd_at(at, *p, black_box(f), at).is_some() {
                    delivered += 1;
                }
            }
            black_box(delivered)
        })
    });
    g.bench_function("handle_rx_classic_8_bytes_per_frame", |b| {
        b.iter(|| {
            let mut l = fd_link();
            let mut delivered = 0u32;
            for (t, p, f) in &classic {
                let at = Instant::from_micros(*t);
                if l.handle_rx_at(at, *p, black_box(f), at).is_some() {
                    delivered += 1;
                }
            }
            black_box(delivered)
        })
    });
    g.finish();
    // Each frame delivered once: one copy of the two.
    let mut l = fd_link();
    let delivered = arrivals
        .iter()
        .filter(|(t, p, f)| {
            let at = Instant::from_micros(*t);
            l.handle_rx_fd_at(at, *p, f, at).is_some()
        })
        .count();
    assert_eq!(delivered, FRAMES, "every FD frame delivered exactly once");
}

criterion_group!(benches, merge_per_frame);

fn main() {
    print_latency();
    benches();
    Criterion::default().configure_from_args().final_summary();
}
