//! The front door: a network handle and remote nodes, typed and async, for applications that
//! talk to CANopen nodes the way python `canopen` users do.
//!
//! ```
//! use duocan::net::{NetError, Network};
//! use duocan::NmtState;
//! use std::time::Duration;
//!
//! #[tokio::main]
//! async fn main() -> Result<(), NetError> {
//!     // "sim-nodes": simulated nodes 1–10; or "can0", "udp", "udp:N".
//!     let net = Network::open_named("sim-nodes")?;
//!     let node = net.node(5);
//!     let vendor: u32 = node.sdo().read(0x1018, 1).await?;
//!     assert_eq!(vendor, duocan::net::SIM_VENDOR);
//!     assert_eq!(node.sdo().read_string(0x1008, 0).await?, "duocan simulated node");
//!     node.start().await?;
//!     node.wait_for_state(NmtState::Operational, Duration::from_secs(2)).await?;
//!     Ok(())
//! }
//! ```
//!
//! | python `canopen` | duocan |
//! | --- | --- |
//! | `network.connect(channel="can0", bustype="socketcan")` | `Network::open_named("can0")?` |
//! | `node = network.add_node(5)` | `let node = net.node(5);` |
//! | `node = network.add_node(5, "dev.eds")` | `let node = net.add_node_eds(5, "dev.eds")?;` |
//! | `node.sdo[0x1018][1].raw` | `node.sdo().read::<u32>(0x1018, 1).await?` |
//! | `node.sdo[0x1017].raw = 100` | `node.sdo().write(0x1017, 0, 100u16).await?` |
//! | `node.sdo["Producer heartbeat time"].raw` | `node.sdo().read_named::<u16>("Producer heartbeat time").await?` |
//! | `node.sdo["Producer heartbeat time"].raw = 100` | `node.sdo().write_named("Producer heartbeat time", 100u16).await?` |
//! | `node.sdo["Manufacturer device name"].raw` (typed by the EDS) | `node.sdo().read_value("Manufacturer device name").await?` ([`AnyValue`]) |
//! | `node.sdo.upload(0x1008, 0)` | `node.sdo().read_bytes(0x1008, 0).await?` |
//! | `with node.sdo[0x2002].open("rb") as f: shutil.copyfileobj(f, out)` | `node.sdo().read_to(0x2002, 0, out, \|p\| ..).await?` (any size, bounded memory, [`TransferProgress`]) |
//! | `with node.sdo[0x2002].open("wb", size=n) as f: shutil.copyfileobj(src, f)` | `node.sdo().write_from(0x2002, 0, src, Some(n), \|p\| ..).await?` |
//! | `node.nmt.state = "OPERATIONAL"` | `node.start().await?` |
//! | `node.nmt.wait_for_bootup(10)` | `node.wait_for_boot_up(Duration::from_secs(10)).await?` |
//! | `node.nmt.wait_for_heartbeat()` / `node.nmt.state` | `node.state().await?` |
//! | `node.tpdo.read()` | `node.read_pdos(Dir::Transmit).await?` (one: `let mut t1 = node.tpdo(1).read().await?;`) |
//! | `node.tpdo[1].clear()` | `t1.clear();` |
//! | `node.tpdo[1].add_variable("Input 1")` | `t1.add_variable("Input 1")?;` (or `t1.add(0x6000, 1, 16)?`) |
//! | `node.tpdo[1].trans_type = 1` / `.event_timer = 10` / `.enabled = True` | `t1.transmission_type = 1;` / `t1.event_timer_ms = Some(10);` / `t1.enabled = true;` |
//! | `node.tpdo.save()` | `node.tpdo(1).save(&t1).await?` |
//! | `node.store()` after `save()` | `node.tpdo(1).save_and_store(&t1).await?` / `node.store_parameters().await?` |
//! | `node.tpdo[1].wait_for_reception()`, then `node.tpdo[1]["Input 1"].raw` | `node.wait_for_pdo(1, timeout).await?.get("Input 1")` |
//! | `node.tpdo[1].add_callback(f)` | `NetEvent::Pdo { node, pdo, values, .. }` on [`Network::events`] |
//! | `node.rpdo[1]["Output 1"].raw = 5; node.rpdo[1].transmit()` | `node.rpdo(1).send_named(&[("Output 1", 5u16.into())]).await?` (all in order: `send(&[..])`) |
//! | `network.sync.start(0.05)` / `network.sync.stop()` | `net.start_sync(Duration::from_millis(50)).await?` / `net.stop_sync().await?` |
//! | `node.emcy.wait(timeout=2)` / `node.emcy.active` | `node.wait_for_emcy(timeout).await?` / `NetEvent::Emcy` ([`NetEvent::emcy`]) |
//! | `network.lss.send_switch_state_global(network.lss.CONFIGURATION_STATE)` | `net.lss().switch_global(LssMode::Configuration).await?` ([`NetLss`]) |
//! | `network.lss.send_switch_state_selective(v, p, r, s)` | `net.lss().switch_selective(address).await?` |
//! | `network.lss.inquire_node_id()` | `net.lss().inquire(Inquiry::NodeId).await?` |
//! | `network.lss.configure_node_id(5)` / `.store_configuration()` | `net.lss().configure_node_id(5).await?` / `.store().await?` |
//! | `network.lss.fast_scan()` (one slave, its identity) | `net.lss().fastscan(plan).await?` (every slave, each given its node-ID: [`FastscanReport`]) |
//!
//! Underneath is the ordinary stack on the [`runtime`](crate::runtime): a node that only
//! observes (it tracks every node's state from boot-ups and heartbeats, consumes EMCY and the
//! heartbeats it is told to watch) and an SDO client, behind a filter that lets only NMT
//! commands and SDO requests onto the bus, and three things the user turns on: SYNC while the
//! SYNC producer runs ([`Network::start_sync`]), the RPDOs the user sends, and the requests of
//! the LSS master (CiA 305, [`Network::lss`]) the user calls. The network handle is therefore
//! not a node: it sends no boot-up, no heartbeat, and answers nothing (it uses node-ID 127
//! internally, so a node 127 on the bus is not tracked).
//! [`Network::monitor`] sends nothing at all.
//!
//! **Links.** The observer and the client sit on a link ([`NetLink`], one trait object, so
//! [`Network`] is one type whatever it runs on): one port ([`Network::open`]), or two ports
//! merged by the redundancy crate's dual-bus layer (`duocan_redundancy::net::open_dual`, via
//! [`Network::open_link`]), where every request goes out on both buses and every answer is
//! delivered once. The stack above the link does not know how many wires there are;
//! [`Network::ports`] (name, state, counters: [`PortView`]) and [`Network::heard_on`] (the
//! buses a node was heard on) do, and [`NetEvent::PortState`] and [`NetEvent::Reach`] report
//! their changes.
//!
//! **Cores.** The observer and client are one [`NetCore`]: the door (nodes, SDO, waits, PDOs,
//! events, and the LSS master, whose requests leave through the core) is written once over
//! that trait, and [`Network::open_core`] runs it
//! over another core, whose own calls [`Network::with_core`] reaches and whose own events
//! come in the same stream as [`NetEvent::Ext`] ([`Extension`]).
//!
//! **Program download** (CiA 302-3): [`RemoteNode::download_program`] replaces a node's
//! program by the master's procedure, the image streamed by block transfer, with progress.
//!
//! Every call returns one error, [`NetError`], naming the node and object and what to do.
//! SDO transfers to different nodes run at once; to one node they take turns (a server runs one
//! transfer per client at a time).
//!
//! **Names.** With a device description attached ([`Network::add_node`],
//! [`RemoteNode::with_description`], or from an EDS/DCF file), a name resolves as
//! [`Description::entry`] resolves it: `"Producer heartbeat time"`, `"0x1017"`, `"1017sub0"`,
//! `"Identity object.Vendor-ID"`, without regard to case. The typed by-name calls check the
//! Rust type against the entry's data type before anything is sent; an unknown or ambiguous
//! name is [`NetError::Name`], listing the candidates.
//!
//! **PDOs** ([`RemotePdo`]: `node.tpdo(n)`, `node.rpdo(n)`): the network decodes a node's TPDO once it knows the mapping
//! (read over SDO, saved, or given with [`RemotePdo::learn`]), inside the runtime as the frame
//! arrives, and reports [`NetEvent::Pdo`] with the values named and typed by the description.
//! At a high PDO rate, a reader of [`Network::events`] that falls behind gets
//! [`NetEvent::Lagged`]; [`RemoteNode::wait_for_pdo`] never misses the PDO it waits for.

