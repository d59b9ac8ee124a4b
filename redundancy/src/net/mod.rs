//! The front door of a redundant network (feature `tokio`): the network a
//! [`RedundantNetworkBuilder`] describes, running on two ports, as duocan's own front door.
//! A [`RedundantNetwork`] *is* a `duocan::net::Network` (it dereferences to one): remote nodes,
//! SDO, NMT, states and the event stream are that network's, and this module adds only what
//! redundancy has (the master role, the pairs, the status table, a forced switch-over).
//!
//! ```
//! use std::time::Duration;
//! use duocan_redundancy::net::{RedundantEvent, RedundantNetwork};
//! use duocan_redundancy::RedundantError;
//!
//! // The simulated station runs on tokio's paused clock here (tokio's `test-util`): its
//! // seconds pass at once and every run is the same. A plain #[tokio::main] runs it in real time.
//! #[tokio::main(flavor = "current_thread", start_paused = true)]
//! async fn main() -> Result<(), RedundantError> {
//!     let ms = Duration::from_millis;
//!     // "sim-pairs": two simulated buses with the declared pairs and peers on them; or "can0,can1".
//!     let net = RedundantNetwork::builder()
//!         .node_id(1)
//!         .heartbeat(ms(50))
//!         .master_timeout(ms(200))
//!         .pair(0x10, 0x50)
//!         .open_named("sim-pairs")?;
//!     let mut events = net.events();
//!     // Active once the power-on negotiation is over and the boards are configured.
//!     while let Some(e) = events.next().await {
//!         if matches!(e.ext(), Some(RedundantEvent::PairRole(_))) {
//!             break;
//!         }
//!     }
//!     // SDO to any node, through whichever bus works.
//!     let vendor: u32 = net.node(0x10).sdo().read(0x1018, 1).await?;
//!     assert_eq!(vendor, duocan::net::SIM_VENDOR);
//!     net.close().await;
//!     Ok(())
//! }
//! ```
//!
//! Underneath is a [`LogicalNetwork`](crate::LogicalNetwork) as the network's core (`duocan::net::NetCore`): the
//! door's SDO transfers run on the master's own client, while this master is active (on a
//! standby one they are `NetError::Standby`), its NMT commands go through the master, and its
//! events come out in duocan's flat stream: boot-ups, states, EMCY, port health, reach and
//! members never heard as duocan's `NetEvent`s, and pair and master roles, the master's boot
//! process and lost slaves, refused members, LSS and discrepancies as [`RedundantEvent`]s
//! (`NetEvent::Ext`), each carrying its layer's own event type. The door's calls
//! fail with `duocan::net::NetError`; the builder's and this module's with [`RedundantError`],
//! which takes a `NetError` with `?`.
//!
//! A tool that must not become a master on somebody's network opens duocan's plain front door
//! on the two buses instead: [`open_dual`] / [`open_dual_named`] ([`DualLink`], the dual-bus
//! layer as `duocan::net::Network`'s link); `open_dual_named("sim-station")` runs it on a
//! simulated redundant station:
//!
//! | node | what | state |
//! | --- | --- | --- |
//! | 0x01 | a redundant master (supervisor, flying master) | active master |
//! | 0x02 | its peer master, the same settings | standby master |
//! | 0x10 / 0x50, 0x11 / 0x51 | two A/B board pairs ([`SIM_PAIRS`]) | A active (operational), B standby (pre-operational) |
//! | 0x05, 0x06, 0x07 | plain slaves ([`SIM_SLAVES`]): `duocan::net`'s simulated node and a read-write DOMAIN [`SIM_DOMAIN`] of up to [`SIM_DOMAIN_SIZE`] bytes; [`SIM_PROGRAM_NODE`] takes program download (identification after start: `duocan::cia302::program::image_id` of the image) | pre-operational |
//! | none (0xFF) | two boards that arrive without a node-ID ([`SIM_LSS_SERIALS`], identity [`sim_lss_address`]): silent but for LSS (CiA 305) until an LSS master gives them a node-ID, then they boot as the simulated node with it (one on a rig of one's own: [`sim_lss_board`]) | non-configured |
//!
//! `"sim-station:faults"` repeats a script every [`SIM_FAULT_PERIOD`]: at [`SIM_FAULT_BUS_CUT`] into
//! it the network's connection to bus 1 is cut (back at [`SIM_FAULT_BUS_BACK`]), at
//! [`SIM_FAULT_MEMBER_STOPS`] the active member of the first pair stops (back at
//! [`SIM_FAULT_MEMBER_BACK`]), at [`SIM_FAULT_MASTER_STOPS`] the active master stops (back at
//! [`SIM_FAULT_MASTER_BACK`]).
//!
//! The station runs inside the network's own task, on its clock: its buses carry each frame
//! for its wire time at [`SIM_BIT_RATE`], and the two copies of a frame reach every device
//! together, however loaded the machine (two simulated devices each run by tasks of their own
//! would see them as far apart as the tasks were scheduled).

