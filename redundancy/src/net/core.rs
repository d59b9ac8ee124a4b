//! The redundant master as the core of duocan's front door: [`MasterCore`] makes a
//! [`LogicalNetwork`] a [`NetCore`], so that [`RedundantNetwork`](super::RedundantNetwork) is a
//! `duocan::net::Network` (remote nodes, SDO, events, waits written once, in duocan) and only
//! what redundancy adds is written here.
//!
//! **What the door gets.** The master's own SDO client while this master is active (on a
//! standby one, [`NetError::Standby`]: two clients on one server channel would corrupt each
//! other's transfers); NMT through the master, so that its view of the slaves follows; the
//! states the master's node heard; the dual-bus layer's port health and reach. The station's
//! events become the door's ([`NetEvent`]) where the door has the word, and
//! [`RedundantEvent`]s ([`NetEvent::Ext`]) where only redundancy has it.
//!
//! **Process data.** The door decodes TPDOs from what the dual-bus layer delivers, so each
//! arrives once whether one bus carries it or two. The application's own frames (RPDOs) go to
//! the layer like the master's and so onto both buses, and only while this master may command:
//! a standby master's application must not drive the outputs the active one drives
//! ([`NetError::Standby`]).
//!
//! **Heartbeats.** The master guards its slaves (0x1F81, the pair members among them) with
//! the 0x1016 entries it configured and reports a loss as [`RedundantEvent::Master`] (the
//! master's `SlaveLost`, with its CiA 302-2 status); watching one of those through the door
//! changes nothing. Any other node gets an entry of the door's in the master's 0x1016, on a
//! standby master as on the active one, and its loss is the door's
//! [`NetEvent::HeartbeatLost`]. States and boot-up waits are the door's, over what the
//! master's node heard.
//!
//! **CAN FD.** On a CANopen FD network (the builder's `with_fd`) the door's USDO client sends
//! its requests through the station's dual-bus layer, onto both buses, and takes each answer
//! once as the layer delivers it; the supervisor's master serves USDO for its own dictionary
//! through the same layer. The client sends only while this master may command, as the door's
//! other frames.
//!
//! **SYNC.** `start_sync` and `stop_sync` change the SYNC period the builder's `.sync(…)`
//! set, and nothing else: SYNC stays the flying master's, produced by the active master
//! alone, so a standby master takes the period and produces at it once it takes over.

use super::dual_link::heard_on;
use super::events::RedundantEvent;
use crate::logical::{
    LogicalNetwork, NetProfile, NetworkError, NetworkEvent, NetworkEventKind as K,
};
use crate::supervisor::pairs::PairsEvent;
use crate::SupervisorEvent;
use alloc::boxed::Box;
use alloc::string::ToString;
use duocan::cia305::LssError;
use duocan::frame::FdFrame;
use duocan::machine::{BusLink, Device, PortState, StationEvent};
use duocan::master::MasterError;
use duocan::net::{CoreEvent, ExtEvent, HeardOn, NetClient, NetCore, NetError, NetEvent};
use duocan::nmt::NmtTarget;
use duocan::od::{comm, DynamicDictionary, ObjectDictionary};
use duocan::runtime::SdoEvents;
use duocan::AbortCode;
use duocan::NodeEventKind;
use duocan::{Frame, Instant, NmtCommand, NmtState, NodeId};

/// The network the core runs: on the profile the builder was given, a value
/// ([`NetProfile`]), so that the handle is one type whatever it runs.
pub(super) type Net = LogicalNetwork<DynamicDictionary, NetProfile>;

/// A [`LogicalNetwork`] as the core of a `duocan::net::Network` (boxed: the network is some
/// 160 kB).
pub(crate) struct MasterCore {
    pub(super) net: Box<Net>,
    /// The nodes whose 0x1016 entry the door wrote (bit n = node-ID n): their heartbeat
    /// losses are the door's [`NetEvent::HeartbeatLost`], and only their entries does it
    /// change again.
    watched: u128,
}