mod core;
mod door;
mod error;
mod events;
mod ext;
mod heard_on;
mod link;
mod lss;
mod named;
mod observer;
mod pdo;
mod program;
mod remote;
mod sdo;
mod sdo_stream;
mod sim;
mod starts;
mod usdo;
mod value;

pub use self::core::{CoreEvent, NetClient, NetCore, LSS_PLAN};
pub use error::{Awaited, NetError};
pub use events::{Events, NetEvent};
pub use ext::{ExtEvent, Extension};
pub use heard_on::HeardOn;
pub use link::{NetLink, NetPorts, PortView};
pub use lss::{FastscanReport, NetLss};
pub use pdo::{PdoMap, PdoValue, PdoValues, PdoVariable, RemotePdo, MAX_LEARNED};
pub use remote::RemoteNode;
pub use sdo::RemoteSdo;
pub use sdo_stream::{TransferProgress, STREAM_WINDOW};
pub use sim::{
    sim_description, sim_dictionary, FD_CLIENT, SIM_DEVICE_NAME, SIM_HEARTBEAT_MS, SIM_NAMES,
    SIM_VENDOR,
};
pub use value::AnyValue;

use crate::cia301::nmt::{NmtCommand, NmtTarget};
use crate::cia301::sdo::SdoOptions;
use crate::cia305::LssMasterConfig;
use crate::eds::Description;
use crate::frame::cob_id::NodeId;
use crate::frame::instant::{Duration, Instant};
use crate::machine::{Device, PortState};
use crate::port::Port;
use crate::runtime::{Handle, Runtime};
use door::Door;
use std::collections::BTreeMap;
use std::future::Future;
use std::pin::Pin;
use std::sync::Arc;
use tokio::sync::{watch, Mutex};