mod core;
mod dual_link;
mod events;
mod sim_pairs;
mod sim_station;

pub use dual_link::{open_dual, open_dual_named, open_dual_with, DualLink};
pub use events::RedundantEvent;
pub use sim_pairs::{SIM_BUS_FAILS, SIM_B_BOOTS, SIM_END, SIM_MEMBER_FAILS, SIM_PEERS_FAIL};
pub use sim_station::{
    sim_lss_address, sim_lss_board, SimLssBoard, SimLssBuild, SIM_BIT_RATE, SIM_DOMAIN,
    SIM_DOMAIN_SIZE, SIM_FAULT_BUS_BACK, SIM_FAULT_BUS_CUT, SIM_FAULT_MASTER_BACK,
    SIM_FAULT_MASTER_STOPS, SIM_FAULT_MEMBER_BACK, SIM_FAULT_MEMBER_STOPS, SIM_FAULT_PERIOD,
    SIM_LSS_PRODUCT, SIM_LSS_REVISION, SIM_LSS_SERIALS, SIM_PAIRS, SIM_PROGRAM_NODE, SIM_SLAVES,
};

use self::core::{MasterCore, Net};
use crate::logical::{RedundantError, RedundantNetworkBuilder};
use crate::pair::{Member, PairId};
use crate::supervisor::flying_master::MasterRole;
use alloc::boxed::Box;
use alloc::string::{String, ToString};
use alloc::vec::Vec;
use duocan::master::SlaveView;
use duocan::net::{Awaited, NetError, NetEvent, NetOptions, Network};
use duocan::port::Port;
use duocan::{Instant, NmtState, NodeId};

/// A redundant network on two ports: duocan's front door ([`Network`], which it dereferences
/// to: `net.node(5).sdo()`, `net.events()`, `net.nmt_all(…)`, `net.close()`) run by a
/// redundant master, with what only redundancy has. Cheap to clone; the network runs until
/// [`Network::close`].
#[derive(Clone)]
pub struct RedundantNetwork {
    net: Network,
}

impl ::core::ops::Deref for RedundantNetwork {
    type Target = Network;
    fn deref(&self) -> &Network {
        &self.net
    }
}

impl RedundantNetwork {
    /// The builder, every setting at its default (see [`RedundantNetworkBuilder`]).
    pub fn builder() -> RedundantNetworkBuilder {
        RedundantNetworkBuilder::default()
    }

    fn start<P1: Port, P2: Port>(
        net: Box<Net>,
        ports: (P1, P2),
        fd: Option<u8>,
    ) -> Result<RedundantNetwork, RedundantError> {
        let name = ports.0.name().to_string();
        let core = Box::new(MasterCore::new(net));
        let opts = match fd.and_then(NodeId::new) {
            Some(client) => NetOptions::default().with_fd(client),
            None => NetOptions::default(),
        };
        match Network::open_core(core, ports, opts) {
            Ok(net) => Ok(RedundantNetwork { net }),
            Err(NetError::Port(why)) => Err(RedundantError::Port { port: 0, name, why }),
            Err(e) => Err(e.into()),
        }
    }

