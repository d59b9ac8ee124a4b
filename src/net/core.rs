//! What a [`Network`](super::Network) runs on: a [`NetCore`], behind one trait object.
//!
//! **Why.** The front door (remote nodes, SDO handles, waits, PDO decoding, events) is
//! written once, over whatever sits below it: today's observing node and SDO client on one
//! port or two ([`Network::open`](super::Network::open),
//! [`Network::open_link`](super::Network::open_link)), or another station a crate brings
//! ([`Network::open_core`](super::Network::open_core)). The network stays one type whatever
//! the core is, as it does whatever the [`NetLink`](super::NetLink) is.
//!
//! **The rule.** A core is a [`Device`] whose events are [`CoreEvent`]s. The door feeds it
//! every port input (a frame through [`NetCore::rx`], so that the door sees what the link
//! delivered) and asks it the few things the door's calls need: an SDO client, NMT, the
//! nodes' states, the heartbeat watch, SYNC, its own frames, the port view. Anything
//! else a core offers is reached with [`Network::with_core`](super::Network::with_core).
//!
//! **Memory.** The door keeps what every core shares: the boot-up record, the PDO table, the
//! heartbeat waits, the SDO starts waiting for the client and the LSS master (CiA 305,
//! written once: its requests leave through [`NetCore::send`]). A core keeps only its own
//! station.
//!
//! **CAN FD.** On a CANopen FD network the door's USDO client is the network's own, whatever
//! the core (see [`super::usdo`]), but its frames go through the core's link as the door's
//! classic frames do ([`NetCore::rx_fd`], [`NetCore::send_fd`]): over two buses a request goes
//! out on both and an answer's two copies reach the client once. A core that carries no CAN FD
//! is refused an FD network when it opens.
//!
//! **Order.** The door hands each input to the core first, then decodes what it delivered,
//! then takes the link's own inputs ([`NetCore::poll_input`]) the same way; its own queued
//! events come out before the core's.

use super::error::NetError;
use super::events::NetEvent;
use super::heard_on::HeardOn;
use crate::cia301::nmt::{NmtCommand, NmtTarget};
use crate::cia301::sdo::{RequestId, SdoError};
use crate::frame::cob_id::NodeId;
use crate::frame::instant::Instant;
use crate::frame::{FdFrame, Frame};
use crate::machine::{Device, PortState};
use crate::port::PortInput;
use crate::NmtState;

/// Identities a fastscan plan of the network holds ([`Network::lss`](super::Network::lss)).
pub const LSS_PLAN: usize = 32;

/// The SDO client a core lends the door: a CiA 302 master's client (its sessions on the heap,
/// 8 by default), so that a master core lends its own. The observer's takes transfers up to
/// [`MAX_TRANSFER`](super::MAX_TRANSFER).
pub type NetClient = crate::cia302::master::MasterSdoClient;

/// What a core reports to the door.
#[derive(Clone, Debug)]
#[non_exhaustive]
pub enum CoreEvent {
    /// For the user's event stream.
    Net(NetEvent),
    /// An SDO transfer ended: its request and the data read (empty for a write) or the error.
    Sdo(RequestId, Result<Vec<u8>, SdoError>),
}

