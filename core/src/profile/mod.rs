//! Identifier profiles: which CAN identifiers carry the services whose identifiers CiA 301 fixes
//! (NMT, error control, default EMCY). Everything configurable through the dictionary (SDO, PDO,
//! SYNC, TIME, EMCY COB-IDs) is read from the dictionary instead.
//!
//! The stack only ever asks a profile; the predefined connection set is one implementation and a
//! deployment-specific scheme ([`railway`], the 29-bit layout of a published railway-depot network) is another.
//!
//! ```
//! use duocan_core::profile::{IdProfile, Predefined, ProfileFrame};
//! use duocan_core::{Id, NodeId};
//!
//! let (p, node) = (Predefined, NodeId::must(0x12));
//! assert_eq!(p.nmt(), Id::Standard(0x000));
//! assert_eq!(p.heartbeat(node), Id::Standard(0x712));
//! assert_eq!(p.emcy(node), Id::Standard(0x092));
//! // Back from an identifier: a guarding request is the remote frame on the heartbeat identifier.
//! assert_eq!(p.classify(Id::Standard(0x712), false), Some(ProfileFrame::Heartbeat(node)));
//! assert_eq!(p.classify(Id::Standard(0x712), true), Some(ProfileFrame::Guarding(node)));
//! // SDO and PDO identifiers come from the dictionary, not from the profile.
//! assert_eq!(p.classify(Id::Standard(0x592), false), None);
//! ```

pub mod railway;

use crate::frame::cob_id::{predefined, NodeId};
use crate::frame::Id;

/// What a profile recognises in an identifier.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ProfileFrame {
    /// NMT module control.
    Nmt,
    /// Boot-up or heartbeat of a node.
    Heartbeat(NodeId),
    /// Node-guarding request (remote) or answer (data) of a node.
    Guarding(NodeId),
    /// EMCY of a node on its default identifier.
    Emcy(NodeId),
}

/// Maps the fixed-identifier services to CAN identifiers and back.
pub trait IdProfile {
    /// NMT module-control identifier.
    fn nmt(&self) -> Id;
    /// Boot-up and heartbeat identifier of a node.
    fn heartbeat(&self, node: NodeId) -> Id;
    /// Node-guarding identifier of a node (request and answer).
    fn guarding(&self, node: NodeId) -> Id {
        self.heartbeat(node)
    }
    /// Default EMCY identifier of a node (what 0x1014 holds after reset).
    fn emcy(&self, node: NodeId) -> Id;
    /// Decodes a received identifier. `remote` tells guarding requests from heartbeats where a
    /// profile shares one identifier between the two.
    fn classify(&self, id: Id, remote: bool) -> Option<ProfileFrame>;
}

/// The CiA 301 predefined connection set: NMT 0x000, error control 0x700+n, EMCY 0x080+n.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Predefined;

impl IdProfile for Predefined {
    fn nmt(&self) -> Id {
        Id::Standard(predefined::NMT)
    }
    fn heartbeat(&self, node: NodeId) -> Id {
        predefined::error_control(node)
    }
    fn emcy(&self, node: NodeId) -> Id {
        predefined::emcy(node)
    }
    #[inline]
    fn classify(&self, id: Id, remote: bool) -> Option<ProfileFrame> {
        match predefined::classify(id) {
            predefined::Function::Nmt => Some(ProfileFrame::Nmt),
            predefined::Function::ErrorControl(n) if remote => Some(ProfileFrame::Guarding(n)),
            predefined::Function::ErrorControl(n) => Some(ProfileFrame::Heartbeat(n)),
            predefined::Function::Emcy(n) => Some(ProfileFrame::Emcy(n)),
            _ => None,
        }
    }
}

impl<P: IdProfile + ?Sized> IdProfile for &P {
    fn nmt(&self) -> Id {
        (**self).nmt()
    }
    fn heartbeat(&self, node: NodeId) -> Id {
        (**self).heartbeat(node)
    }
    fn guarding(&self, node: NodeId) -> Id {
        (**self).guarding(node)
    }
    fn emcy(&self, node: NodeId) -> Id {
        (**self).emcy(node)
    }
    fn classify(&self, id: Id, remote: bool) -> Option<ProfileFrame> {
        (**self).classify(id, remote)
    }
}