/// SDO transfers in flight at once (the client's session count).
const SESSIONS: usize = 8;
/// The largest value one SDO transfer moves (a domain read or written whole).
pub const MAX_TRANSFER: usize = 64 * 1024;

/// How a [`Network`] behaves. Start from `NetOptions::default()` and change with `with_*`.
#[derive(Clone)]
#[non_exhaustive]
pub struct NetOptions {
    /// Transfer mode, timeout, block size and CRC of every SDO transfer (default: the
    /// smallest mode that fits, 1 s timeout).
    pub sdo: SdoOptions,
    /// Send nothing: watch the nodes without a single frame on the bus.
    pub listen_only: bool,
    /// Told of every frame each port receives and sends, as the port saw it (a
    /// [`Recorder`](crate::capture::recorder::Recorder) writes them to a candump log or a pcap;
    /// a tool decodes them live). `None`: no tap.
    pub tap: Option<Arc<dyn crate::capture::recorder::Tap>>,
    /// The LSS master's answer timeout and fastscan settle time ([`Network::lss`]).
    pub lss: LssMasterConfig,
    /// A CANopen FD network (CiA 1301), and the node-ID of the network's own USDO client
    /// (`None`, the default: a classic network). See [`NetOptions::with_fd`].
    pub fd: Option<NodeId>,
}

impl ::core::fmt::Debug for NetOptions {
    fn fmt(&self, f: &mut ::core::fmt::Formatter<'_>) -> ::core::fmt::Result {
        f.debug_struct("NetOptions")
            .field("sdo", &self.sdo)
            .field("listen_only", &self.listen_only)
            .field("tap", &self.tap.is_some())
            .field("lss", &self.lss)
            .field("fd", &self.fd)
            .finish()
    }
}

