//! The logical network object: what the application holds per dual-bus
//! network.
//!
//! [`LogicalNetwork`] is a thin facade over a [`SupervisedStation`] (dual-bus layer, CiA 302-2
//! master, pair supervision, flying master, audit trail). It adds no state and no behaviour of
//! its own; it gathers what the application needs in one place:
//!
//! | need                         | call                                                        |
//! |------------------------------|-------------------------------------------------------------|
//! | building it                  | [`LogicalNetwork::builder`]: named settings with defaults, all checked ([`RedundantNetworkBuilder`]); with the `tokio` feature `.open(…)` / `.open_named(…)` give the async handle `net::RedundantNetwork` |
//! | its identifier profile       | [`RedundantNetworkBuilder::profile`]: the predefined set or the railway 29-bit scheme, a value ([`NetProfile`], see [`profile`](NetProfile) for why not a type) |
//! | the object dictionary        | [`LogicalNetwork::od`], [`read`](LogicalNetwork::read), [`write`](LogicalNetwork::write) |
//! | SDO access to any node       | [`sdo_read`](LogicalNetwork::sdo_read), [`sdo_write`](LogicalNetwork::sdo_write): a [`RequestId`] now, [`NetworkEventKind::Sdo`] when done |
//! | NMT commands                 | [`nmt`](LogicalNetwork::nmt)                                 |
//! | PDO values                   | [`pdo_value`](LogicalNetwork::pdo_value): the master's mirrored RPDO entries ([`mirror_tpdo`](LogicalNetwork::mirror_tpdo)) |
//! | events                       | [`Device::poll_event`]: one typed stream, [`NetworkEvent`]   |
//! | slave, pair and master state | [`slaves`](LogicalNetwork::slaves), [`pairs`](LogicalNetwork::pairs), [`role`](LogicalNetwork::role) |
//! | manual control               | [`set_active`](LogicalNetwork::set_active), [`set_standby`](LogicalNetwork::set_standby), [`switch_over`](LogicalNetwork::switch_over) |
//! | status snapshot              | [`status`](LogicalNetwork::status), printable as a table     |
//! | audit export                 | [`export_audit_csv`](LogicalNetwork::export_audit_csv), [`export_audit_text`](LogicalNetwork::export_audit_text) |
//!
//! It is a sans-IO [`Device`]: the simulator runs it as any device, and so does the tokio
//! runtime, whose `Handle::request` fits the SDO calls exactly (start on the device, wait for the
//! event with the request id).
//!
//! ```
//! use duocan::od::comm;
//! use duocan::sim::{BusConfig, SimNetwork};
//! use duocan::{Duration, Instant, Node, NodeConfig, NodeId, Station};
//! use duocan_redundancy::{DualBus, DualBusConfig, LogicalNetwork, NetworkEventKind};
//!
//! let ms = Duration::from_millis;
//! let mut sim = SimNetwork::new(1);
//! let buses = [sim.add_bus(BusConfig::new("can1", 1_000_000)), sim.add_bus(BusConfig::new("can2", 1_000_000))];
//! let net = LogicalNetwork::builder()
//!     .node_id(1)
//!     .heartbeat(ms(20))
//!     .master_timeout(ms(50))
//!     .sync(ms(10))
//!     .pair(0x10, 0x50)
//!     .build()?;
//! let net = sim.add_device("turnout rack", net, &buses)?;
//! for id in [0x10, 0x50] {
//!     let mut n = Node::new(NodeConfig::slave(NodeId::must(id)), comm::standard_dictionary(id, Default::default()));
//!     n.boot(Instant::ZERO);
//!     sim.add_device(format!("board {id:#x}"), Station::new(DualBus::new(DualBusConfig::default()), n), &buses)?;
//! }
//! sim.run_until(Instant::from_secs(1));
//! // Read board A's device type over SDO.
//! let now = sim.now();
//! let req = sim.device_mut(net).sdo_read(now, NodeId::must(0x10), 0x1000, 0)?;
//! sim.run_until(Instant::from_millis(1_010));
//! let done = sim.events(net).iter().find_map(|(_, e)| match &e.kind {
//!     NetworkEventKind::Sdo(s) if s.request == req => Some(s.clone()),
//!     _ => None,
//! });
//! assert!(done.is_some_and(|s| s.result.is_ok()));
//! println!("{}", sim.device(net).status(sim.now()));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! The builder ([`RedundantNetworkBuilder`]) names each setting and checks them all before
//! building; the parts underneath can still be built one by one (a [`Master`](duocan::master::Master),
//! a [`Supervisor`] with a [`SupervisorConfig`](crate::SupervisorConfig) and
//! [`PairSpec`](crate::PairSpec)s, a [`DualBus`], a [`SupervisedStation`]) for
//! what the builder does not cover.

