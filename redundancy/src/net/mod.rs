//! The front door of a redundant network (feature `tokio`): the network a
//! [`RedundantNetworkBuilder`] describes, running on two ports, as one async handle that feels
//! like the root crate's single-bus `duocan::net::Network`.
//!
//! ```
//! use duocan::Duration;
//! use duocan_redundancy::net::{RedundantEvent, RedundantNetwork};
//! use duocan_redundancy::RedundantError;
//!
//! // The simulated station runs on tokio's paused clock here (tokio's `test-util`): its
//! // seconds pass at once and every run is the same. A plain #[tokio::main] runs it in real time.
//! #[tokio::main(flavor = "current_thread", start_paused = true)]
//! async fn main() -> Result<(), RedundantError> {
//!     let ms = Duration::from_millis;
//!     // "sim": two simulated buses with the declared pairs and peers on them; or "can0,can1".
//!     let net = RedundantNetwork::builder()
//!         .node_id(1)
//!         .heartbeat(ms(50))
//!         .master_timeout(ms(200))
//!         .pair(0x10, 0x50)
//!         .open_named("sim")?;
//!     let mut events = net.events();
//!     // Active once the power-on negotiation is over and the boards are configured.
//!     while let Some(e) = events.next().await {
//!         if matches!(e, RedundantEvent::PairRole { .. }) {
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
//! Underneath is a [`LogicalNetwork`] under the duocan runtime: the handle's calls run on it
//! (SDO, NMT, switch-over, status) and its events come out flat ([`RedundantEvent`]), with lag
//! as an item. Every call returns one error, [`RedundantError`].
//!
//! A tool that must not become a master on somebody's network opens duocan's plain front door
//! on the two buses instead: [`open_dual`] / [`open_dual_named`] ([`DualLink`], the dual-bus
//! layer as `duocan::net::Network`'s link); `open_dual_named("sim")` runs it on a simulated
//! redundant station:
//!
//! | node | what | state |
//! | --- | --- | --- |
//! | 0x01 | a redundant master (supervisor, flying master) | active master |
//! | 0x02 | its peer master, the same settings | standby master |
//! | 0x10 / 0x50, 0x11 / 0x51 | two A/B board pairs ([`SIM_PAIRS`]) | A active (operational), B standby (pre-operational) |
//! | 0x05, 0x06, 0x07 | plain slaves ([`SIM_SLAVES`]): `duocan::net`'s simulated node and a read-write DOMAIN [`SIM_DOMAIN`] of up to [`SIM_DOMAIN_SIZE`] bytes; [`SIM_PROGRAM_NODE`] takes program download (identification after start: [`sim_program_id`] of the image) | pre-operational |
//! | none (0xFF) | two boards that arrive without a node-ID ([`SIM_LSS_SERIALS`], identity [`sim_lss_address`]): silent but for LSS (CiA 305) until an LSS master gives them a node-ID, then they boot as the simulated node with it | non-configured |
//!
//! `"sim:faults"` repeats a script every [`SIM_FAULT_PERIOD`]: at [`SIM_FAULT_BUS_CUT`] into
//! it the network's connection to bus 1 is cut (back at [`SIM_FAULT_BUS_BACK`]), at
//! [`SIM_FAULT_MEMBER_STOPS`] the active member of the first pair stops (back at
//! [`SIM_FAULT_MEMBER_BACK`]), at [`SIM_FAULT_MASTER_STOPS`] the active master stops (back at
//! [`SIM_FAULT_MASTER_BACK`]).
//!
//! The station runs inside the network's own task, on its clock: its buses carry each frame
//! for its wire time at [`SIM_BIT_RATE`], and the two copies of a frame reach every device
//! together, however loaded the machine (two simulated devices each run by tasks of their own
//! would see them as far apart as the tasks were scheduled).

mod dual_link;
mod events;
mod node;
mod sim;
mod sim_station;