impl MasterCore {
    pub(super) fn new(net: Box<Net>) -> Self {
        MasterCore { net, watched: 0 }
    }
    fn is_watched(&self, node: NodeId) -> bool {
        self.watched & (1 << node.raw()) != 0
    }
    /// The door's event of a heartbeat the door watches going or coming back.
    fn watched_heartbeat(&self, e: &NetworkEvent) -> Option<CoreEvent> {
        let K::Other(StationEvent::Machine(SupervisorEvent::Node(n))) = &e.kind else {
            return None;
        };
        let at = e.at;
        let net = match n.kind {
            NodeEventKind::HeartbeatTimeout { node, last } if self.is_watched(node) => {
                NetEvent::HeartbeatLost { node, last, at }
            }
            NodeEventKind::HeartbeatResumed { node } if self.is_watched(node) => {
                NetEvent::HeartbeatResumed { node, at }
            }
            _ => return None,
        };
        Some(CoreEvent::Net(net))
    }
}

/// The door's event of a port's change of health or of a node's reach, from the network's
/// event or, through `typed`, from the dual-bus layer's.
pub(super) fn link_event(kind: &K, at: Instant) -> Option<NetEvent> {
    Some(match *kind {
        K::Port {
            port,
            from,
            to,
            reason,
        } => NetEvent::PortState {
            port,
            from,
            to,
            reason,
            at,
        },
        K::Reach { node, heard } => NetEvent::Reach {
            node,
            heard: heard.into(),
            at,
        },
        _ => return None,
    })
}

/// The door's event of a network event, if the stream shows it.
pub(super) fn core_event(e: NetworkEvent) -> Option<CoreEvent> {
    let at = e.at;
    if let Some(net) = link_event(&e.kind, at) {
        return Some(CoreEvent::Net(net));
    }
    let net = match e.kind {
        K::NodeBooted { node } => NetEvent::BootUp { node, at },
        K::NodeState { node, from, to } => NetEvent::State { node, from, to, at },
        K::Emcy { node, msg } => NetEvent::Emcy { node, msg, at },
        K::Sdo(s) => {
            let (id, r) = s.sdo_result()?;
            return Some(CoreEvent::Sdo(id, r));
        }
        K::Other(StationEvent::Machine(SupervisorEvent::Pairs(PairsEvent::Missing {
            node,
            since,
            ..
        }))) => NetEvent::NotHeard { node, since, at },
        kind => NetEvent::Ext(ExtEvent::new(RedundantEvent::of(at, kind)?)),
    };
    Some(CoreEvent::Net(net))
}

impl Device for MasterCore {
    type Event = CoreEvent;

    duocan::forward_device_to!(net);
    fn fd_capable(&self) -> bool {
        self.net.fd_capable()
    }
    fn handle_rx_fd(&mut self, now: Instant, port: usize, frame: &FdFrame, at: Instant) {
        self.net.handle_rx_fd(now, port, frame, at);
    }
    fn poll_transmit_fd(&mut self) -> Option<(usize, FdFrame)> {
        self.net.poll_transmit_fd()
    }
    fn poll_event(&mut self) -> Option<CoreEvent> {
        loop {
            let e = self.net.poll_event()?;
            if let Some(e) = self.watched_heartbeat(&e).or_else(|| core_event(e)) {
                return Some(e);
            }
        }
    }
}