mod builder;
mod error;
mod events;
mod profile;
#[cfg(feature = "tokio")]
pub(crate) use events::typed;

pub use builder::{RedundantNetworkBuilder, DEFAULT_HEARTBEAT, DEFAULT_MASTER_TIMEOUT};
pub use error::{RedundantError, Role};
pub use events::{NetworkEvent, NetworkEventKind};
pub use profile::NetProfile;

use crate::link::dual_bus::DualBus;
use crate::pair::{Member, PairId};
use crate::station::{Status, SupervisedStation};
use crate::supervisor::audit::{AuditTrail, AUDIT_CAPACITY};
use crate::supervisor::flying_master::{FlyingMasterError, MasterRole};
use crate::supervisor::pairs::{PairState, PairsError};
use crate::supervisor::Supervisor;
use crate::FrameClassifier;
use core::fmt;
use duocan::cia302::pdo_config::PdoConfig;
use duocan::frame::storage::Heap;
#[cfg(feature = "fd")]
use duocan::frame::FdFrame;
use duocan::machine::Device;
use duocan::master::{MasterError, SlaveView};
use duocan::nmt::NmtTarget;
use duocan::od::abort::AbortCode;
use duocan::od::{DynamicDictionary, ObjectDictionary, OdValue};
use duocan::pdo::Dir;
use duocan::profile::{IdProfile, Predefined};
use duocan::sdo::{RequestId, SdoError, SdoOptions};
use duocan::{Instant, NmtCommand, NodeId};

/// One dual-bus network as the application sees it: `D` is the master's dictionary, `P` the
/// identifier profile (as for the [`SupervisedStation`] underneath).
pub struct LogicalNetwork<D, P: IdProfile + FrameClassifier = Predefined> {
    station: SupervisedStation<D, DualBus<P>>,
}

/// Why a call on the network was refused, or failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NetworkError {
    /// This master is standby: SDO and NMT to other nodes are the active master's (two SDO
    /// clients on one server channel would corrupt each other's transfers).
    Standby,
    /// The SDO client refused the request (busy node, no free session, too long), or, for a
    /// transfer awaited through a runtime handle, the transfer failed.
    Sdo(SdoError),
    /// The master refused the NMT command.
    Nmt(MasterError),
    /// The pair table refused the switch-over.
    Pairs(PairsError),
    /// The flying master refused the role change.
    Role(FlyingMasterError),
    /// The runtime driving the network has stopped (only from calls through a runtime handle,
    /// which then return this one error for everything).
    Closed,
}

impl From<SdoError> for NetworkError {
    fn from(e: SdoError) -> Self {
        NetworkError::Sdo(e)
    }
}

/// A network driven by the tokio runtime: `handle.try_call(|net, now| net.nmt(…)).await?` and
/// `handle.sdo_read(…).await?` return [`NetworkError`] alone, a stopped runtime included.
#[cfg(feature = "tokio")]
impl From<duocan::runtime::RuntimeClosed> for NetworkError {
    fn from(_: duocan::runtime::RuntimeClosed) -> Self {
        NetworkError::Closed
    }
}

impl core::error::Error for NetworkError {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        match self {
            NetworkError::Standby | NetworkError::Closed => None,
            NetworkError::Sdo(e) => Some(e),
            NetworkError::Nmt(e) => Some(e),
            NetworkError::Pairs(e) => Some(e),
            NetworkError::Role(e) => Some(e),
        }
    }
}

impl fmt::Display for NetworkError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            NetworkError::Standby => f.write_str(
                "this master is standby: SDO and NMT go through the active master (or make this one active)",
            ),
            NetworkError::Sdo(e) => write!(f, "{e}"),
            NetworkError::Nmt(e) => write!(f, "{e}"),
            NetworkError::Pairs(e) => write!(f, "{e}"),
            NetworkError::Role(e) => write!(f, "{e}"),
            NetworkError::Closed => f.write_str("the duocan runtime has stopped"),
        }
    }
}

impl<D: ObjectDictionary, P: IdProfile + FrameClassifier> LogicalNetwork<D, P> {
    /// The network run by `station`.
    #[must_use]
    pub fn new(station: SupervisedStation<D, DualBus<P>>) -> Self {
        LogicalNetwork { station }
    }
    /// The station underneath (dual-bus layer and supervisor).
    pub fn station(&self) -> &SupervisedStation<D, DualBus<P>> {
        &self.station
    }
    /// The station underneath, for what the facade does not cover.
    pub fn station_mut(&mut self) -> &mut SupervisedStation<D, DualBus<P>> {
        &mut self.station
    }
    /// The supervisor.
    pub fn supervisor(&self) -> &Supervisor<D, P> {
        self.station.sup()
    }

    // ----- dictionary -----

