//! The master's heap, measured on the host: both interlocking computers' stations, built by the
//! firmware's own [`master_board::build`], run in duocan's simulator on two buses with the three
//! board pairs, through boot, a bus failure, a pair failover under computer 1, computer 1's
//! death and computer 2's takeover, and a pair failover under computer 2. A counting allocator
//! attributes every block to the station whose code allocated it (the simulator's own memory
//! is not counted) and keeps each station's high-water mark, which must fit the heap the
//! firmware gives its allocator, [`master_board::HEAP_BYTES`], with a margin.
//!
//! `cargo test -p master-board --test heap -- --nocapture` prints the figures; the mark also
//! goes to `target/tmp/master-heap-high-water`, where CI's firmware step reads it to put it
//! beside the images' sizes.

// A global allocator is `unsafe impl GlobalAlloc`; the crate denies unsafe code elsewhere.
#![allow(unsafe_code)]

use duocan::machine::{Device, PortRequest, PortStatus};
use duocan::od::comm;
use duocan::sim::{BusConfig, SimNetwork};
use duocan::{Duration, Frame, Instant, Node, NodeConfig, NodeId, Station};
use duocan_redundancy::supervisor::audit::AuditEntry;
use duocan_redundancy::supervisor::flying_master::MasterRole;
use duocan_redundancy::{DualBus, DualBusConfig, Member};
use master_board::board::MASTER_TIMEOUT;
use master_board::dictionary::Od;
use master_board::{build, indication, Computer, HEAP_BYTES, PAIRS};
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicUsize, Ordering::Relaxed};

// ----- the counting allocator -----

/// Meters: 0 counts nothing, 1 and 2 are the computers.
const METERS: usize = 3;

thread_local! {
    /// The meter of the code running on this thread now.
    static METER: Cell<u8> = const { Cell::new(0) };
}

static LIVE: [AtomicUsize; METERS] = [const { AtomicUsize::new(0) }; METERS];
static PEAK: [AtomicUsize; METERS] = [const { AtomicUsize::new(0) }; METERS];
static BLOCKS: [AtomicUsize; METERS] = [const { AtomicUsize::new(0) }; METERS];
static PEAK_BLOCKS: [AtomicUsize; METERS] = [const { AtomicUsize::new(0) }; METERS];

/// Each block carries its meter in a header, so that a block is subtracted from the meter
/// that allocated it whoever frees it.
struct Counting;

fn header(l: Layout) -> Layout {
    let align = l.align().max(16);
    Layout::from_size_align(l.size() + align, align).expect("layout")
}

fn count(m: u8, add: bool, size: usize) {
    let m = m as usize;
    if m == 0 || m >= METERS {
        return;
    }
    if add {
        let live = LIVE[m].fetch_add(size, Relaxed) + size;
        let blocks = BLOCKS[m].fetch_add(1, Relaxed) + 1;
        if live > PEAK[m].load(Relaxed) {
            PEAK[m].store(live, Relaxed);
            PEAK_BLOCKS[m].store(blocks, Relaxed);
        }
    } else {
        LIVE[m].fetch_sub(size, Relaxed);
        BLOCKS[m].fetch_sub(1, Relaxed);
    }
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        let h = header(l);
        // SAFETY: `h` is non-zero in size (it holds the header).
        let base = unsafe { System.alloc(h) };
        if base.is_null() {
            return base;
        }
        let m = METER.try_with(Cell::get).unwrap_or(0);
        // SAFETY: the block has `h.align() >= 16` bytes before the caller's part.
        unsafe { base.write(m) };
        count(m, true, l.size());
        // SAFETY: within the block.
        unsafe { base.add(h.align()) }
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        let h = header(l);
        // SAFETY: `p` came from `alloc` with the same layout: the header precedes it.
        let base = unsafe { p.sub(h.align()) };
        count(unsafe { base.read() }, false, l.size());
        unsafe { System.dealloc(base, h) };
    }
    unsafe fn realloc(&self, p: *mut u8, l: Layout, new: usize) -> *mut u8 {
        // The block keeps the meter it was allocated under.
        let m = unsafe { p.sub(header(l).align()).read() };
        let saved = METER.with(|c| c.replace(m));
        let q = unsafe { self.alloc(Layout::from_size_align_unchecked(new, l.align())) };
        METER.with(|c| c.set(saved));
        if !q.is_null() {
            unsafe {
                core::ptr::copy_nonoverlapping(p, q, l.size().min(new));
                self.dealloc(p, l);
            }
        }
        q
    }
}

