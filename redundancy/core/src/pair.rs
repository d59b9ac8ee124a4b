//! The vocabulary both parts of the crate share: which pair ([`PairId`]), which board of it
//! ([`Member`]), and what a pair is ([`PairSpec`]).
//!
//! The dual-bus layer uses it to merge the process data of the two boards of a pair; the
//! supervisor uses it to decide which board is active. Neither part imports the other for it.
//!
//! ```
//! use duocan_core::{Duration, NodeId};
//! use duocan_redundancy_core::link::same_function::PairError;
//! use duocan_redundancy_core::{DualBus, DualBusConfig, Member, PairId, PairSpec};
//!
//! let ms = Duration::from_millis;
//! // A turnout controller on two boards, nodes 0x10 (A) and 0x50 (B): heartbeats every 20 ms,
//! // a member silent for 50 ms has failed; both must be generic I/O devices (0x1000).
//! let spec = PairSpec {
//!     device_type: 0x0001_0191,
//!     ..PairSpec::new(NodeId::must(0x10), NodeId::must(0x50), ms(20), ms(50))
//! };
//! assert_eq!(spec.node(Member::A), NodeId::must(0x10));
//! assert_eq!(spec.node(Member::A.other()), NodeId::must(0x50));
//!
//! // The dual-bus layer learns the pair's nodes, to deliver the active member's process data.
//! let mut link: DualBus = DualBus::new(DualBusConfig::default());
//! assert_eq!(link.add_pair(spec.a, spec.b, Some(Member::A))?, PairId(0));
//! // A node belongs to one pair only.
//! let taken = link.add_pair(spec.b, NodeId::must(0x51), None);
//! assert_eq!(taken, Err(PairError::NodeTaken(spec.b)));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use core::fmt;
use duocan_core::{Duration, NodeId};

/// Pairs a layer can hold: 55 board pairs per network, rounded up.
pub const MAX_PAIRS: usize = 64;
/// Members of that many pairs: the nodes whose heartbeats a dual-bus layer can judge for
/// plausibility.
pub const MAX_MEMBERS: usize = 2 * MAX_PAIRS;
/// Index of a configured pair.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct PairId(pub u8);

/// A member of a pair.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Member {
    /// The A board.
    A,
    /// The B board.
    B,
}

impl Member {
    pub(crate) const fn index(self) -> usize {
        match self {
            Member::A => 0,
            Member::B => 1,
        }
    }
    /// The other member.
    #[must_use]
    pub const fn other(self) -> Member {
        match self {
            Member::A => Member::B,
            Member::B => Member::A,
        }
    }
}

impl fmt::Display for Member {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Member::A => "A",
            Member::B => "B",
        })
    }
}

/// One configured pair.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PairSpec {
    /// Node-ID of the A board.
    pub a: NodeId,
    /// Node-ID of the B board.
    pub b: NodeId,
    /// Device type (0x1000) expected of both boards (0: not checked).
    pub device_type: u32,
    /// Heartbeat producer time configured into both members (0x1017).
    pub producer_time: Duration,
    /// Heartbeat consumer time: a member silent this long has failed.
    pub consumer_time: Duration,
}

impl PairSpec {
    /// A pair whose members beat every `producer_time` and fail after `consumer_time`.
    #[must_use]
    pub const fn new(
        a: NodeId,
        b: NodeId,
        producer_time: Duration,
        consumer_time: Duration,
    ) -> Self {
        PairSpec {
            a,
            b,
            device_type: 0,
            producer_time,
            consumer_time,
        }
    }
    /// The node of a member.
    pub const fn node(&self, m: Member) -> NodeId {
        match m {
            Member::A => self.a,
            Member::B => self.b,
        }
    }
}