    /// The master's object dictionary.
    pub fn od(&self) -> &D {
        self.station.sup().node().od()
    }
    /// Reads an entry of the master's dictionary (no access check: the application's own).
    pub fn read(&self, index: u16, sub: u8) -> Result<&[u8], AbortCode> {
        self.od().get(index, sub).map(|e| e.data)
    }
    /// Writes an entry of the master's dictionary, with the stack's reactions.
    pub fn write(
        &mut self,
        now: Instant,
        index: u16,
        sub: u8,
        data: &[u8],
    ) -> Result<(), AbortCode> {
        self.station
            .sup_mut()
            .node_mut()
            .write(now, index, sub, data)
    }

    // ----- SDO -----

    /// Reads (index, sub) of `node` over SDO; the result comes as [`NetworkEventKind::Sdo`]
    /// with the returned id.
    pub fn sdo_read(
        &mut self,
        now: Instant,
        node: NodeId,
        index: u16,
        sub: u8,
    ) -> Result<RequestId, NetworkError> {
        self.sdo_read_with(now, node, index, sub, SdoOptions::default())
    }
    /// [`LogicalNetwork::sdo_read`] with options (protocol, timeout, channel).
    pub fn sdo_read_with(
        &mut self,
        now: Instant,
        node: NodeId,
        index: u16,
        sub: u8,
        opts: SdoOptions,
    ) -> Result<RequestId, NetworkError> {
        self.check_active()?;
        self.station
            .sup_mut()
            .sdo_mut()
            .upload(now, node, index, sub, opts)
            .map_err(NetworkError::Sdo)
    }
    /// Writes `data` to (index, sub) of `node` over SDO; the result comes as
    /// [`NetworkEventKind::Sdo`] with the returned id.
    pub fn sdo_write(
        &mut self,
        now: Instant,
        node: NodeId,
        index: u16,
        sub: u8,
        data: &[u8],
    ) -> Result<RequestId, NetworkError> {
        self.sdo_write_with(now, node, index, sub, data, SdoOptions::default())
    }
    /// [`LogicalNetwork::sdo_write`] with options.
    pub fn sdo_write_with(
        &mut self,
        now: Instant,
        node: NodeId,
        index: u16,
        sub: u8,
        data: &[u8],
        opts: SdoOptions,
    ) -> Result<RequestId, NetworkError> {
        self.check_active()?;
        self.station
            .sup_mut()
            .sdo_mut()
            .download(now, node, index, sub, data, opts)
            .map_err(NetworkError::Sdo)
    }

    // ----- NMT -----

    /// Sends an NMT command (active master only; the master's view of the slaves follows it).
    pub fn nmt(
        &mut self,
        now: Instant,
        cmd: NmtCommand,
        target: NmtTarget,
    ) -> Result<(), NetworkError> {
        self.station
            .sup_mut()
            .nmt(now, cmd, target)
            .map_err(|e| match e {
                MasterError::Standby => NetworkError::Standby,
                e => NetworkError::Nmt(e),
            })
    }

    // ----- PDO -----

    /// The bytes of a master dictionary entry an RPDO writes (see
    /// [`LogicalNetwork::mirror_tpdo`]): the latest value received.
    pub fn pdo_value(&self, index: u16, sub: u8) -> Result<&[u8], AbortCode> {
        self.read(index, sub)
    }
    /// [`LogicalNetwork::pdo_value`], decoded.
    pub fn pdo_value_as<V: OdValue>(&self, index: u16, sub: u8) -> Result<V, AbortCode> {
        self.od().get_value(index, sub)
    }

    // ----- state and control -----

