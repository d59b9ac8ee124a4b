//! The simulated network behind `open_named("sim-pairs")`: two in-memory buses, the
//! declared pairs as simulated duocan boards, the declared peers as simulated redundant masters
//! with the same settings, and a script of faults, so that a user sees a bus, a master and a
//! pair failover without hardware. `open_named("sim-pairs:quiet")` is the same plant without
//! the faults, running until the network closes (a station's simulated rack);
//! `open_named("sim-pairs:failover")` plays the faults and then runs on what is left until the
//! network closes (a station's demonstration rack: its dashboard shows the failovers and the
//! rack goes on). Under tokio's paused clock (tests) the run is deterministic. A builder with
//! `with_fd` gets the same plants as a CANopen FD network: every board and peer speaks CAN FD
//! on both buses and serves USDO.
//!
//! Every simulated device runs on the builder's identifier profile: on the railway 29-bit
//! scheme the boards' nodes and dual-bus layers classify by it and their dictionaries hold the
//! railway communication entries (SYNC, EMCY, SDO server) of their board addresses, so the
//! plant is the same, frame for frame, on the other identifiers.

use super::core::Net;
use super::RedundantNetwork;
use crate::link::config::DualBusConfig;
use crate::link::dual_bus::{DualBus, DualBusNode};
use crate::logical::{NetProfile, RedundantError, RedundantNetworkBuilder};
use alloc::boxed::Box;
use alloc::string::ToString;
use alloc::vec::Vec;
use duocan::cia301::pdo::params;
use duocan::od::{DefaultValue, DynamicDictionary};
use duocan::port::mem::{Connector, MemBus};
use duocan::profile::railway::{self, RailFunction};
use duocan::runtime::{Handle, Runtime};
use duocan::CobId;
use duocan::{Duration, Instant, Node, NodeConfig, NodeId, Station};
use tokio::sync::watch;
use tokio::task::JoinHandle;

/// When bus 1 of this master fails in the simulation (its port stops working: a pulled
/// connector).
pub const SIM_BUS_FAILS: Duration = Duration::from_millis(2000);
/// When the simulated peer masters stop (a standby master takes over after its master
/// timeout).
pub const SIM_PEERS_FAIL: Duration = Duration::from_millis(3000);
/// When the active member of every simulated pair stops (the other takes over after the pair
/// timeout).
pub const SIM_MEMBER_FAILS: Duration = Duration::from_millis(4000);
/// When the simulation ends: the network closes and its event streams end.
pub const SIM_END: Duration = Duration::from_millis(6000);
/// How much later than member A member B boots: after the masters' power-on negotiation, so
/// that the active master configures A alone and A is the active member, the same every run
/// (booted together, A runs too, B waiting for A's configuration, but each run's frames would
/// interleave differently).
pub const SIM_B_BOOTS: Duration = Duration::from_millis(1000);

pub(super) type Board = DualBusNode<DynamicDictionary, NetProfile>;

/// The simulated devices' script, running while the network is open; the network stops it
/// when it closes ([`Network::on_close`](duocan::net::Network::on_close)).
struct SimStation {
    /// Asks the script to stop every simulated device now.
    stop: watch::Sender<bool>,
    task: JoinHandle<()>,
}

impl SimStation {
    /// Stops every simulated device.
    async fn shutdown(self) {
        self.stop.send_replace(true);
        let _ = self.task.await;
    }
}

/// Waits until `t` after `start`; false if `stop` turns true first. A script's clock.
pub(super) async fn until(
    start: tokio::time::Instant,
    t: Duration,
    stop: &mut watch::Receiver<bool>,
) -> bool {
    let at = start + core::time::Duration::from_micros(t.as_micros());
    tokio::select! {
        () = tokio::time::sleep_until(at) => true,
        _ = stop.wait_for(|s| *s) => false,
    }
}

