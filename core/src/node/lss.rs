//! A device with LSS (CiA 305): the [LSS slave](crate::cia305::slave) and, once the device has
//! a node-ID, the node that runs with it.
//!
//! # The rule
//!
//! A board that arrives without a node-ID (0xFF) has no node: it sends nothing but LSS answers,
//! no boot-up, no heartbeat. The node is built (by the application's `build`, which also boots
//! it) whenever a node-ID becomes active:
//!
//! - at start, when the slave already has one (given, or loaded from its medium);
//! - when the non-configured slave, given a node-ID, is switched back to waiting (CiA 305: it
//!   enters reset-communication by itself);
//! - at a reset-communication or reset-node on the bus that makes a newly configured node-ID
//!   active: the node is built anew for the new node-ID rather than reset with the old one.
//!
//! A node-ID made 0xFF again drops the node: the device is LSS-only until it has one. Every
//! frame goes to both; the slave's events and the node's come out in one stream.
//!
//! # Memory
//!
//! The node is held inline (`Option<N>`); no allocation. Eight slave events wait at most, as in
//! the slave.

use crate::cia305::slave::{LssSlave, LssSlaveEvent, LssSlaveEventKind};
use crate::frame::cob_id::NodeId;
use crate::frame::instant::{earliest, Instant};
use crate::frame::queue::Bounded;
use crate::frame::Frame;
use crate::machine::{LinkRequest, Machine};
use crate::od::parameters::ParameterStorage;
use core::convert::Infallible;

/// What an [`LssNode`] reports.
#[derive(Clone, Debug, PartialEq)]
pub enum LssNodeEvent<E> {
    /// From the LSS slave.
    Lss(LssSlaveEvent),
    /// From the node.
    Node(E),
}

/// An LSS slave and the node it gives a node-ID to (see the [module](self)).
pub struct LssNode<N, F, S: ParameterStorage> {
    lss: LssSlave<S>,
    node: Option<N>,
    build: F,
    events: Bounded<LssSlaveEvent, 8>,
}

impl<N, F, S> LssNode<N, F, S>
where
    N: Machine<LinkCommand = Infallible>,
    F: FnMut(NodeId, Instant) -> N,
    S: ParameterStorage,
{
    /// The device at power-on (`now`): `build(node_id, now)` makes and boots the node, at once if
    /// `lss` has a node-ID.
    pub fn new(now: Instant, lss: LssSlave<S>, mut build: F) -> Self {
        let node = lss.node_id().map(|n| build(n, now));
        LssNode {
            lss,
            node,
            build,
            events: Bounded::new(),
        }
    }
    /// The LSS slave.
    pub fn lss(&self) -> &LssSlave<S> {
        &self.lss
    }
    /// The node, once the device has a node-ID.
    pub fn node(&self) -> Option<&N> {
        self.node.as_ref()
    }
    /// The node, for the application's writes.
    pub fn node_mut(&mut self) -> Option<&mut N> {
        self.node.as_mut()
    }

    /// Acts on what the slave reported, and keeps it for the application.
    fn follow(&mut self) {
        while let Some(e) = self.lss.poll_event() {
            match e.kind {
                LssSlaveEventKind::ResetCommunication(n) => {
                    self.node = Some((self.build)(n, e.at));
                }
                LssSlaveEventKind::NodeIdActivated(n) => {
                    self.node = n.map(|n| (self.build)(n, e.at));
                }
                _ => {}
            }
            self.events.push(e);
        }
    }
}

impl<N, F, S> Machine for LssNode<N, F, S>
where
    N: Machine<LinkCommand = Infallible>,
    F: FnMut(NodeId, Instant) -> N,
    S: ParameterStorage,
{
    type Event = LssNodeEvent<N::Event>;
    type LinkCommand = Infallible;

    fn handle_frame(&mut self, now: Instant, frame: &Frame) {
        // The node first: a reset-communication that changes the node-ID is handled by the old
        // node, then replaced by the new one.
        if let Some(n) = &mut self.node {
            n.handle_frame(now, frame);
        }
        self.lss.handle_frame(now, frame);
        self.follow();
    }
    fn handle_timeout(&mut self, now: Instant) {
        if let Some(n) = &mut self.node {
            n.handle_timeout(now);
        }
        self.lss.handle_timeout(now);
        self.follow();
    }
    fn poll_transmit(&mut self) -> Option<Frame> {
        self.lss
            .poll_transmit()
            .or_else(|| self.node.as_mut()?.poll_transmit())
    }
    fn poll_timeout(&self) -> Option<Instant> {
        earliest(
            self.lss.poll_timeout(),
            self.node.as_ref().and_then(|n| n.poll_timeout()),
        )
    }
    fn poll_event(&mut self) -> Option<Self::Event> {
        if let Some(e) = self.events.pop() {
            return Some(LssNodeEvent::Lss(e));
        }
        self.node.as_mut()?.poll_event().map(LssNodeEvent::Node)
    }
    fn handle_link_request(&mut self, now: Instant, req: LinkRequest) {
        if let Some(n) = &mut self.node {
            n.handle_link_request(now, req);
        }
    }
    // LSS itself stays classic (CiA 305 on an FD network uses classic frames); the node's CAN
    // FD services (USDO) get their frames.
    #[cfg(feature = "fd")]
    fn handle_frame_fd(&mut self, now: Instant, frame: &crate::frame::FdFrame) {
        if let Some(n) = &mut self.node {
            n.handle_frame_fd(now, frame);
        }
    }
    #[cfg(feature = "fd")]
    fn poll_transmit_fd(&mut self) -> Option<crate::frame::FdFrame> {
        self.node.as_mut()?.poll_transmit_fd()
    }
}
