//! The identifier profile a built network runs: [`NetProfile`], chosen with
//! [`RedundantNetworkBuilder::profile`](super::RedundantNetworkBuilder::profile).
//!
//! The sans-IO layers are generic over the profile (`Supervisor<D, P>`, `DualBus<C>`,
//! `LogicalNetwork<D, P>`), and a station built in code names the one it runs. The builder and
//! the async handle `net::RedundantNetwork` choose it at run time instead (a station file says
//! `profile = "railway29"`), and the handle is one type whatever it runs: a type parameter on
//! it, or a third one on `LogicalNetwork`, would make every user name what only a few choose.
//! So the choice is a value: [`NetProfile`] holds an internal enum over the two profiles and is
//! itself an [`IdProfile`] and a [`FrameClassifier`], answering as the profile it holds (the
//! predefined set's answers are [`Predefined`]'s exactly, so a network built on it runs as
//! before, frame for frame).
//!
//! **The railway 29-bit layout.** Each node-ID has a fixed board address
//! ([`NetProfile::railway_address`]: row 1, cabinet = the node-ID's high nibble, layer 1,
//! board = its low nibble), so that every device of the network (masters, pair members, plain
//! slaves) agrees on it without a table to share: the master's SDO client reaches each node on
//! a channel computed from its node-ID alone. Heartbeat, node guarding, EMCY, NMT, SYNC and the
//! SDO channels are then the railway identifiers of `duocan::profile::railway`; the
//! flying-master frames (0x71–0x76) stay the 11-bit ones CiA 302-2 fixes, as on any network.

use crate::FrameClassifier;
use alloc::boxed::Box;
use duocan::od::DynamicDictionary;
use duocan::profile::railway::{self, DeviceAddress, RailFunction, RailwayProfile};
use duocan::profile::{IdProfile, Predefined, ProfileFrame};
use duocan::sdo::Channel;
use duocan::{Frame, Id, NodeId};

/// The identifier profile of a network the builder builds: the CiA 301 predefined connection
/// set (default) or the railway 29-bit scheme with every node-ID at its
/// [`railway_address`](Self::railway_address).
///
/// ```
/// use duocan::profile::IdProfile;
/// use duocan::{Id, NodeId};
/// use duocan_redundancy::logical::NetProfile;
///
/// let rail = NetProfile::railway29();
/// // Node 0x10's heartbeat: function 0x008 at row 1, cabinet 1, layer 1, board 0.
/// assert_eq!(rail.heartbeat(NodeId::must(0x10)), Id::Extended(0x0081_1100));
/// assert_eq!(NetProfile::predefined().heartbeat(NodeId::must(0x10)), Id::Standard(0x710));
/// assert_eq!(rail.name(), "railway29");
/// ```
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct NetProfile(Scheme);

/// The two profiles.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
enum Scheme {
    #[default]
    Predefined,
    /// Every node-ID 1–127 in the table, at [`NetProfile::railway_address`] (boxed: the
    /// table is a kilobyte, the predefined set nothing).
    Railway(Box<RailwayProfile>),
}

impl NetProfile {
    /// The row of every board address of the railway layout.
    pub const RAILWAY_ROW: u8 = 1;
    /// The layer of every board address of the railway layout.
    pub const RAILWAY_LAYER: u8 = 1;

    /// The CiA 301 predefined connection set (the default).
    #[must_use]
    pub const fn predefined() -> Self {
        NetProfile(Scheme::Predefined)
    }

    /// The railway 29-bit scheme, every node-ID 1–127 at its
    /// [`railway_address`](Self::railway_address).
    #[must_use]
    pub fn railway29() -> Self {
        let mut table = RailwayProfile::new();
        for raw in 1..=127u8 {
            if let Some(node) = NodeId::new(raw) {
                // Distinct in-range board addresses, one per node-ID: the table takes them all.
                let _ = table.add(node, Self::railway_address(node));
            }
        }
        NetProfile(Scheme::Railway(Box::new(table)))
    }