#[global_allocator]
static ALLOC: Counting = Counting;

/// Runs `f` with the allocations of this thread counted on meter `m`.
fn metered<R>(m: u8, f: impl FnOnce() -> R) -> R {
    let saved = METER.with(|c| c.replace(m));
    let r = f();
    METER.with(|c| c.set(saved));
    r
}

/// A device whose every call is metered on `meter`: what the station allocates while the
/// simulator drives it.
struct Metered<D> {
    meter: u8,
    dev: D,
}

impl<D: Device> Device for Metered<D> {
    type Event = D::Event;
    fn port_count(&self) -> usize {
        self.dev.port_count()
    }
    fn handle_rx(&mut self, now: Instant, port: usize, frame: &Frame) {
        metered(self.meter, || self.dev.handle_rx(now, port, frame));
    }
    fn handle_rx_at(&mut self, now: Instant, port: usize, frame: &Frame, at: Instant) {
        metered(self.meter, || self.dev.handle_rx_at(now, port, frame, at));
    }
    fn handle_port_status(&mut self, now: Instant, port: usize, status: PortStatus) {
        metered(self.meter, || {
            self.dev.handle_port_status(now, port, status)
        });
    }
    fn handle_timeout(&mut self, now: Instant) {
        metered(self.meter, || self.dev.handle_timeout(now));
    }
    fn poll_transmit(&mut self) -> Option<(usize, Frame)> {
        metered(self.meter, || self.dev.poll_transmit())
    }
    fn poll_port_request(&mut self) -> Option<(usize, PortRequest)> {
        metered(self.meter, || self.dev.poll_port_request())
    }
    fn poll_timeout(&self) -> Option<Instant> {
        metered(self.meter, || self.dev.poll_timeout())
    }
    fn poll_event(&mut self) -> Option<Self::Event> {
        metered(self.meter, || self.dev.poll_event())
    }
}

// ----- the network -----

/// A pair board: a slave on its own dual-bus layer, booted at `at`.
fn board(id: NodeId, at: Instant) -> Station<DualBus, Node<duocan::od::DynamicDictionary>> {
    let od = comm::standard_dictionary(id.raw(), comm::Identity::default());
    let mut node = Node::new(NodeConfig::slave(id), od);
    node.boot(at);
    Station::new(DualBus::new(DualBusConfig::default()), node)
}

const B_POWERED: Instant = Instant::from_millis(1_000);
const BUS_DOWN: Instant = Instant::from_millis(2_000);
const BUS_UP: Instant = Instant::from_millis(2_500);
const PAIR_0_FAILS: Instant = Instant::from_millis(3_000);
const COMPUTER_1_DIES: Instant = Instant::from_millis(4_000);
const PAIR_1_FAILS: Instant = Instant::from_millis(5_000);
const END: Instant = Instant::from_millis(6_000);

