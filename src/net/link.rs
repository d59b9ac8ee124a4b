//! The link a [`Network`](super::Network) runs on, behind one trait object: one port passed
//! through, or two ports merged by a dual-bus layer, so that the network stays one type.
//!
//! **The rule.** The network's observer and SDO client sit on a [`NetLink`]: a
//! [`BusLink`] whose events are already [`NetEvent`]s and that answers two questions the
//! front door asks of it: the state it keeps for each port ([`NetLink::port_state`]) and on
//! which buses a node was heard ([`NetLink::heard_on`]). The stack above it does not know how
//! many wires there are; only [`Network::ports`](super::Network::ports) and
//! [`Network::heard_on`](super::Network::heard_on) say so.
//!
//! **One port.** [`Network::open`](super::Network::open) wraps a [`SinglePort`]: it reports no
//! events and keeps no health, so a port's state is derived from what its driver last
//! reported ([`PortView::state`]), and no node has a reach.
//!
//! **Two ports.** The redundancy crate's dual-bus layer implements the trait (its port health
//! and reachability) and opens the network with [`Network::open_link`](super::Network::open_link).

use super::events::NetEvent;
use super::heard_on::HeardOn;
use crate::frame::cob_id::NodeId;
use crate::frame::instant::Instant;
use crate::machine::{BusLink, Device, ErrorCause, PortState, PortStatus, SinglePort};
use crate::port::{Port, PortCountersSnapshot, PortInput};
use crate::runtime::Runtime;
use core::convert::Infallible;
use core::fmt;

/// A link a [`Network`](super::Network) can run on: a [`BusLink`] reporting [`NetEvent`]s
/// ([`NetEvent::PortState`], [`NetEvent::Reach`]) that takes no commands, and tells the port
/// states and the per-node reach it keeps.
pub trait NetLink: BusLink<Event = NetEvent, Command = Infallible> + Send + 'static {
    /// The state the link keeps for `port` (a dual bus: its port health); `None` if it keeps
    /// none (the network then shows what the port's driver last reported).
    fn port_state(&self, port: usize) -> Option<PortState> {
        let _ = port;
        None
    }
    /// On which of its buses `node` was heard within the link's reach timeout; `None` if the
    /// link does not tell (one port, or a dual-bus mode that listens to one bus at a time).
    fn heard_on(&self, node: NodeId) -> Option<HeardOn> {
        let _ = node;
        None
    }
    /// The next input the link produced itself, as the driver of `port` would have handed it
    /// over: a frame that port read, or the port's status. The network takes these after every
    /// input and timeout of its own and handles each as it came from the port, so that a link
    /// carrying a segment of its own (a simulated station run in the network's own task, its
    /// two buses unable to drift apart) is seen through the same path as real ports. A frame's
    /// stamp is on the network's clock (the instants the link is given): when the frame was on
    /// the segment's wire, no later than the input or timeout after which it is taken.
    fn poll_input(&mut self) -> Option<(usize, PortInput<Instant>)> {
        None
    }
}

/// The network's link, erased: what the door's station runs on.
impl BusLink for Box<dyn NetLink> {
    type Event = NetEvent;
    type Command = Infallible;
    crate::forward_bus_link!(*;
        port_count, handle_rx, handle_rx_at, handle_port_status, send, poll_transmit,
        poll_port_request, handle_timeout, poll_timeout, poll_event, poll_machine_request, fd
    );
}

/// One port: the [`SinglePort`] pass-through, reporting nothing of its own.
#[derive(Debug, Default)]
pub(crate) struct OnePort(SinglePort);

impl OnePort {
    /// The link of a network with `opts`: its port carries CAN FD on a CANopen FD network
    /// ([`NetOptions::with_fd`](super::NetOptions::with_fd)).
    pub fn for_options(opts: &super::NetOptions) -> Self {
        OnePort(if opts.fd.is_some() {
            SinglePort::fd()
        } else {
            SinglePort::new()
        })
    }
}

impl BusLink for OnePort {
    type Event = NetEvent;
    type Command = Infallible;
    fn port_count(&self) -> usize {
        1
    }
    crate::forward_bus_link!(0; handle_rx, handle_port_status, send, poll_transmit, fd);
    fn handle_timeout(&mut self, _: Instant) {}
    fn poll_timeout(&self) -> Option<Instant> {
        None
    }
    fn poll_event(&mut self) -> Option<NetEvent> {
        None
    }
}

impl NetLink for OnePort {}