    /// Runs `f` on the master inside the network's runtime.
    async fn call<R, F>(&self, f: F) -> Result<R, RedundantError>
    where
        F: FnOnce(&mut Net, Instant) -> R + Send + 'static,
        R: Send + 'static,
    {
        let r = self
            .net
            .with_core(move |c: &mut MasterCore, now| f(&mut c.net, now));
        Ok(r.await?)
    }

    /// This master's role (active, standby, negotiating…).
    pub async fn role(&self) -> Result<MasterRole, RedundantError> {
        self.call(|n, _| n.role()).await
    }

    /// The active member of every pair, in the order declared.
    pub async fn active_members(&self) -> Result<Vec<(PairId, Option<Member>)>, RedundantError> {
        self.call(|n, _| n.pairs().map(|(id, p)| (id, p.active)).collect())
            .await
    }

    /// The node-ID of the board that runs in the pair whose A member is node `a`: the member
    /// this master (active) started and heard operational, waiting at most `timeout` for one.
    /// A pair's process data come from whichever of its boards runs, and which one that is
    /// depends on which booted first and on every failover since. No pair with A member `a`:
    /// [`NetError::NoSuchNode`]; none running in time: [`NetError::Timeout`] (awaiting
    /// operational, for node `a`).
    pub async fn running_board(
        &self,
        a: u8,
        timeout: std::time::Duration,
    ) -> Result<u8, RedundantError> {
        let node = NodeId::new(a).ok_or(NetError::NoSuchNode(a))?;
        let until = tokio::time::Instant::now() + timeout;
        // Listening before the first look: a change between the look and the wait is not missed.
        let mut events = self.events();
        loop {
            let running = self
                .call(move |n, _| {
                    let (_, p) = n.pairs().find(|(_, p)| p.spec.a == node)?;
                    Some(p.active.and_then(|m| {
                        let s = p.member(m);
                        (s.nmt == Some(NmtState::Operational)).then_some(s.node.raw())
                    }))
                })
                .await?
                .ok_or(NetError::NoSuchNode(a))?;
            if let Some(id) = running {
                return Ok(id);
            }
            // The pair table changes with what also reaches the stream (a member's state, a
            // pair's role): look again after such an event, not on a timer.
            loop {
                match tokio::time::timeout_at(until, events.next()).await {
                    Err(_) => {
                        return Err(NetError::Timeout {
                            node,
                            awaited: Awaited::State(NmtState::Operational),
                            after: timeout,
                        }
                        .into())
                    }
                    Ok(None) => return Err(NetError::Closed.into()),
                    Ok(Some(
                        NetEvent::State { .. }
                        | NetEvent::BootUp { .. }
                        | NetEvent::Ext(_)
                        | NetEvent::Lagged(_),
                    )) => break,
                    Ok(Some(_)) => {}
                }
            }
        }
    }

    /// The status table (ports, master role, pairs, slaves), as text.
    pub async fn status(&self) -> Result<String, RedundantError> {
        self.call(|n, now| n.status(now).to_string()).await
    }

    /// What the master knows of node `id` (1–127): its last state heard, whether it is lost,
    /// its boot process. A node-ID outside 1–127 is [`NetError::NoSuchNode`].
    pub async fn slave(&self, id: u8) -> Result<SlaveView, RedundantError> {
        let node = NodeId::new(id).ok_or(NetError::NoSuchNode(id))?;
        self.call(move |n, _| n.slave(node)).await
    }

    /// Makes `to` the active member of `pair` (active master only).
    pub async fn switch_over(&self, pair: PairId, to: Member) -> Result<(), RedundantError> {
        self.call(move |n, now| n.switch_over(now, pair, to))
            .await?
            .map_err(RedundantError::from)
    }

    /// Runs `f` on the [`LogicalNetwork`](crate::LogicalNetwork) inside the runtime, for what the handle does not
    /// cover (audit export, PDO values, the master's dictionary).
    pub async fn with<R, F>(&self, f: F) -> Result<R, RedundantError>
    where
        F: FnOnce(&mut Net, Instant) -> R + Send + 'static,
        R: Send + 'static,
    {
        self.call(f).await
    }
}