/// A simulated duocan board `id`: `duocan::net`'s simulated node (identity with the vendor-ID
/// `duocan::net::SIM_VENDOR` and product code = node-ID; inputs 0x6000 on TPDO 1, outputs
/// 0x6200 on RPDO 1, described by `duocan::net::sim_description`) on `profile`, booted (its
/// boot-up goes out when its runtime starts).
///
/// On a CANopen FD network (`fd`) the board speaks CAN FD on both ports and serves USDO.
pub(super) fn board(id: NodeId, profile: &NetProfile, fd: bool) -> Board {
    let mut od = duocan::net::sim_dictionary(id);
    profile.fit_dictionary(&mut od, id);
    if profile.is_railway() {
        // Its process data on the railway identifiers too: inputs as state changes and
        // outputs as commands of I/O port 1 (TPDO and RPDO 2–4 stay disabled).
        let port1 = NetProfile::railway_address(id).with_port(1);
        let cob = |f| DefaultValue::Unsigned(u64::from(CobId::from_id(railway::id(f, port1)).0));
        let tpdo = params::tpdo_comm(1, cob(RailFunction::StateChange), 254, 0, 0);
        let rpdo = params::rpdo_comm(1, cob(RailFunction::Command), 255, 0);
        for def in tpdo.into_iter().chain(rpdo) {
            od.upsert(def);
        }
    }
    let mut node = Node::with_profile(NodeConfig::slave(id).with_fd(fd), od, profile.clone());
    node.boot(Instant::ZERO);
    let mut link = DualBus::with_classifier(DualBusConfig::default(), profile.clone());
    link.set_port_fd(0, fd);
    link.set_port_fd(1, fd);
    Station::new(link, node)
}

pub(super) fn spawn<D>(
    dev: Box<D>,
    name: &str,
    buses: &[MemBus; 2],
) -> Result<Handle<D>, RedundantError>
where
    D: duocan::Device + Send + 'static,
    D::Event: Clone + Send + core::fmt::Debug + 'static,
{
    Runtime::boxed(dev)
        .name(name)
        .port(buses[0].port())
        .port(buses[1].port())
        .spawn()
        .map_err(|e| RedundantError::Port {
            port: 0,
            name: "sim-pairs".into(),
            why: e.to_string(),
        })
}

/// What the simulated plant does (see `open_named`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Plant {
    /// The script of faults, then the network closes (`sim-pairs`).
    Script,
    /// No faults: the plant runs until the network closes (`sim-pairs:quiet`).
    Quiet,
    /// The script of faults, timed from the moment every pair has a running board once the B
    /// boards are on, then the
    /// plant runs on what is left until the network closes (`sim-pairs:failover`).
    Failover,
}

/// Opens `b`'s network on a simulated station (see `open_named`) as `plant` says.
pub(super) fn open(
    b: &RedundantNetworkBuilder,
    plant: Plant,
) -> Result<RedundantNetwork, RedundantError> {
    open_on(b, plant, [MemBus::new("sim-bus1"), MemBus::new("sim-bus2")])
}

/// [`open`] on `buses` (a test listens on them).
pub(super) fn open_on(
    b: &RedundantNetworkBuilder,
    plant: Plant,
    buses: [MemBus; 2],
) -> Result<RedundantNetwork, RedundantError> {
    let net = b.build_profiled()?;
    let fd = b.fd_client().is_some();
    // This master's ports first: a port hears only what is sent after it exists.
    let (port1, cut) = buses[0].plugged_port();
    let ports = (port1, buses[1].port());
    let mut peers = Vec::new();
    let mut boards = Vec::new();
    if tokio::runtime::Handle::try_current().is_ok() {
        for &(n, _) in b.peers() {
            let dev = b.as_peer(n).build_profiled()?;
            peers.push(spawn(dev, &alloc::format!("sim master {n}"), &buses)?);
        }
        for &(a, _) in b.pairs() {
            // Checked by build(): valid node-IDs.
            if let Some(id) = NodeId::new(a) {
                boards.push((
                    a,
                    spawn(
                        Box::new(board(id, b.id_profile(), fd)),
                        &alloc::format!("sim board {a}"),
                        &buses,
                    )?,
                ));
            }
        }
    }
    let net = RedundantNetwork::start(net, ports, b.fd_client())?;
    let (stop, stop_rx) = watch::channel(false);
    let script = Script {
        net: net.clone(),
        buses,
        cut,
        peers,
        boards,
        later: b.pairs().iter().map(|&(_, b)| b).collect(),
        profile: b.id_profile().clone(),
        fd,
        stop: stop_rx,
        start: tokio::time::Instant::now(),
        plant,
    };
    let sim = SimStation {
        stop,
        task: tokio::spawn(script.run()),
    };
    net.on_close(move || sim.shutdown());
    Ok(net)
}