impl Default for NetOptions {
    fn default() -> Self {
        NetOptions {
            sdo: SdoOptions::default().with_timeout(Duration::from_millis(1000)),
            listen_only: false,
            tap: None,
            lss: LssMasterConfig::default(),
            fd: None,
        }
    }
}

impl NetOptions {
    /// The options with every SDO transfer's answer timeout set to `t`.
    #[must_use]
    pub fn with_sdo_timeout(mut self, t: std::time::Duration) -> Self {
        let us = u64::try_from(t.as_micros()).unwrap_or(u64::MAX);
        self.sdo = self.sdo.with_timeout(Duration::from_micros(us));
        self
    }
    /// The options with the SDO options replaced.
    #[must_use]
    pub fn with_sdo(mut self, sdo: SdoOptions) -> Self {
        self.sdo = sdo;
        self
    }
    /// The options with listen-only mode set.
    #[must_use]
    pub fn with_listen_only(mut self, on: bool) -> Self {
        self.listen_only = on;
        self
    }
    /// The options with the LSS master's timeout and settle time.
    #[must_use]
    pub fn with_lss(mut self, lss: LssMasterConfig) -> Self {
        self.lss = lss;
        self
    }
    /// The options of a CANopen FD network (CiA 1301) on an FD-capable port: the network
    /// reads and writes the nodes' dictionaries over USDO, with the same calls and the same
    /// results as over SDO (typed values, strings, bytes through [`RemoteSdo`]; streams go
    /// whole, at most [`MAX_TRANSFER`] bytes). `client` is the node-ID its USDO requests go out with (on 0x600 + `client`,
    /// in CAN FD frames): one no node of the network has, since USDO names its clients by
    /// their node-IDs. The nodes must serve USDO (a duocan node with
    /// [`NodeConfig::fd`](crate::NodeConfig::fd)).
    ///
    /// **Why an option, not the port's say.** A port that carries CAN FD does not make the
    /// network one: a classic node answers an FD frame with error frames, so only the user
    /// knows that every node speaks FD. The network runs on one port
    /// ([`Network::open_with`]), or on two through a link that carries CAN FD (the redundancy
    /// crate's `open_dual`: each request on both buses, each answer taken once); any other
    /// link or core is refused at open. The ports must be opened for CAN FD (a classic one
    /// reports each USDO request as a failed send, and the transfer times out).
    #[must_use]
    pub fn with_fd(mut self, client: NodeId) -> Self {
        self.fd = Some(client);
        self
    }
    /// The options with `tap` told of every frame each port receives and sends.
    #[must_use]
    pub fn with_tap(mut self, tap: Arc<dyn crate::capture::recorder::Tap>) -> Self {
        self.tap = Some(tap);
        self
    }
}

/// A CANopen network on one port or on two merged ones (see [`Network::open_link`]): the
/// handle everything starts from. Cheap to clone; the network runs until [`Network::close`] or
/// until the last clone (and every [`RemoteNode`]) is dropped.
#[derive(Clone)]
pub struct Network {
    shared: Arc<Shared>,
}

struct Shared {
    handle: Handle<Door>,
    opts: NetOptions,
    /// One lock per node-ID: transfers to one node take turns.
    per_node: Vec<Mutex<()>>,
    /// LSS requests take turns (LSS has no addresses: one runs at a time).
    lss_turn: Mutex<()>,
    /// Simulated nodes started with the network (`open_named("sim-nodes")`), kept running.
    sim: sim::SimNodes,
    /// Set by [`Network::close`]: ends every event stream.
    closed: watch::Sender<bool>,
    /// Device descriptions attached with [`Network::add_node`], by node-ID.
    descs: std::sync::Mutex<BTreeMap<u8, Arc<Description>>>,
    /// What stops with the network ([`Network::on_close`]), in the order given.
    on_close: std::sync::Mutex<Vec<OnClose>>,
}

/// A task run when the network closes.
type OnClose = Box<dyn FnOnce() -> Pin<Box<dyn Future<Output = ()> + Send>> + Send>;

impl Network {
    /// Opens the network on `port` (a SocketCAN, UDP or in-memory port) with default options.
    /// Must be called inside a tokio runtime.
    pub fn open<P: Port>(port: P) -> Result<Network, NetError> {
        Self::open_with(port, NetOptions::default())
    }

