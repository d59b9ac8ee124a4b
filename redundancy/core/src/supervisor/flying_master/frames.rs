//! The flying-master frames: six COB-IDs of CiA 302-2, and the [`Rank`] three of them carry
//! (priority, node-ID), by which every conflict between masters is decided.

use core::cmp::Ordering;
use core::fmt;
use duocan_core::NodeId;

/// Active-master response / announcement.
pub const ACTIVE_MASTER_RESPONSE: u16 = 0x71;
/// Negotiation request.
pub const NEGOTIATION_REQUEST: u16 = 0x72;
/// Active-master request.
pub const ACTIVE_MASTER_REQUEST: u16 = 0x73;
/// Master-capable response.
pub const MASTER_CAPABLE_RESPONSE: u16 = 0x74;
/// Master-capable request.
pub const MASTER_CAPABLE_REQUEST: u16 = 0x75;
/// Force negotiation (and multiple-master detection).
pub const FORCE_NEGOTIATION: u16 = 0x76;

/// A master's rank: priority first (lower wins), then node-ID.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Rank {
    /// 0x1F90 sub 3.
    pub priority: u8,
    /// Node-ID.
    pub node: NodeId,
}

impl Rank {
    /// A rank.
    #[must_use]
    pub const fn new(priority: u8, node: NodeId) -> Self {
        Rank { priority, node }
    }
    pub(super) fn payload(self) -> [u8; 2] {
        [self.priority, self.node.raw()]
    }
    pub(super) fn from_payload(d: &[u8]) -> Option<Rank> {
        match d {
            [p, n] => Some(Rank::new(*p, NodeId::new(*n)?)),
            _ => None,
        }
    }
}

impl Ord for Rank {
    fn cmp(&self, o: &Self) -> Ordering {
        (self.priority, self.node.raw()).cmp(&(o.priority, o.node.raw()))
    }
}
impl PartialOrd for Rank {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}

impl fmt::Display for Rank {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} (priority {})", self.node, self.priority)
    }
}
