//! # A redundant CiA 302-2 master for a microcontroller, on duocan
//!
//! One of the two interlocking computers of a dual-bus network: a board with two CAN
//! controllers, one on bus 1 and one on bus 2 (the firmware image in `firmware/master` runs it
//! on an STM32F413's CAN1 and CAN2). It is the CiA 302-2 master of three A/B board pairs
//! ([`PAIRS`]) with duocan's slave-pair supervision, and a flying master with the other
//! computer as its peer: computer 1 is the strong master, computer 2 the hot standby that takes
//! over when computer 1 falls silent ([`MASTER_TIMEOUT`](board::MASTER_TIMEOUT)).
//!
//! What a microcontroller needs differs from the host's master in where memory comes from:
//!
//! - the dictionary is `'static` tables in flash and a [`StaticDictionary`](duocan::od::StaticDictionary)
//!   in RAM ([`dictionary`]): 945 entries, 897 of them the node-indexed arrays of CiA 302-2;
//! - the dual-bus layer's capacities are sized to the network ([`MERGE_SLOTS`](board::MERGE_SLOTS),
//!   [`FUNCTIONS`](board::FUNCTIONS): one type parameter of the layer, [`Link`](board::Link)), and so are the master's and the supervisor's queues and
//!   tables ([`network_config`](board::network_config),
//!   [`supervisor_config`](board::supervisor_config)): allocated once by [`build`],
//!   from a heap of [`HEAP_BYTES`], never grown.
//!
//! The same code runs on the host: this crate's `tests/heap.rs` drives both computers' stations
//! in duocan's simulator through boot, a bus failure, a pair failover, a master takeover and a
//! failover under the new master, with a counting allocator, and asserts that the high-water
//! mark of their heaps fits [`HEAP_BYTES`].
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]

extern crate alloc;

pub mod board;
pub mod dictionary;

pub use board::{
    build, indication, start, unstarted, BoardError, Indication, MasterBoard, Station,
};

use board::node;
use duocan::NodeId;

/// The A/B board pairs of the network: (A, B).
pub const PAIRS: [(NodeId, NodeId); 3] = [
    (node(0x10), node(0x50)),
    (node(0x11), node(0x51)),
    (node(0x12), node(0x52)),
];

/// The heap the firmware gives its allocator: the high-water mark measured on the host
/// (`tests/heap.rs`: 13,063 bytes, computer 1 through boot, a bus failure and a pair failover
/// before it dies; computer 2 stays 24 bytes below it through the same and its takeover and a
/// failover after) plus a quarter, which the test asserts. It is the master's slots for the six
/// pair members (`max_slaves` in [`board::network_config`]: the library's default of one for
/// each of the 127 node-IDs was 31.5 KB), its queues, and the supervisor's audit trail, pair
/// table and queues. The host's pointers are twice as wide as the target's, so the figure bounds
/// the target's need from above; the margin covers the allocator's per-block overhead and paths
/// the run did not take.
pub const HEAP_BYTES: usize = 16 * 1024;

/// Which of the two interlocking computers the board is (the firmware reads it from a strap
/// pin, as an A/B board learns its role).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Computer {
    /// Computer 1: node 1, the strong master.
    One,
    /// Computer 2: node 2, the weak (standby) master.
    Two,
}

impl Computer {
    /// Its node-ID.
    #[must_use]
    pub const fn node(self) -> NodeId {
        match self {
            Computer::One => node(1),
            Computer::Two => node(2),
        }
    }
    /// The other computer.
    #[must_use]
    pub const fn other(self) -> Computer {
        match self {
            Computer::One => Computer::Two,
            Computer::Two => Computer::One,
        }
    }
}