pub use dual_link::{open_dual, open_dual_named, open_dual_with, DualLink};
pub use events::{RedundantEvent, RedundantEvents};
pub use node::{RedundantNode, RedundantSdo};
pub use sim::{SIM_BUS_FAILS, SIM_B_BOOTS, SIM_END, SIM_MEMBER_FAILS, SIM_PEERS_FAIL};
pub use sim_station::{
    sim_lss_address, sim_program_id, SIM_BIT_RATE, SIM_DOMAIN, SIM_DOMAIN_SIZE, SIM_FAULT_BUS_BACK,
    SIM_FAULT_BUS_CUT, SIM_FAULT_MASTER_BACK, SIM_FAULT_MASTER_STOPS, SIM_FAULT_MEMBER_BACK,
    SIM_FAULT_MEMBER_STOPS, SIM_FAULT_PERIOD, SIM_LSS_PRODUCT, SIM_LSS_REVISION, SIM_LSS_SERIALS,
    SIM_PAIRS, SIM_PROGRAM_NODE, SIM_SLAVES,
};

use crate::network::{LogicalNetwork, RedundantError, RedundantNetworkBuilder};
use crate::pair::{Member, PairId};
use crate::supervisor::flying_master::MasterRole;
use alloc::string::{String, ToString};
use alloc::sync::Arc;
use alloc::vec::Vec;
use duocan::nmt::NmtTarget;
use duocan::od::DynamicDictionary;
use duocan::port::Port;
use duocan::runtime::{Handle, Runtime};
use duocan::sdo::SdoOptions;
use duocan::{Duration, Instant, NmtCommand};
use tokio::sync::{watch, Mutex};

/// The device the handle runs.
type Net = LogicalNetwork<DynamicDictionary>;

/// A redundant network on two ports: the handle everything starts from. Cheap to clone; the
/// network runs until [`RedundantNetwork::close`].
#[derive(Clone)]
pub struct RedundantNetwork {
    shared: Arc<Shared>,
}

struct Shared {
    handle: Handle<Net>,
    /// One lock per node-ID: transfers to one node take turns (a server runs one at a time).
    per_node: Vec<Mutex<()>>,
    sdo: SdoOptions,
    /// The simulated station of `open_named("sim")`, kept running.
    sim: Option<sim::SimStation>,
    /// Turns true when the network is closed: ends every event stream.
    closed: Arc<watch::Sender<bool>>,
}

impl RedundantNetwork {
    /// The builder, every setting at its default (see [`RedundantNetworkBuilder`]).
    pub fn builder() -> RedundantNetworkBuilder {
        RedundantNetworkBuilder::default()
    }

    fn start<P1: Port, P2: Port>(
        net: alloc::boxed::Box<Net>,
        ports: (P1, P2),
        sim: Option<sim::SimStation>,
    ) -> Result<RedundantNetwork, RedundantError> {
        let names = [ports.0.name().to_string(), ports.1.name().to_string()];
        if tokio::runtime::Handle::try_current().is_err() {
            return Err(RedundantError::Port {
                port: 0,
                name: names[0].clone(),
                why: "no tokio runtime: open the network from inside one (#[tokio::main])".into(),
            });
        }
        let handle = Runtime::boxed(net)
            .name(alloc::format!("{},{}", names[0], names[1]))
            .port(ports.0)
            .port(ports.1)
            .spawn()
            .map_err(|e| RedundantError::Port {
                port: 0,
                name: names[0].clone(),
                why: e.to_string(),
            })?;
        let closed = sim
            .as_ref()
            .map_or_else(|| Arc::new(watch::channel(false).0), |s| s.closed.clone());
        Ok(RedundantNetwork {
            shared: Arc::new(Shared {
                handle,
                per_node: (0..128).map(|_| Mutex::new(())).collect(),
                sdo: SdoOptions::default().with_timeout(Duration::from_millis(1000)),
                sim,
                closed,
            }),
        })
    }

    /// The node `id` (1–127): a pair member, a plain slave or any node on the buses. Nothing
    /// is sent; an invalid ID is reported by the first call on the node.
    #[must_use]
    pub fn node(&self, id: u8) -> RedundantNode {
        RedundantNode::new(self.clone(), id)
    }

    /// Every event from now on, as a stream on which lag is an item.
    #[must_use]
    pub fn events(&self) -> RedundantEvents {
        RedundantEvents::new(
            self.shared.handle.subscribe(),
            self.shared.closed.subscribe(),
        )
    }

    /// The network's clock: time since it was opened (the `at` of every event).
    #[must_use]
    pub fn now(&self) -> Instant {
        self.shared.handle.now()
    }

    /// This master's role (active, standby, negotiating…).
    pub async fn role(&self) -> Result<MasterRole, RedundantError> {
        Ok(self.shared.handle.call(|n, _| n.role()).await?)
    }