/// The simulated devices and what happens to them.
struct Script {
    /// The network the script closes at its end.
    net: RedundantNetwork,
    buses: [MemBus; 2],
    cut: Connector,
    peers: Vec<Handle<Net>>,
    boards: Vec<(u8, Handle<Board>)>,
    /// The B members, booted [`SIM_B_BOOTS`].
    later: Vec<u8>,
    /// The boards' identifier profile.
    profile: NetProfile,
    stop: watch::Receiver<bool>,
    start: tokio::time::Instant,
    plant: Plant,
    /// A CANopen FD network: the boards speak CAN FD and serve USDO.
    fd: bool,
}

impl Script {
    /// Waits until `t` after the start; false if asked to stop first.
    async fn until(&mut self, t: Duration) -> bool {
        until(self.start, t, &mut self.stop).await
    }

    async fn run(mut self) {
        let played = self.play().await;
        for (_, h) in &self.boards {
            h.shutdown().await;
        }
        for h in &self.peers {
            h.shutdown().await;
        }
        if played {
            // Closing the network stops this script and waits for it: the close runs as a
            // task of its own, which this one does not wait for.
            let net = self.net.clone();
            tokio::spawn(async move { net.close().await });
        }
    }

    /// The script; false if it was stopped before its end.
    async fn play(&mut self) -> bool {
        if !self.until(SIM_B_BOOTS).await {
            return false;
        }
        for b in core::mem::take(&mut self.later) {
            if let Some(id) = NodeId::new(b) {
                let name = alloc::format!("sim board {b}");
                if let Ok(h) = spawn(
                    Box::new(board(id, &self.profile, self.fd)),
                    &name,
                    &self.buses,
                ) {
                    self.boards.push((b, h));
                }
            }
        }
        if self.plant == Plant::Quiet {
            return self.until_closed().await;
        }
        if self.plant == Plant::Failover && !self.until_every_pair_runs().await {
            return false;
        }
        if !self.until(SIM_BUS_FAILS).await {
            return false;
        }
        self.cut.pull();
        if !self.until(SIM_PEERS_FAIL).await {
            return false;
        }
        for h in &self.peers {
            h.shutdown().await;
        }
        if !self.until(SIM_MEMBER_FAILS).await {
            return false;
        }
        let active: Vec<u8> = self
            .net
            .with(|n, _| {
                n.pairs()
                    .filter_map(|(_, p)| p.active.map(|m| p.spec.node(m).raw()))
                    .collect()
            })
            .await
            .unwrap_or_default();
        for (id, h) in &self.boards {
            if active.contains(id) {
                h.shutdown().await;
            }
        }
        if self.plant == Plant::Failover {
            return self.until_closed().await;
        }
        self.until(SIM_END).await
    }

    /// `sim-pairs:failover`'s start: its faults come at their times after every pair has a
    /// running board (checked once the B boards are on), not after the network opened, so that a station whose racks take long to
    /// come up (many simulated boards on a small machine) still shows each failover from a
    /// running rack. Polled every 100 ms; false if asked to stop first.
    async fn until_every_pair_runs(&mut self) -> bool {
        loop {
            let running = self
                .net
                .with(|n, _| n.pairs().all(|(_, p)| p.active.is_some()))
                .await
                .unwrap_or(false);
            if running {
                self.start = tokio::time::Instant::now();
                return true;
            }
            let next = tokio::time::Instant::now() + core::time::Duration::from_millis(100);
            if tokio::time::timeout_at(next, self.stop.wait_for(|s| *s))
                .await
                .is_ok()
            {
                return false;
            }
        }
    }

    /// Runs on until the network closes, which stops the script: false (not played to an end).
    async fn until_closed(&mut self) -> bool {
        let _ = self.stop.wait_for(|s| *s).await;
        false
    }
}

#[cfg(test)]
mod tests;