impl RedundantNetworkBuilder {
    /// Opens the network on two ports (port 1 = bus 1): builds it on its
    /// [`profile`](RedundantNetworkBuilder::profile) and runs it under the duocan runtime.
    /// Must be called inside a tokio runtime.
    pub fn open<P1: Port, P2: Port>(
        &self,
        bus1: P1,
        bus2: P2,
    ) -> Result<RedundantNetwork, RedundantError> {
        RedundantNetwork::start(self.build_profiled()?, (bus1, bus2), self.fd_client())
    }
    /// Opens the network by name:
    ///
    /// - `sim-pairs`: two simulated buses carrying the declared pairs (`duocan::net`'s simulated node, with its process data, on the builder's [`profile`](RedundantNetworkBuilder::profile)) and
    ///   peer masters (simulated redundant masters with the same settings), and a script of
    ///   faults: bus 1 of this master fails at [`SIM_BUS_FAILS`], the peer masters stop at
    ///   [`SIM_PEERS_FAIL`] (a standby master takes over), the active member of every pair
    ///   stops at [`SIM_MEMBER_FAILS`] (the other one takes over), and the simulation ends at
    ///   [`SIM_END`] (the network closes, event streams end);
    /// - `sim-pairs:quiet`: the same buses, pairs and peers without the faults, running until
    ///   the network is closed;
    /// - `sim-pairs:failover`: the faults of `sim-pairs`, timed from the moment every pair has a
    ///   running board once the B boards are on (not from the opening: a station's racks may take long to come up),
    ///   after which the plant runs on what is left (bus 1 cut, the peers and the members that
    ///   ran stopped) until the network is closed;
    /// - `A,B`: SocketCAN interfaces A (bus 1) and B (bus 2), such as `can0,can1` (feature
    ///   `socketcan`, Linux).
    pub fn open_named(&self, name: &str) -> Result<RedundantNetwork, RedundantError> {
        match name {
            "sim-pairs" => return sim_pairs::open(self, sim_pairs::Plant::Script),
            "sim-pairs:quiet" => return sim_pairs::open(self, sim_pairs::Plant::Quiet),
            "sim-pairs:failover" => return sim_pairs::open(self, sim_pairs::Plant::Failover),
            _ => {}
        }
        if name == "sim" || name.starts_with("sim-") || name.starts_with("sim:") {
            return Err(RedundantError::Port {
                port: 0,
                name: name.into(),
                why: alloc::format!(
                    "a redundant network on simulated buses is sim-pairs (or sim-pairs:quiet, \
                     sim-pairs:failover); {}",
                    duocan::net::SIM_NAMES
                ),
            });
        }
        let Some((a, b)) = name.split_once(',') else {
            return Err(RedundantError::Port {
                port: 0,
                name: name.into(),
                why: "a redundant network needs two interfaces: name them as can0,can1 (or use \"sim-pairs\")".into(),
            });
        };
        socketcan(self, a.trim(), b.trim())
    }
}

#[cfg(all(feature = "socketcan", target_os = "linux"))]
fn socketcan(
    b: &RedundantNetworkBuilder,
    bus1: &str,
    bus2: &str,
) -> Result<RedundantNetwork, RedundantError> {
    use duocan::port::socketcan::SocketCanPort;
    let open = |port: u8, name: &str| {
        SocketCanPort::open(name).map_err(|e| RedundantError::Port {
            port,
            name: name.into(),
            why: e.to_string(),
        })
    };
    b.open(open(0, bus1)?, open(1, bus2)?)
}

#[cfg(not(all(feature = "socketcan", target_os = "linux")))]
fn socketcan(
    _: &RedundantNetworkBuilder,
    bus1: &str,
    _: &str,
) -> Result<RedundantNetwork, RedundantError> {
    Err(RedundantError::Port {
        port: 0,
        name: bus1.into(),
        why: "this build has no SocketCAN: use \"sim-pairs\", or enable the `socketcan` feature of duocan-redundancy (Linux)".into(),
    })
}
