//! # A railway safety gateway on duocan's no_std core
//!
//! A board with three CAN controllers (e.g. an STM32G474: Cortex-M4F, three FDCAN, 128 KiB
//! SRAM). Two sit on the interlocking's dual bus; the third on a field bus where a
//! track-circuit board sends its track circuits as safety data: a CiA 304 SRDO, the four codes
//! (0x55 clear, 0xAA occupied) plain and bitwise inverted, every cycle. The gateway consumes it
//! with duocan's SRDO consumer (SCT, SRVT, exact inverse) and mirrors the track circuits to the
//! interlocking: a code that is neither, or any SRDO violation (the board silent, a corrupted
//! half, a half alone), makes the track circuits occupied. The mirrored states go out as
//! CRC-protected state changes on both buses, event-driven and refreshed cyclically, and together
//! as a CiA 304 SRDO (the four codes plain on 0x127 and inverted on 0x128 every 50 ms; the
//! configuration checked by its CRC before the node may start). On the interlocking side it is
//! an ordinary CANopen slave of the railway 29-bit profile: boot-up, heartbeat, NMT, SDO server
//! (0x6000 sub *k* reads a mirrored state).
//!
//! Nothing is allocated: the dictionary's definitions are `const` tables ([`dictionary`],
//! generated at build time from the gateway's EDS, `safety_gateway.eds`), its values a fixed
//! arena; the node, the dual-bus layer, the driver and the mirrors are one [`Gateway`], placed
//! in a `static` [`Storage`] on a host, or built in place in the frame of a `main` that never
//! returns on a microcontroller ([`Gateway::unstarted`], as `firmware/gateway` does: a
//! `static` is filled through a copy on the stack). No allocator exists in this crate's world
//! (`duocan` and `duocan-redundancy-core` without default features).
//!
//! [`mock`] has an in-memory controller pair so that the same code runs on a host: this
//! crate's tests and `cargo run -p safety-gateway --example gateway_host` drive the gateway
//! against a duocan interlocking master on two mock buses and a scripted field board.
#![cfg_attr(not(test), no_std)]

pub mod dictionary;
pub mod gateway;
pub mod mirror;
pub mod mock;

pub use gateway::{Board, Event, FieldStats, Gateway, GatewayDevice, SetupError, Storage};
pub use mirror::{Cause, TrackChange};

use duocan::profile::railway::DeviceAddress;
use duocan::{Duration, NodeId};

/// The gateway's node-ID on the interlocking network.
pub const NODE_ID: NodeId = NodeId::must(20);
/// Its board address there: row 1, cabinet 4, layer 1, board 1 (I/O port *k* carries track
/// circuit *k*).
pub const ADDRESS: DeviceAddress = DeviceAddress::board_at(1, 4, 1, 1);
/// The track-circuit board's node-ID on the field bus.
pub const FIELD_NODE: NodeId = NodeId::must(1);
/// The normal frame of the field board's SRDO: CiA 304's default for SRDO 1 of node 1
/// (0xFF + 2 × node-ID).
pub const FIELD_NORMAL: u16 = 0xFF + 2 * FIELD_NODE.raw() as u16;
/// Its inverted frame (0x100 + 2 × node-ID).
pub const FIELD_INVERTED: u16 = FIELD_NORMAL + 1;
/// The field SRDO's validation time: the inverse must follow the normal frame within it.
pub const FIELD_SRVT: Duration = Duration::from_millis(20);
/// Track circuits mirrored.
pub const TRACKS: u8 = 4;
/// Merger slots of the dual-bus layer: the gateway hears a master's heartbeats, NMT, SYNC and
/// SDO, a few frames per 5 ms skew window (with a bus dead, the oldest records are evicted
/// first, counted: their twins never come).
pub const MERGE_SLOTS: usize = 64;

/// RAM budget of the slave node with its dictionary (issue 2's no_std slave): 16 KiB.
pub const NODE_RAM_BUDGET: usize = 16 * 1024;
/// RAM budget of the whole gateway (node, dictionary, dual-bus layer, driver, mirrors, event
/// queue): 40 KiB of the reference MCU's 128 KiB, the rest for stacks and the HAL. Measured on
/// thumbv7em (2026-12-06): 33,000 bytes, 3,352 of them the dictionary (the node with its
/// dictionary: 11,136; 288 of them its four SRDO slots). In the STM32F413 image
/// (`firmware/gateway`) the dictionary is a `static` and the gateway lives in `main`'s frame,
/// built there in place.
pub const GATEWAY_RAM_BUDGET: usize = 40 * 1024;

// The budgets hold on the target, checked when the crate is built for it.
#[cfg(all(target_arch = "arm", target_os = "none"))]
const _: () = {
    use core::mem::size_of;
    // The node borrows its dictionary: count both.
    assert!(size_of::<Board>() + size_of::<dictionary::Od>() <= NODE_RAM_BUDGET);
    assert!(
        size_of::<Gateway<mock::MockCan<'static>>>() + size_of::<dictionary::Od>()
            <= GATEWAY_RAM_BUDGET
    );
};
