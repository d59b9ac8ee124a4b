//! # The redundant master's firmware image
//!
//! The `master-board` crate's [`MasterBoard`] on the STM32F413 board ([`duocan_board`]): CAN1
//! and CAN2 are the dual bus; the CiA 302-2 master, its supervisor with three A/B pairs and
//! the flying master run on them. The computer strap (PF12) says which interlocking computer
//! the board is: computer 1 (node 1, the strong master) or computer 2 (node 2, the standby).
//!
//! Memory: the static dictionary is a `static` whose empty state is a constant (in .bss: no
//! start-up code, no copy), loaded at start-up; the station (dual-bus layer, master,
//! supervisor) lives in the frame of `main`, which never returns, built there in place
//! (`master_board::unstarted`: a `static` would be filled through copies on the stack, tens
//! of kilobytes each); what the master and the supervisor allocate when they are built (their
//! queues, the slave table, the pair table, the audit trail, the SDO sessions) comes from a
//! heap of [`HEAP_BYTES`] given to `embedded-alloc`, sized from the host run that measures its
//! high-water mark (`examples/master_board/tests/heap.rs`). Nothing grows after start-up.
//!
//! The main loop is the board's ([`duocan_board::Board::run`]): it polls the board (duocan's
//! `EmbeddedDriver` over CAN1 and CAN2) whenever a frame arrives, a mailbox frees or the
//! deadline comes, and sleeps otherwise. The panel: green while this computer is the active
//! master, blue while both buses carry traffic, red after a panic.
//!
//! A panic leaves the board silent ([`fail_silent`]): the master's outputs are its commands
//! to the network (NMT, SYNC, TIME, SDO configuration), and after a fault it must give none.
//! Silence is also what the redundancy is built on: the standby computer takes over when this
//! one's heartbeat has been missing for the master-heartbeat timeout (150 ms), continuing the
//! SYNC grid without resetting a slave, and the running boards keep their state meanwhile. A
//! last "stop all nodes" would instead halt the whole network for the new master to restart.
#![no_std]
#![no_main]

use cortex_m_rt::entry;
use duocan::Instant;
use duocan_board::can::Port;
use duocan_board::safe::{fail_silent, Panel};
use duocan_board::App;
use embedded_alloc::LlffHeap;
use master_board::dictionary::Od;
use master_board::{start, unstarted, Computer, MasterBoard, Station, HEAP_BYTES};
use static_cell::ConstStaticCell;

/// The dictionary: its empty state is a constant, so the `static` needs no start-up code.
static OD: ConstStaticCell<Od> = ConstStaticCell::new(Od::new());

/// The heap: what the master and the supervisor allocate when they are built.
#[global_allocator]
static HEAP: LlffHeap = LlffHeap::empty();

/// The board as the main loop runs it.
struct Image<'a>(&'a mut MasterBoard<Port>);

impl App for Image<'_> {
    fn acknowledge(&mut self) {
        for p in 0..2 {
            if let Some(port) = self.0.bus_mut(p) {
                port.acknowledge();
            }
        }
    }

    fn poll(&mut self, now: Instant, panel: &mut Panel) -> Option<Instant> {
        let next = self.0.poll(now);
        let shown = self.0.indication();
        panel.show(shown.active, shown.bus_ok == [true, true]);
        next
    }
}

#[entry]
fn main() -> ! {
    // SAFETY: runs once, first, before anything allocates; the arena is a `static` of
    // `HEAP_BYTES` bytes that nothing else refers to.
    #[allow(unsafe_code)]
    unsafe {
        embedded_alloc::init!(HEAP, HEAP_BYTES);
    }
    let Some((mut board, ports)) = duocan_board::init(false) else {
        fail_silent()
    };
    let computer = if board.strap() {
        Computer::Two
    } else {
        Computer::One
    };
    let now = board.now();
    // The dictionary is a `static` (all zeros until loaded: in .bss, nothing built at run time,
    // no copy); the station lives in this frame, which never ends, built there in place (see
    // the crate docs): a `static` would be filled through copies on the stack.
    let Some(od) = OD.try_take() else {
        fail_silent()
    };
    // Matched by reference: moving the station out of the `Result` would copy it.
    let mut built = unstarted(computer, od);
    let Ok(station) = &mut built else {
        fail_silent()
    };
    if start(station, now).is_err() {
        fail_silent()
    }
    // SAFETY: `station` lives in `built`, a local of `main`, which never returns (see
    // `forever`).
    #[allow(unsafe_code)]
    let station: &'static mut Station = unsafe { forever(station) };
    let mut master = MasterBoard::new(station, ports.buses);
    board.run(&mut Image(&mut master))
}

/// A local of `main` for good.
///
/// # Safety
///
/// `local` must be a local of `main` (or of another function that never returns and never
/// unwinds): `main` diverges and the image aborts on a panic (`panic = "abort"`, the panic
/// handler diverges too), so its frame is never popped and what lives in it lasts until
/// reset; the local stays mutably borrowed, so the returned reference is the only way to it.
#[allow(unsafe_code)]
unsafe fn forever<T>(local: &mut T) -> &'static mut T {
    // SAFETY: the caller's promise: the memory is valid for the rest of the program.
    unsafe { &mut *core::ptr::from_mut(local) }
}

/// A panic stops the master where it stands, off the buses (see the crate docs).
#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    fail_silent()
}