    /// Every slave of the master (pair members included).
    pub fn slaves(&self) -> impl Iterator<Item = SlaveView> + '_ {
        self.station.sup().slaves()
    }
    /// What the master knows of one node.
    pub fn slave(&self, node: NodeId) -> SlaveView {
        self.station.sup().master().slave(node)
    }
    /// The pair table.
    pub fn pairs(&self) -> impl Iterator<Item = (PairId, &PairState)> + '_ {
        self.station.sup().pairs()
    }
    /// Makes `to` the active member of `pair` (active master only).
    pub fn switch_over(
        &mut self,
        now: Instant,
        pair: PairId,
        to: Member,
    ) -> Result<(), NetworkError> {
        self.station
            .sup_mut()
            .switch_over(now, pair, to)
            .map_err(NetworkError::Pairs)
    }
    /// This master's role.
    pub fn role(&self) -> MasterRole {
        self.station.sup().role()
    }
    /// Makes this standby master active by hand (between two SYNCs).
    pub fn set_active(&mut self, now: Instant) -> Result<(), NetworkError> {
        self.station
            .sup_mut()
            .set_active(now)
            .map_err(NetworkError::Role)
    }
    /// Hands the role of this active master to the best live one (between two SYNCs).
    pub fn set_standby(&mut self, now: Instant) -> Result<(), NetworkError> {
        self.station
            .sup_mut()
            .set_standby(now)
            .map_err(NetworkError::Role)
    }

    // ----- status and audit -----

    /// Ports, master role, pairs, slaves: `Display` prints a table.
    pub fn status(&self, now: Instant) -> Status<'_, D, DualBus<P>> {
        self.station.status(now)
    }
    /// The audit trail (every role change, switch and toggle with reason and time).
    pub fn audit(&self) -> &AuditTrail<AUDIT_CAPACITY, Heap> {
        self.station.sup().audit()
    }
    /// The audit trail as CSV (`seq,time_us,kind,subject,from,to,reason`).
    pub fn export_audit_csv(&self, out: &mut impl fmt::Write) -> fmt::Result {
        self.audit().write_csv(out)
    }
    /// The audit trail as text, one line per record.
    pub fn export_audit_text(&self, out: &mut impl fmt::Write) -> fmt::Result {
        self.audit().write_text(out)
    }

    fn check_active(&self) -> Result<(), NetworkError> {
        if self.station.sup().is_active() {
            Ok(())
        } else {
            Err(NetworkError::Standby)
        }
    }
}

impl<P: IdProfile + FrameClassifier> LogicalNetwork<DynamicDictionary, P> {
    /// Makes the master's RPDO `m.pdo` the other end of a slave's TPDO configured as `remote`:
    /// the values land in the master's entries `m.locals` (created where missing), read with
    /// [`LogicalNetwork::pdo_value`]; each reception is a [`NetworkEventKind::PdoReceived`].
    /// Both masters of a network mirror the same way, so a standby has the values too.
    pub fn mirror_tpdo(
        &mut self,
        now: Instant,
        remote: &PdoConfig,
        m: &duocan::cia302::pdo_config::Mirror<'_>,
    ) -> Result<(), duocan::cia302::pdo_config::MirrorError> {
        duocan::cia302::pdo_config::mirror(
            self.station.sup_mut().node_mut(),
            now,
            Dir::Transmit,
            remote,
            m,
        )
    }
}

impl<D: ObjectDictionary, P: IdProfile + FrameClassifier> Device for LogicalNetwork<D, P> {
    type Event = NetworkEvent;

    duocan::forward_device_to!(station);
    /// FD-capable when the station's layer is (both ports), on a CANopen FD network.
    #[cfg(feature = "fd")]
    fn fd_capable(&self) -> bool {
        self.station.fd_capable()
    }
    #[cfg(feature = "fd")]
    fn handle_rx_fd(&mut self, now: Instant, port: usize, frame: &FdFrame, at: Instant) {
        self.station.handle_rx_fd(now, port, frame, at);
    }
    #[cfg(feature = "fd")]
    fn poll_transmit_fd(&mut self) -> Option<(usize, FdFrame)> {
        self.station.poll_transmit_fd()
    }
    fn poll_event(&mut self) -> Option<NetworkEvent> {
        let e = self.station.poll_event()?;
        let at = events::when(&e);
        let kind = events::typed(&e).unwrap_or(NetworkEventKind::Other(e));
        Some(NetworkEvent { at, kind })
    }
}

/// SDO through the tokio runtime: `handle.sdo_read(node, index, sub, opts).await?` starts the
/// transfer on the network (refused on a standby master) and waits for its
/// [`NetworkEventKind::Sdo`]; every failure is one [`NetworkError`].
#[cfg(feature = "tokio")]
impl<D: ObjectDictionary, P: IdProfile + FrameClassifier> duocan::runtime::SdoHost
    for LogicalNetwork<D, P>
{
    type Error = NetworkError;
    fn sdo_start(
        &mut self,
        now: Instant,
        r: duocan::runtime::SdoStart<'_>,
    ) -> Result<RequestId, NetworkError> {
        match r.data {
            None => self.sdo_read_with(now, r.node, r.index, r.sub, r.opts),
            Some(d) => self.sdo_write_with(now, r.node, r.index, r.sub, d, r.opts),
        }
    }
}

#[cfg(feature = "tokio")]
impl duocan::runtime::SdoEvents for NetworkEvent {
    fn sdo_result(&self) -> Option<(RequestId, Result<alloc::vec::Vec<u8>, SdoError>)> {
        match &self.kind {
            NetworkEventKind::Sdo(s) => s.sdo_result(),
            _ => None,
        }
    }
}

impl<D, P: IdProfile + FrameClassifier> fmt::Debug for LogicalNetwork<D, P> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("LogicalNetwork")
            .field("sup", self.station.sup())
            .finish_non_exhaustive()
    }
}