    /// Opens a listen-only network on `port`: it watches boot-ups, heartbeats and EMCY and
    /// sends nothing (no boot-up, no answer to NMT or SDO, no requests of its own).
    pub fn monitor<P: Port>(port: P) -> Result<Network, NetError> {
        Self::open_with(port, NetOptions::default().with_listen_only(true))
    }

    /// Opens the network on `port` with `opts`.
    pub fn open_with<P: Port>(port: P, opts: NetOptions) -> Result<Network, NetError> {
        Self::start(
            Box::new(link::OnePort::for_options(&opts)),
            port,
            opts,
            sim::SimNodes::default(),
        )
    }

    /// Opens the network on `link` (a link with two ports: the redundancy crate's dual-bus
    /// layer) over `ports`, one per port of the link in order. The network is the same type
    /// as on one port; [`Network::ports`] and [`Network::heard_on`] show the link's view, and
    /// its port and reach changes come as [`NetEvent::PortState`] and [`NetEvent::Reach`].
    /// A link whose port count differs from the ports given is [`NetError::Port`].
    pub fn open_link(
        link: Box<dyn NetLink>,
        ports: impl NetPorts,
        opts: NetOptions,
    ) -> Result<Network, NetError> {
        Self::start(link, ports, opts, sim::SimNodes::default())
    }

    /// Opens the network on `core` over `ports`, one per port of the core in order: the
    /// same door (remote nodes, SDO, waits, PDOs, events) over another station, such as a
    /// redundancy crate's supervised master. `opts.sdo`, `opts.listen_only` and `opts.lss` are
    /// the door's. A core whose port count differs from
    /// the ports given is [`NetError::Port`]. Must be called inside a tokio runtime.
    pub fn open_core(
        core: Box<dyn NetCore>,
        ports: impl NetPorts,
        opts: NetOptions,
    ) -> Result<Network, NetError> {
        Self::start_core(core, ports, opts, sim::SimNodes::default())
    }

    /// Runs `f` on the network's core, inside its runtime, with the runtime's clock: a core's
    /// calls that the door does not know (`C` is the type given to [`Network::open_core`]).
    /// A core of another type is [`NetError::Argument`], naming both.
    pub async fn with_core<C, R>(
        &self,
        f: impl FnOnce(&mut C, Instant) -> R + Send + 'static,
    ) -> Result<R, NetError>
    where
        C: NetCore,
        R: Send + 'static,
    {
        self.shared
            .handle
            .try_call(move |d, now| {
                let name = d.core.type_name();
                match d.core.as_any_mut().downcast_mut::<C>() {
                    Some(c) => Ok(f(c, now)),
                    None => Err(NetError::Argument(format!(
                        "the network's core is a {name}, not a {}",
                        ::core::any::type_name::<C>()
                    ))),
                }
            })
            .await
    }

    /// The observer core on `link`, then [`Network::start_core`].
    fn start(
        link: Box<dyn NetLink>,
        ports: impl NetPorts,
        opts: NetOptions,
        sim: sim::SimNodes,
    ) -> Result<Network, NetError> {
        let core = observer::ObserverCore::new(link, &opts)?;
        Self::start_core(Box::new(core), ports, opts, sim)
    }