    /// The board address of `node` on the railway layout: row [`RAILWAY_ROW`](Self::RAILWAY_ROW),
    /// cabinet = the node-ID's high nibble, layer [`RAILWAY_LAYER`](Self::RAILWAY_LAYER),
    /// board = its low nibble, port 0.
    #[must_use]
    pub const fn railway_address(node: NodeId) -> DeviceAddress {
        DeviceAddress::board_at(
            Self::RAILWAY_ROW,
            node.raw() >> 4,
            Self::RAILWAY_LAYER,
            node.raw() & 0xF,
        )
    }

    /// The name a station file gives it: `"predefined"` or `"railway29"`.
    #[must_use]
    pub const fn name(&self) -> &'static str {
        match self.0 {
            Scheme::Predefined => "predefined",
            Scheme::Railway(_) => "railway29",
        }
    }

    /// True for the railway 29-bit scheme.
    #[must_use]
    pub const fn is_railway(&self) -> bool {
        matches!(self.0, Scheme::Railway(_))
    }

    /// The railway table (node-ID ↔ board address), on the railway scheme.
    #[must_use]
    pub fn railway(&self) -> Option<&RailwayProfile> {
        match &self.0 {
            Scheme::Predefined => None,
            Scheme::Railway(t) => Some(&**t),
        }
    }

    /// The SDO channel (server 1) of each node, for an SDO client: a plain function of the
    /// node-ID, as the master's client takes it.
    #[must_use]
    pub fn sdo_channels(&self) -> fn(NodeId) -> Channel {
        match self.0 {
            Scheme::Predefined => Channel::predefined,
            Scheme::Railway(_) => railway_channel,
        }
    }

    /// Puts `node`'s communication entries of this profile into `od` (on the railway scheme
    /// SYNC, EMCY and SDO server COB-IDs: `RailwayProfile::comm_objects`, as defaults, so that
    /// resets keep them); the predefined set's are the standard dictionary's already.
    pub fn fit_dictionary(&self, od: &mut DynamicDictionary, node: NodeId) {
        if self.is_railway() {
            for def in RailwayProfile::comm_objects(Self::railway_address(node)) {
                od.upsert(def);
            }
        }
    }
}

/// The SDO channel of `node` on the railway layout.
fn railway_channel(node: NodeId) -> Channel {
    let a = NetProfile::railway_address(node);
    Channel {
        request: railway::id(RailFunction::SdoRequest, a),
        response: railway::id(RailFunction::SdoResponse, a),
    }
}

impl IdProfile for NetProfile {
    fn nmt(&self) -> Id {
        match &self.0 {
            Scheme::Predefined => Predefined.nmt(),
            Scheme::Railway(p) => p.nmt(),
        }
    }
    fn heartbeat(&self, node: NodeId) -> Id {
        match &self.0 {
            Scheme::Predefined => Predefined.heartbeat(node),
            Scheme::Railway(p) => p.heartbeat(node),
        }
    }
    fn guarding(&self, node: NodeId) -> Id {
        match &self.0 {
            Scheme::Predefined => Predefined.guarding(node),
            Scheme::Railway(p) => p.guarding(node),
        }
    }
    fn emcy(&self, node: NodeId) -> Id {
        match &self.0 {
            Scheme::Predefined => Predefined.emcy(node),
            Scheme::Railway(p) => p.emcy(node),
        }
    }
    #[inline]
    fn classify(&self, id: Id, remote: bool) -> Option<ProfileFrame> {
        match &self.0 {
            Scheme::Predefined => Predefined.classify(id, remote),
            Scheme::Railway(p) => p.classify(id, remote),
        }
    }
}