impl NetCore for MasterCore {
    fn rx(
        &mut self,
        now: Instant,
        port: usize,
        frame: &Frame,
        at: Option<Instant>,
    ) -> Option<Frame> {
        // The supervised station is a station: what its dual-bus layer delivers, once.
        self.net
            .station_mut()
            .handle_rx_delivered(now, port, frame, at)
    }
    /// On a CANopen FD network: through the station as a classic frame goes (the layer merges
    /// the two copies, the supervisor's master serves USDO), the delivered frame to the door's
    /// USDO client.
    fn rx_fd(
        &mut self,
        now: Instant,
        port: usize,
        frame: &FdFrame,
        at: Instant,
    ) -> Option<FdFrame> {
        self.net
            .station_mut()
            .handle_rx_fd_delivered(now, port, frame, at)
    }
    /// The door's USDO request goes to the dual-bus layer as the master's frames do: onto both
    /// buses (the healthy ones). The door sends only while this master may command.
    fn send_fd(&mut self, now: Instant, frame: &FdFrame) {
        BusLink::send_fd(&mut self.net.station_mut().link, now, frame);
    }
    fn client(&mut self) -> Result<&mut NetClient, NetError> {
        let sup = self.net.station_mut().sup_mut();
        if !sup.is_active() {
            return Err(NetError::Standby { node: None });
        }
        Ok(sup.sdo_mut())
    }
    fn nmt(&mut self, now: Instant, cmd: NmtCommand, target: NmtTarget) -> Result<(), NetError> {
        self.net.nmt(now, cmd, target).map_err(|e| match e {
            NetworkError::Nmt(e) => NetError::from(e),
            NetworkError::Standby => NetError::Standby { node: None },
            e => NetError::Argument(e.to_string()),
        })
    }
    fn remote(&self, node: NodeId) -> Option<(NmtState, Instant)> {
        let v = self.net.supervisor().node().remote(node)?;
        Some((v.state, v.seen))
    }
    /// The master guards its slaves itself (0x1F81 bit 0: the pair members among them) with
    /// the 0x1016 entries it configured, and reports a loss as [`RedundantEvent::Master`];
    /// for those, and for a node another entry already names (a peer master the flying
    /// master watches), this is `Ok` and changes nothing. For any other node the door writes
    /// an entry of its own into the master's 0x1016 (the sub naming it, else sub node-ID if
    /// free, else the first free one), standby or active alike: the entries the master uses
    /// stay as they are. A table without a free entry is [`NetError::Master`].
    fn watch_heartbeat(&mut self, now: Instant, node: NodeId, ms: u16) -> Result<(), NetError> {
        let ours = self.is_watched(node);
        let sup = self.net.station_mut().sup_mut();
        if sup.master().slave(node).assignment.is_slave() {
            return Ok(());
        }
        let od = sup.node().od();
        let count = od
            .get_u32(comm::HEARTBEAT_CONSUMER, 0)
            .unwrap_or(0)
            .min(127) as u8;
        let value = |sub: u8| od.get_u32(comm::HEARTBEAT_CONSUMER, sub);
        let naming = (1..=count).find(|s| value(*s).is_some_and(|v| (v >> 16) as u8 == node.raw()));
        let free = |sub: u8| value(sub).is_some_and(|v| v & 0xFFFF == 0 || v >> 16 & 0xFF == 0);
        let sub = match naming {
            Some(_) if !ours => return Ok(()),
            Some(s) => s,
            None if ms == 0 => return Ok(()),
            None => {
                let own = (node.raw() <= count && free(node.raw())).then_some(node.raw());
                own.or_else(|| (1..=count).find(|s| free(*s)))
                    .ok_or(NetError::Master(MasterError::Refused {
                        index: comm::HEARTBEAT_CONSUMER,
                        sub: 0,
                        code: AbortCode::NO_RESOURCE,
                    }))?
            }
        };
        let v = if ms == 0 {
            0
        } else {
            (u32::from(node.raw()) << 16) | u32::from(ms)
        };
        sup.node_mut()
            .write(now, comm::HEARTBEAT_CONSUMER, sub, &v.to_le_bytes())
            .map_err(|code| {
                NetError::Master(MasterError::Refused {
                    index: comm::HEARTBEAT_CONSUMER,
                    sub,
                    code,
                })
            })?;
        if ms == 0 {
            self.watched &= !(1 << node.raw());
        } else {
            self.watched |= 1 << node.raw();
        }
        Ok(())
    }
    /// Changes the SYNC period only ([`Supervisor::set_sync_period`](crate::Supervisor::set_sync_period)):
    /// SYNC stays the flying master's, produced by the active master alone; a standby master
    /// takes the period and produces nothing until it takes over.
    fn set_sync(&mut self, now: Instant, period_us: Option<u32>) -> Result<(), NetError> {
        let period = period_us.map(|us| duocan::Duration::from_micros(u64::from(us)));
        self.net
            .station_mut()
            .sup_mut()
            .set_sync_period(now, period)
            .map_err(|code| {
                NetError::Master(MasterError::Refused {
                    index: comm::SYNC_PERIOD,
                    sub: 0,
                    code,
                })
            })
    }
    /// The frame goes to the dual-bus layer as the master's own frames do: it fans it out
    /// onto both buses (the healthy ones), behind what the layer already holds. Only while
    /// this master may command (active, not suspended): a standby master's application must
    /// not drive the outputs the active one drives. A copy a port's full queue drops is
    /// counted by the layer (`tx_dropped`), as for every frame of the master's.
    fn send(&mut self, now: Instant, frame: Frame) -> Result<(), NetError> {
        if !self.may_send(now) {
            return Err(self.send_refused());
        }
        let station = self.net.station_mut();
        if frame.id() == duocan::cia305::codec::MASTER_TO_SLAVE {
            // The door's LSS request: the supervisor's board replacement waits after it.
            station.machine.lss_heard(now);
        }
        station.link.send(now, &frame);
        Ok(())
    }
    fn may_send(&self, now: Instant) -> bool {
        self.net.supervisor().may_command(now)
    }
    fn send_refused(&self) -> NetError {
        NetError::Standby { node: None }
    }
    /// The door's LSS master waits for the supervisor's (board replacement) to finish: the
    /// slaves answer whoever asked on the one LSS identifier, so two masters' answers would
    /// mix.
    fn lss_refused(&self, now: Instant) -> Option<NetError> {
        if !self.may_send(now) {
            return Some(self.send_refused());
        }
        (!self.net.supervisor().lss_idle()).then_some(NetError::Lss(LssError::Busy))
    }
    fn port_state(&self, port: usize) -> Option<PortState> {
        (port < 2).then(|| self.net.station().link.port_state(port))
    }
    fn heard_on(&self, node: NodeId) -> Option<HeardOn> {
        heard_on(&self.net.station().link, node)
    }
    fn type_name(&self) -> &'static str {
        "redundant master"
    }
    fn as_any_mut(&mut self) -> &mut dyn core::any::Any {
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use duocan::machine::{ErrorCause, PortReason};

    #[test]
    fn a_port_change_is_the_doors_and_names_its_reason() {
        let e = core_event(NetworkEvent {
            at: Instant::from_millis(7),
            kind: K::Port {
                port: 0,
                from: PortState::Ok,
                to: PortState::Failed,
                reason: PortReason::Down(ErrorCause::InterfaceDown),
            },
        });
        let Some(CoreEvent::Net(e)) = e else {
            panic!("{e:?}")
        };
        assert!(e.is_failover());
        assert_eq!(e.to_string(), "bus 1: failed (port down: interface down)");
        assert_eq!(e.at(), Some(Instant::from_millis(7)));
    }

    #[test]
    fn a_lost_slave_is_redundancys_own_event() {
        let node = NodeId::must(0x12);
        let e = core_event(NetworkEvent {
            at: Instant::from_millis(7),
            kind: K::NodeLost {
                node,
                status: duocan::master::ErrorStatus::E,
            },
        });
        let Some(CoreEvent::Net(e)) = e else {
            panic!("{e:?}")
        };
        assert_eq!(
            e.ext::<RedundantEvent>(),
            Some(&RedundantEvent::Master(duocan::master::MasterEvent {
                at: Instant::from_millis(7),
                kind: duocan::master::MasterEventKind::SlaveLost {
                    node,
                    status: duocan::master::ErrorStatus::E
                },
            }))
        );
        assert_eq!(e.node(), Some(node));
        assert_eq!(
            e.to_string(),
            "node 0x12: lost, error status E: heartbeat lost"
        );
    }

    #[test]
    fn what_the_stream_does_not_show_is_dropped() {
        let e = core_event(NetworkEvent {
            at: Instant::ZERO,
            kind: K::PdoReceived { pdo: 1 },
        });
        assert!(e.is_none(), "{e:?}");
    }
}
