//! # The safety gateway's firmware image
//!
//! The `safety-gateway` crate's [`Gateway`] on the STM32F413 board ([`duocan_board`]): CAN1
//! and CAN2 are the interlocking's dual bus, CAN3 the field bus where the track-circuit board
//! reports. No allocator exists in this image: the gateway lives in the frame of `main`, which
//! never returns, built there in place ([`Gateway::unstarted`]: no copy of its 30 kB on the
//! stack on the way); its dictionary's definitions are `const` tables, its values a fixed arena
//! in a `static` ([`OD`]: all zeros until loaded, so in `.bss`) that the gateway's node
//! borrows; the network table is a `static` too ([`PROFILE`]). So the RAM the image needs is
//! its static RAM plus its stack, and the stack at start-up is the gateway and a few kilobytes
//! of construction, hardly more than the main loop needs.
//!
//! The main loop is the board's ([`duocan_board::Board::run`]): it polls the gateway (whose
//! interlocking side is duocan's `EmbeddedDriver` over CAN1 and CAN2) whenever a frame
//! arrives, a mailbox frees or the deadline the gateway returned comes, and sleeps otherwise.
//! The panel: green while the node is operational, blue while both buses carry traffic, red
//! after a panic.
//!
//! A panic leaves the board silent ([`fail_silent`]): the gateway's safe outputs are its
//! messages to the interlocking (the track circuits' states as SRDO and TPDOs), and the safe
//! thing for them after a fault is to stop, never to send one more. The interlocking's SRDO
//! consumer reaches its safe state when the refresh time passes without a valid SRDO, and its
//! heartbeat consumer reports the gateway lost: every track circuit behind it counts as
//! occupied there.
#![no_std]
#![no_main]

use cortex_m_rt::entry;
use duocan::profile::railway::{DeviceAddress, RailwayProfile};
use duocan::{Instant, NmtState, NodeId};
use duocan_board::can::Port;
use duocan_board::safe::{fail_silent, Panel};
use duocan_board::App;
use duocan_redundancy_core::PortState;
use safety_gateway::dictionary::Od;
use safety_gateway::{Gateway, ADDRESS, NODE_ID};
use static_cell::{ConstStaticCell, StaticCell};

/// The interlocking network as the gateway's identifier profile knows it: the two
/// interlocking computers and the gateway.
const NETWORK: [(NodeId, DeviceAddress); 3] = [
    (NodeId::must(1), DeviceAddress::board_at(0, 0, 0, 1)),
    (NodeId::must(2), DeviceAddress::board_at(0, 0, 0, 2)),
    (NODE_ID, ADDRESS),
];

/// The network table as the gateway's identifier profile: static storage, no heap.
static PROFILE: StaticCell<RailwayProfile> = StaticCell::new();
/// The dictionary: its empty state is a constant of zeros, so the `static` is in `.bss` and
/// needs no start-up code; the gateway's node borrows it.
static OD: ConstStaticCell<Od> = ConstStaticCell::new(Od::new());

/// The gateway as the board's main loop runs it.
struct Image<'a>(&'a mut Gateway<Port>);

impl App for Image<'_> {
    fn acknowledge(&mut self) {
        for p in 0..2 {
            if let Some(port) = self.0.bus_mut(p) {
                port.acknowledge();
            }
        }
        self.0.field_mut().acknowledge();
    }

    fn poll(&mut self, now: Instant, panel: &mut Panel) -> Option<Instant> {
        let next = self.0.poll(now);
        // The events are the application's to log; this image has nowhere to put them, and
        // the gateway's outputs do not depend on them being read.
        while self.0.poll_event().is_some() {}
        let link = &self.0.device().link;
        let buses_ok = (0..2).all(|p| link.port(p).state() == PortState::Ok);
        panel.show(self.0.node().nmt_state() == NmtState::Operational, buses_ok);
        next
    }
}

#[entry]
fn main() -> ! {
    let Some((mut board, ports)) = duocan_board::init(true) else {
        fail_silent()
    };
    let ([bus1, bus2], Some(field)) = (ports.buses, ports.field) else {
        fail_silent()
    };
    let Ok(profile) = RailwayProfile::with(&NETWORK) else {
        fail_silent()
    };
    let profile = PROFILE.init(profile);
    let Some(od) = OD.try_take() else {
        fail_silent()
    };
    let now = board.now();
    // Built in this frame, which never ends: see the crate docs.
    let mut gateway = Gateway::unstarted(profile, od, [bus1, bus2, field], now);
    if gateway.start(now).is_err() {
        fail_silent()
    }
    board.run(&mut Image(&mut gateway))
}

/// A panic stops the gateway where it stands, off the buses (see the crate docs).
#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    fail_silent()
}