/// The ports a network runs on, in order (port 0 first): one [`Port`], or a pair `(P1, P2)` of
/// possibly different types for a two-port link.
pub trait NetPorts {
    /// How many ports.
    fn count(&self) -> usize;
    /// Their names, joined with a comma (the runtime's name).
    fn label(&self) -> String;
    /// Adds the ports to `rt`, in order.
    fn attach<D>(self, rt: Runtime<D>) -> Runtime<D>
    where
        D: Device + Send + 'static,
        D::Event: Clone + Send + fmt::Debug + 'static;
}

impl<P: Port> NetPorts for P {
    fn count(&self) -> usize {
        1
    }
    fn label(&self) -> String {
        self.name().to_owned()
    }
    fn attach<D>(self, rt: Runtime<D>) -> Runtime<D>
    where
        D: Device + Send + 'static,
        D::Event: Clone + Send + fmt::Debug + 'static,
    {
        rt.port(self)
    }
}

impl<P1: Port, P2: Port> NetPorts for (P1, P2) {
    fn count(&self) -> usize {
        2
    }
    fn label(&self) -> String {
        format!("{},{}", self.0.name(), self.1.name())
    }
    fn attach<D>(self, rt: Runtime<D>) -> Runtime<D>
    where
        D: Device + Send + 'static,
        D::Event: Clone + Send + fmt::Debug + 'static,
    {
        rt.port(self.0).port(self.1)
    }
}

/// One port of a network, as [`Network::ports`](super::Network::ports) shows it.
#[derive(Clone, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub struct PortView {
    /// Its index (0 = bus 1).
    pub index: usize,
    /// Its name (`can0`, `udp`, `sim-bus1`).
    pub name: String,
    /// Its state. On a dual bus, the layer's port health: `"ok"`, `"suspect"`, `"failed"` or
    /// `"recovering"`. On one port, what its driver last reported: `"ok"` (nothing, up again,
    /// or a frame sent since), `"down"`, `"bus-off"`, `"error passive"` or `"error warning"`.
    pub state: &'static str,
    /// On a dual bus, the layer's port health (what `state` names); `None` on one port.
    pub health: Option<PortState>,
    /// The last error its driver reported, if any.
    pub last_error: Option<ErrorCause>,
    /// Its driver's counters (frames received and sent, failures).
    pub counters: PortCountersSnapshot,
}

/// What the door remembers of a port's driver reports: the state of a link that keeps none.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct DriverState {
    pub state: &'static str,
    pub last_error: Option<ErrorCause>,
}

impl Default for DriverState {
    fn default() -> Self {
        DriverState {
            state: "ok",
            last_error: None,
        }
    }
}

impl DriverState {
    /// Takes one report of the driver. A momentary error (a CRC error, a frame not
    /// acknowledged) changes no state: only the controller's own states do.
    pub fn on(&mut self, status: PortStatus) {
        self.state = match status {
            PortStatus::Down(c) => {
                self.last_error = Some(c);
                "down"
            }
            PortStatus::Up | PortStatus::Error(ErrorCause::Restarted) => "ok",
            PortStatus::Error(c) => {
                self.last_error = Some(c);
                match c {
                    ErrorCause::BusOff => "bus-off",
                    ErrorCause::ErrorPassive => "error passive",
                    ErrorCause::ErrorWarning => "error warning",
                    _ => self.state,
                }
            }
            PortStatus::TxFailed(c) => {
                self.last_error = Some(c);
                self.state
            }
            // A frame went out: the controller sends again (a down port sends nothing).
            PortStatus::TxOk if self.state != "down" => "ok",
            PortStatus::TxOk => self.state,
        };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_single_port_state_follows_the_controller_not_momentary_errors() {
        let mut s = DriverState::default();
        s.on(PortStatus::Error(ErrorCause::Crc));
        assert_eq!((s.state, s.last_error), ("ok", Some(ErrorCause::Crc)));
        s.on(PortStatus::Error(ErrorCause::BusOff));
        assert_eq!(s.state, "bus-off");
        s.on(PortStatus::TxOk);
        assert_eq!(s.state, "ok");
        s.on(PortStatus::Down(ErrorCause::InterfaceDown));
        s.on(PortStatus::TxOk);
        assert_eq!(s.state, "down", "a down port sends nothing");
        s.on(PortStatus::Up);
        assert_eq!(
            (s.state, s.last_error),
            ("ok", Some(ErrorCause::InterfaceDown))
        );
    }
}