    /// The active member of every pair, in the order declared.
    pub async fn active_members(&self) -> Result<Vec<(PairId, Option<Member>)>, RedundantError> {
        let h = &self.shared.handle;
        Ok(
            h.call(|n, _| n.pairs().map(|(id, p)| (id, p.active)).collect())
                .await?,
        )
    }

    /// The status table (ports, master role, pairs, slaves), as text.
    pub async fn status(&self) -> Result<String, RedundantError> {
        let h = &self.shared.handle;
        Ok(h.call(|n, now| n.status(now).to_string()).await?)
    }

    /// Sends an NMT command to every node (active master only).
    pub async fn nmt_all(&self, cmd: NmtCommand) -> Result<(), RedundantError> {
        self.nmt(cmd, NmtTarget::All).await
    }

    async fn nmt(&self, cmd: NmtCommand, target: NmtTarget) -> Result<(), RedundantError> {
        let h = &self.shared.handle;
        h.try_call(move |n, now| n.nmt(now, cmd, target).map_err(RedundantError::from))
            .await
    }

    /// Makes `to` the active member of `pair` (active master only).
    pub async fn switch_over(&self, pair: PairId, to: Member) -> Result<(), RedundantError> {
        let h = &self.shared.handle;
        h.try_call(move |n, now| n.switch_over(now, pair, to).map_err(RedundantError::from))
            .await
    }

    /// Runs `f` on the [`LogicalNetwork`] inside the runtime, for what the handle does not
    /// cover (audit export, PDO values, the master's dictionary).
    pub async fn with<R, F>(&self, f: F) -> Result<R, RedundantError>
    where
        F: FnOnce(&mut Net, Instant) -> R + Send + 'static,
        R: Send + 'static,
    {
        Ok(self.shared.handle.call(f).await?)
    }

    /// Stops the network (and the simulated station, if any) and waits for it; calls made
    /// afterwards fail with [`RedundantError::Closed`] and event streams end.
    pub async fn close(&self) {
        if let Some(s) = &self.shared.sim {
            s.shutdown().await;
        }
        self.shared.handle.shutdown().await;
        self.shared.closed.send_replace(true);
    }
}

impl RedundantNetworkBuilder {
    /// Opens the network on two ports (port 1 = bus 1): builds it and runs it under the duocan
    /// runtime. Must be called inside a tokio runtime.
    pub fn open<P1: Port, P2: Port>(
        &self,
        bus1: P1,
        bus2: P2,
    ) -> Result<RedundantNetwork, RedundantError> {
        RedundantNetwork::start(self.build_boxed()?, (bus1, bus2), None)
    }

    /// Opens the network by name:
    ///
    /// - `sim`: two simulated buses carrying the declared pairs (simulated duocan boards) and
    ///   peer masters (simulated redundant masters with the same settings), and a script of
    ///   faults: bus 1 of this master fails at [`SIM_BUS_FAILS`], the peer masters stop at
    ///   [`SIM_PEERS_FAIL`] (a standby master takes over), the active member of every pair
    ///   stops at [`SIM_MEMBER_FAILS`] (the other one takes over), and the simulation ends at
    ///   [`SIM_END`] (the network closes, event streams end);
    /// - `A,B`: SocketCAN interfaces A (bus 1) and B (bus 2), such as `can0,can1` (feature
    ///   `socketcan`, Linux).
    pub fn open_named(&self, name: &str) -> Result<RedundantNetwork, RedundantError> {
        if name == "sim" {
            return sim::open(self);
        }
        let Some((a, b)) = name.split_once(',') else {
            return Err(RedundantError::Port {
                port: 0,
                name: name.into(),
                why: "a redundant network needs two interfaces: name them as can0,can1 (or use \"sim\")".into(),
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
        why: "this build has no SocketCAN: use \"sim\", or enable the `socketcan` feature of duocan-redundancy (Linux)".into(),
    })
}

/// For [`RedundantNode`]: the shared parts.
impl RedundantNetwork {
    fn handle(&self) -> &Handle<Net> {
        &self.shared.handle
    }
    fn sdo_options(&self) -> SdoOptions {
        self.shared.sdo
    }
    fn turn(&self, raw: u8) -> &Mutex<()> {
        &self.shared.per_node[usize::from(raw & 0x7F)]
    }
}