    fn start_core(
        core: Box<dyn NetCore>,
        ports: impl NetPorts,
        opts: NetOptions,
        sim: sim::SimNodes,
    ) -> Result<Network, NetError> {
        if core.port_count() != ports.count() || ports.count() > 2 {
            return Err(NetError::Port(format!(
                "{}: {} ports given to a link of {}",
                ports.label(),
                ports.count(),
                core.port_count()
            )));
        }
        if tokio::runtime::Handle::try_current().is_err() {
            return Err(NetError::Port(
                "no tokio runtime: open the network from inside one (#[tokio::main])".into(),
            ));
        }
        if opts.fd.is_some() && !core.fd_capable() {
            return Err(NetError::Port(format!(
                "{}: a CANopen FD network (USDO) needs a link that carries CAN FD, and this {} does not",
                ports.label(),
                core.type_name()
            )));
        }
        let mut door = Door::new(core, opts.lss);
        if let Some(me) = opts.fd {
            door.usdo = Some(usdo::UsdoDoor::new(me, MAX_TRANSFER));
        }
        let label = ports.label();
        let mut rt = ports.attach(Runtime::new(door).name(label));
        if let Some(tap) = &opts.tap {
            rt = rt.tap(tap.clone());
        }
        let handle = rt.spawn().map_err(|e| NetError::Port(e.to_string()))?;
        Ok(Network {
            shared: Arc::new(Shared {
                handle,
                opts,
                per_node: (0..128).map(|_| Mutex::new(())).collect(),
                lss_turn: Mutex::new(()),
                sim,
                closed: watch::channel(false).0,
                descs: std::sync::Mutex::default(),
                on_close: std::sync::Mutex::default(),
            }),
        })
    }

    /// The remote node `id` (1–127). Nothing is sent; an invalid ID is reported by the first
    /// call on the node. The node's boot-up waits count from this moment
    /// ([`RemoteNode::wait_for_boot_up`]).
    #[must_use]
    pub fn node(&self, id: u8) -> RemoteNode {
        let desc = self.descriptions().get(&id).cloned();
        RemoteNode::new(self.clone(), id, self.now(), desc)
    }

    /// The remote node `id` with a device description, which every handle
    /// [`Network::node`] gives for `id` from now on carries too: its names work in the by-name
    /// calls ([`RemoteSdo::read_named`]) and name the values of its PDOs.
    pub fn add_node(&self, id: u8, desc: impl Into<Arc<Description>>) -> RemoteNode {
        self.descriptions().insert(id, desc.into());
        self.node(id)
    }

    /// [`Network::add_node`] with the description read from an EDS or DCF file (leniently:
    /// what a real file gets wrong is a warning in [`Description::warnings`]).
    pub fn add_node_eds(
        &self,
        id: u8,
        path: impl AsRef<std::path::Path>,
    ) -> Result<RemoteNode, NetError> {
        Ok(self.add_node(id, Description::read(path)?))
    }

    fn descriptions(&self) -> std::sync::MutexGuard<'_, BTreeMap<u8, Arc<Description>>> {
        // A poisoned lock only means another thread panicked while inserting: the map is
        // still whole.
        self.shared
            .descs
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    /// Every event from now on, as a stream on which lag is an item.
    #[must_use]
    pub fn events(&self) -> Events {
        Events {
            rx: self.shared.handle.subscribe(),
            closed: self.shared.closed.subscribe(),
        }
    }

    /// The network's clock: time since it was opened (the `at` of every event).
    #[must_use]
    pub fn now(&self) -> Instant {
        self.shared.handle.now()
    }

    /// True if the network is listen-only.
    #[must_use]
    pub fn is_listen_only(&self) -> bool {
        self.shared.opts.listen_only
    }

    /// The node-ID of the network's USDO client if it is a CANopen FD network
    /// ([`NetOptions::with_fd`], or a name with `:fd` given to [`Network::open_named`]); `None`
    /// on a classic one.
    #[must_use]
    pub fn fd_client(&self) -> Option<NodeId> {
        self.shared.opts.fd
    }

    /// The network's LSS master (CiA 305): find devices by identity and give them a node-ID
    /// and a bit rate (python `canopen`'s `network.lss`). See [`NetLss`].
    #[must_use]
    pub fn lss(&self) -> NetLss {
        NetLss::new(self.clone())
    }

    /// Sends an NMT command to every node.
    pub async fn nmt_all(&self, cmd: NmtCommand) -> Result<(), NetError> {
        self.nmt(None, cmd, NmtTarget::All).await
    }

    async fn nmt(
        &self,
        node: Option<NodeId>,
        cmd: NmtCommand,
        target: NmtTarget,
    ) -> Result<(), NetError> {
        if self.is_listen_only() {
            return Err(NetError::ListenOnly { node });
        }
        self.shared
            .handle
            .try_call(move |d, now| d.core.nmt(now, cmd, target))
            .await
            .map_err(|e| match e {
                NetError::Standby { node: None } => NetError::Standby { node },
                e => e,
            })
    }