/// A station a [`Network`](super::Network) runs on: the door (remote nodes, SDO, waits, PDO
/// decoding, events) is written once over this trait, so the network stays one type whatever
/// the core is. The door feeds the core every port input, a frame through [`NetCore::rx`] so
/// that it decodes what the link delivered, and asks it only what its calls need; anything
/// else a core offers is reached with [`Network::with_core`](super::Network::with_core).
/// Every method is called inside the network's runtime task, with the runtime's `now`.
pub trait NetCore: Device<Event = CoreEvent> + Send + 'static {
    /// A frame from `port` (its receive stamp `at`, if the driver gives one), returning what
    /// the link delivers upward: once per occurrence over two buses, `None` for a copy.
    fn rx(
        &mut self,
        now: Instant,
        port: usize,
        frame: &Frame,
        at: Option<Instant>,
    ) -> Option<Frame>;
    /// A CAN FD frame from `port`, received at `at`, returning what the link delivers upward:
    /// once per occurrence over two buses, `None` for a copy. The default, a core that carries
    /// no CAN FD ([`Device::fd_capable`] false), delivers none.
    fn rx_fd(
        &mut self,
        now: Instant,
        port: usize,
        frame: &FdFrame,
        at: Instant,
    ) -> Option<FdFrame> {
        let _ = (now, port, frame, at);
        None
    }
    /// Hands a CAN FD frame of the network's own (a USDO request of the door's client) to the
    /// link, which puts it on every bus; the core's [`Device::poll_transmit_fd`] gives it back
    /// per port. The default, a core that carries no CAN FD, drops it.
    fn send_fd(&mut self, now: Instant, frame: &FdFrame) {
        let _ = (now, frame);
    }
    /// The next input the link produced itself, as the driver of that port would have handed
    /// it over ([`NetLink::poll_input`](super::NetLink::poll_input)); the door handles it like
    /// a port's.
    fn poll_input(&mut self) -> Option<(usize, PortInput<Instant>)> {
        None
    }
    /// The SDO client transfers start on; an error if the core cannot make requests now.
    fn client(&mut self) -> Result<&mut NetClient, NetError>;
    /// Sends an NMT command; [`NetError::QueueFull`] if it cannot be queued.
    fn nmt(&mut self, now: Instant, cmd: NmtCommand, target: NmtTarget) -> Result<(), NetError>;
    /// The last state heard from `node` and when it was last heard; `None` if never.
    fn remote(&self, node: NodeId) -> Option<(NmtState, Instant)>;
    /// Watches `node`'s heartbeat with a timeout of `ms` (zero: stops watching).
    fn watch_heartbeat(&mut self, now: Instant, node: NodeId, ms: u16) -> Result<(), NetError>;
    /// Produces SYNC every `period_us` µs, or stops producing it (`None`).
    fn set_sync(&mut self, now: Instant, period_us: Option<u32>) -> Result<(), NetError>;
    /// Why the network's LSS master may not start a request now, if it may not: the core may
    /// not send ([`NetCore::send_refused`]), or, for a core that runs an LSS master of its own
    /// (a supervisor replacing boards), that one is busy: LSS has no addresses, so the slaves'
    /// answers to two masters would mix.
    fn lss_refused(&self, now: Instant) -> Option<NetError> {
        (!self.may_send(now)).then(|| self.send_refused())
    }
    /// Queues a frame of the network's own (an RPDO) for every bus of the link, ahead of the
    /// core's next frames; [`NetError::QueueFull`] if too many wait.
    fn send(&mut self, now: Instant, frame: Frame) -> Result<(), NetError>;
    /// True if the core may put frames of its own on the bus (false: listen-only, or a
    /// standby master).
    fn may_send(&self, now: Instant) -> bool;
    /// Why the core may not send now ([`NetCore::may_send`] false), as the caller's error:
    /// [`NetError::ListenOnly`] unless the core knows better (a standby master says
    /// [`NetError::Standby`], so that the user learns which master sends).
    fn send_refused(&self) -> NetError {
        NetError::ListenOnly { node: None }
    }
    /// The state the link keeps for `port`; `None` if it keeps none (the network then shows
    /// what the port's driver last reported).
    fn port_state(&self, port: usize) -> Option<PortState> {
        let _ = port;
        None
    }
    /// On which of the link's buses `node` was heard lately; `None` if the link does not tell.
    fn heard_on(&self, node: NodeId) -> Option<HeardOn> {
        let _ = node;
        None
    }
    /// The core's name in messages (a wrong type asked of
    /// [`Network::with_core`](super::Network::with_core)): its Rust type by default.
    fn type_name(&self) -> &'static str {
        core::any::type_name::<Self>()
    }
    /// The core itself, for [`Network::with_core`](super::Network::with_core)'s downcast.
    fn as_any_mut(&mut self) -> &mut dyn core::any::Any;
}