impl FrameClassifier for NetProfile {
    #[inline]
    fn heartbeat_of(&self, frame: &Frame) -> Option<NodeId> {
        match &self.0 {
            Scheme::Predefined => Predefined.heartbeat_of(frame),
            Scheme::Railway(p) => p.heartbeat_of(frame),
        }
    }
    #[inline]
    fn sender(&self, frame: &Frame) -> Option<NodeId> {
        match &self.0 {
            Scheme::Predefined => FrameClassifier::sender(&Predefined, frame),
            Scheme::Railway(p) => FrameClassifier::sender(&**p, frame),
        }
    }
    #[inline]
    fn function(&self, frame: &Frame) -> Option<(NodeId, u32)> {
        match &self.0 {
            Scheme::Predefined => Predefined.function(frame),
            Scheme::Railway(p) => p.function(frame),
        }
    }
    fn same_value(&self, a: &Frame, b: &Frame) -> bool {
        match &self.0 {
            Scheme::Predefined => Predefined.same_value(a, b),
            Scheme::Railway(p) => p.same_value(a, b),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_railway_layout_puts_every_node_id_on_its_own_board() {
        let p = NetProfile::railway29();
        let table = p.railway().map(RailwayProfile::len);
        assert_eq!(table, Some(127));
        let n = NodeId::must(0x51);
        // Function · row 1 · cabinet 5 · layer 1 · board 1 · port 0.
        assert_eq!(p.heartbeat(n), Id::Extended(0x0081_5110));
        assert_eq!(p.emcy(n), Id::Extended(0x0041_5110));
        assert_eq!(p.nmt(), Id::Extended(0));
        let ch = (p.sdo_channels())(n);
        assert_eq!(
            (ch.request, ch.response),
            (Id::Extended(0x0821_5110), Id::Extended(0x0801_5110))
        );
        assert_eq!(p.railway().and_then(|t| t.sdo_channel(n)), Some(ch));
        assert_eq!(
            p.classify(Id::Extended(0x0081_5110), false),
            Some(ProfileFrame::Heartbeat(n))
        );
    }

    #[test]
    fn the_predefined_set_answers_as_predefined() {
        let p = NetProfile::default();
        let n = NodeId::must(0x10);
        assert_eq!(p.name(), "predefined");
        assert_eq!(p.heartbeat(n), Predefined.heartbeat(n));
        assert_eq!((p.sdo_channels())(n), Channel::predefined(n));
        let hb = Frame::new(Id::Standard(0x710), &[5]).unwrap();
        assert_eq!(p.heartbeat_of(&hb), Some(n));
        let mut od = duocan::od::comm::standard_dictionary(0x10, Default::default());
        p.fit_dictionary(&mut od, n);
        use duocan::od::{comm, ObjectDictionary};
        assert_eq!(od.get_u32(comm::SDO_SERVER, 1), Some(0x610));
        assert_eq!(od.get_u32(comm::EMCY_COB_ID, 0), Some(0x90));
    }

    #[test]
    fn build_names_the_predefined_set_and_build_profiled_runs_either() {
        use super::super::{RedundantError, RedundantNetworkBuilder};
        use duocan::od::{comm, ObjectDictionary};
        let b = RedundantNetworkBuilder::default()
            .pair(0x10, 0x50)
            .profile(NetProfile::railway29());
        let e = b.build().unwrap_err();
        assert_eq!(
            e,
            RedundantError::ProfileNotPredefined {
                profile: "railway29"
            }
        );
        assert!(e.to_string().contains("build_profiled()"), "{e}");
        let net = b.build_profiled().unwrap();
        assert!(net.station().link.classifier().is_railway());
        // The master's own dictionary: its SDO server and EMCY on its railway board address.
        let table = RailwayProfile::with(&[(
            NodeId::must(1),
            NetProfile::railway_address(NodeId::must(1)),
        )])
        .unwrap();
        let (rx, _) = table.sdo_cob_ids(NodeId::must(1)).unwrap();
        assert_eq!(net.od().get_u32(comm::SDO_SERVER, 1), Some(rx));
        assert_eq!(rx, 0x2821_0110);
        let on_predefined = RedundantNetworkBuilder::default().pair(0x10, 0x50);
        assert!(on_predefined.build().is_ok());
        assert!(!on_predefined
            .build_profiled()
            .unwrap()
            .station()
            .link
            .classifier()
            .is_railway());
    }
}