#[test]
fn the_heap_high_water_of_boot_failovers_and_takeover_fits_the_firmware_heap() {
    let mut sim = SimNetwork::new(20);
    let buses = [
        sim.add_bus(BusConfig::new("bus 1", 1_000_000)),
        sim.add_bus(BusConfig::new("bus 2", 1_000_000)),
    ];
    // The dictionaries are statics on the board, not heap: leaked here, before the meter runs.
    let station = |c: Computer, m: u8| {
        let od: &'static mut Od = Box::leak(Box::new(Od::new()));
        Metered {
            meter: m,
            dev: metered(m, || build(c, od, Instant::ZERO)).expect("the board's station builds"),
        }
    };
    let c1 = sim
        .add_device("computer 1", station(Computer::One, 1), &buses)
        .unwrap();
    let c2 = sim
        .add_device("computer 2", station(Computer::Two, 2), &buses)
        .unwrap();
    let mut members = Vec::new();
    for (a, b) in PAIRS {
        let a = sim
            .add_device(format!("{a}"), board(a, Instant::ZERO), &buses)
            .unwrap();
        let id = sim
            .add_device(format!("{b}"), board(b, Instant::ZERO), &buses)
            .unwrap();
        // The B boards come later, so that every A is configured first and active.
        sim.power_off(id);
        sim.at(B_POWERED, move |sim| {
            let _ = sim.replace(id, board(b, B_POWERED));
        });
        members.push(a);
    }
    sim.at(BUS_DOWN, move |sim| sim.bus_down(buses[0]));
    sim.at(BUS_UP, move |sim| sim.bus_up(buses[0]));
    let (a0, a1) = (members[0], members[1]);
    sim.at(PAIR_0_FAILS, move |sim| sim.power_off(a0));
    sim.at(COMPUTER_1_DIES, move |sim| sim.power_off(c1));
    sim.at(PAIR_1_FAILS, move |sim| sim.power_off(a1));
    sim.run_until(COMPUTER_1_DIES);

    // Computer 1 commanded until here: pair 0 went over to B, computer 2 followed.
    let one = &sim.device(c1).dev;
    assert!(indication(one).active);
    assert!(!indication(&sim.device(c2).dev).active);
    let active =
        |s: &master_board::Station, p: usize| s.sup().pairs().nth(p).and_then(|(_, st)| st.active);
    assert_eq!(active(one, 0), Some(Member::B));
    assert_eq!(active(&sim.device(c2).dev, 0), Some(Member::B));

    sim.run_until(END);
    let two = &sim.device(c2).dev;
    let panel = indication(two);
    assert!(panel.active, "computer 2 took over");
    assert_eq!(panel.bus_ok, [true, true], "bus 1 is back");
    assert_eq!(panel.pairs_running, 3);
    assert_eq!(
        [0, 1, 2].map(|p| active(two, p)),
        [Some(Member::B), Some(Member::B), Some(Member::A)]
    );
    let takeover = two
        .sup()
        .audit()
        .iter()
        .find_map(|r| match r.entry {
            AuditEntry::Master(m) if m.to == MasterRole::Active => Some(m.at),
            _ => None,
        })
        .expect("computer 2's takeover is in its audit trail");
    // Within the master-heartbeat timeout (+ 1 ms) of computer 1's last heartbeat, which was
    // at most one heartbeat period before it died.
    assert!(
        takeover > COMPUTER_1_DIES
            && takeover <= COMPUTER_1_DIES + MASTER_TIMEOUT + Duration::from_millis(1)
    );

    let peak = |m: usize| (PEAK[m].load(Relaxed), PEAK_BLOCKS[m].load(Relaxed));
    let (p1, b1) = peak(1);
    let (p2, b2) = peak(2);
    println!("heap high-water, computer 1: {p1} bytes in {b1} blocks");
    println!("heap high-water, computer 2: {p2} bytes in {b2} blocks");
    let high = p1.max(p2);
    println!("heap-high-water-bytes: {high}");
    // For CI's firmware step, which puts it beside the images' sizes (`.ci/firmware.sh`).
    let figure = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("master-heap-high-water");
    std::fs::write(&figure, high.to_string()).expect("the target directory is writable");
    println!("firmware heap (HEAP_BYTES): {HEAP_BYTES}");
    assert!(high > 0, "the stations allocate (the meter works)");
    // The host's figure bounds the target's from above (its pointers and sizes are twice as
    // wide). Margin: a quarter of the mark again, for the embedded allocator's per-block
    // overhead (a few bytes a block, and alignment) and paths this run did not take.
    assert!(
        high + high / 4 <= HEAP_BYTES,
        "the firmware heap ({HEAP_BYTES} bytes) is less than the high-water mark ({high}) + 25 %"
    );
}