    /// How many decoded PDOs the network dropped because too many were waiting for its
    /// event queue at once (it passes them on after every frame, so this stays 0 unless the
    /// runtime is starved).
    pub async fn dropped_pdos(&self) -> Result<u64, NetError> {
        Ok(self.shared.handle.call(|d, _| d.pdo_dropped).await?)
    }

    /// Starts producing SYNC every `period` (python `network.sync.start(period)`): the
    /// network's own SYNC producer (0x1005 with bit 30, 0x1006 = the period in µs), on
    /// identifier 0x080, without a counter. Synchronous PDOs (transmission types 0–240) follow
    /// it. A period of zero or above 4294 s is [`NetError::Argument`].
    pub async fn start_sync(&self, period: std::time::Duration) -> Result<(), NetError> {
        if self.is_listen_only() {
            return Err(NetError::ListenOnly { node: None });
        }
        let us = u32::try_from(period.as_micros())
            .ok()
            .filter(|us| *us > 0)
            .ok_or_else(|| {
                NetError::Argument(format!(
                    "a SYNC period of {period:?}: give 1 µs to 4294 s (stop_sync stops it)"
                ))
            })?;
        self.shared
            .handle
            .try_call(move |d, now| d.core.set_sync(now, Some(us)))
            .await
    }

    /// Stops producing SYNC.
    pub async fn stop_sync(&self) -> Result<(), NetError> {
        self.shared
            .handle
            .try_call(move |d, now| d.core.set_sync(now, None))
            .await
    }

    /// Its ports, in order (port 0 = bus 1): name, state and counters. On a dual bus the
    /// state is the layer's port health (`"ok"`, `"suspect"`, `"failed"`, `"recovering"`);
    /// on one port, what its driver last reported ([`PortView::state`]).
    pub async fn ports(&self) -> Result<Vec<PortView>, NetError> {
        let h = &self.shared.handle;
        let states = h
            .call(|d, _| {
                (0..d.port_count())
                    .map(|p| {
                        let driver = d.drivers.get(p).copied().unwrap_or_default();
                        (d.core.port_state(p), driver)
                    })
                    .collect::<Vec<_>>()
            })
            .await?;
        Ok(states
            .into_iter()
            .enumerate()
            .map(|(index, (health, driver))| PortView {
                index,
                name: h.port_names().get(index).cloned().unwrap_or_default(),
                state: health.map_or(driver.state, PortState::as_str),
                health,
                last_error: driver.last_error,
                counters: h.port_counters(index).unwrap_or_default(),
            })
            .collect())
    }

    /// On which of the link's buses node `id` was heard within its reach timeout (none for a
    /// node not heard lately); `None` on one port, where the question has no answer. A node-ID
    /// outside 1–127 is [`NetError::NoSuchNode`].
    pub async fn heard_on(&self, id: u8) -> Result<Option<HeardOn>, NetError> {
        let node = NodeId::new(id).ok_or(NetError::NoSuchNode(id))?;
        Ok(self
            .shared
            .handle
            .call(move |d, _| d.core.heard_on(node))
            .await?)
    }

    /// Runs `stop` when the network is closed ([`Network::close`]), after the network itself
    /// has stopped: what started with the network (a simulated station) stops with it.
    pub fn on_close<F, Fut>(&self, stop: F)
    where
        F: FnOnce() -> Fut + Send + 'static,
        Fut: Future<Output = ()> + Send + 'static,
    {
        let task: OnClose = Box::new(move || Box::pin(stop()));
        self.shared
            .on_close
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .push(task);
    }

    /// Stops the network and waits for it; calls made afterwards fail with
    /// [`NetError::Closed`].
    pub async fn close(&self) {
        self.shared.handle.shutdown().await;
        self.shared.sim.shutdown().await;
        let tasks = ::core::mem::take(
            &mut *self
                .shared
                .on_close
                .lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner),
        );
        for t in tasks {
            t().await;
        }
        self.shared.closed.send_replace(true);
    }
}
