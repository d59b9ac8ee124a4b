//! A redundant master as a driver runs it: the dual-bus layer below, the [`Supervisor`] above.
//!
//! The composition itself is the protocol core's: a [`Station`] of a [`DualBus`] and a
//! [`Supervisor`] hands the layer's requests to the master's node and the supervisor's
//! [`LinkCommand`]s to the layer after every input (so the same-function
//! merge delivers the active member's process data from the instant the role changes).
//! [`SupervisedStation`] wraps that station for what only a redundant master has: the
//! supervisor's pairs configured in the layer from the start, the layer's port changes,
//! channel switches and toggles recorded in the supervisor's audit trail, and
//! [`SupervisedStation::status`], the snapshot the application prints: ports, master role,
//! pairs, the other slaves, and the nodes heard on one bus only. With the feature `fd`, a
//! station whose layer's ports are all FD-capable runs on CAN FD buses and exchanges FD frames
//! through its layer, its supervisor's master serving USDO (see [`fd`]).
//!
//! A redundant master whose pair has only board A on the buses, and bus 2 cut:
//!
//! ```
//! # use duocan_core::master::{objects, Master, MasterConfig};
//! # use duocan_core::od::comm;
//! # use duocan::sim::{BusConfig, SimNetwork};
//! # use duocan_core::{Duration, Instant, Node, NodeConfig, NodeId, Station};
//! # use duocan_redundancy_core::{DualBus, DualBusConfig, PairSpec, RedundantMaster, Supervisor, SupervisorConfig};
//! # let ms = Duration::from_millis;
//! # let mut sim = SimNetwork::new(1);
//! # let buses = [sim.add_bus(BusConfig::new("can1", 1_000_000)), sim.add_bus(BusConfig::new("can2", 1_000_000))];
//! let master = Master::new(NodeId::must(1), objects::master_dictionary(1, comm::Identity::default()), MasterConfig::new())?;
//! let mut sup = Supervisor::new(master, SupervisorConfig::new(0, NodeId::must(1), ms(20), ms(50), ms(10)), Instant::ZERO);
//! sup.add_pair(Instant::ZERO, PairSpec::new(NodeId::must(0x10), NodeId::must(0x50), ms(20), ms(50)))?;
//! let station: RedundantMaster = RedundantMaster::new(DualBus::new(DualBusConfig::default()), sup)?;
//! let m = sim.add_device("master", station, &buses)?;
//! # let mut a = Node::new(NodeConfig::slave(NodeId::must(0x10)), comm::standard_dictionary(0x10, Default::default()));
//! # a.boot(Instant::ZERO);
//! # sim.add_device("board A", Station::new(DualBus::new(DualBusConfig::default()), a), &buses)?;
//! sim.run_until(Instant::from_millis(500));
//! sim.bus_down(buses[1]);
//! sim.run_until(Instant::from_secs(1));
//!
//! // Master role, ports, pairs (state and boot phase of each member), one-bus nodes:
//! let table = sim.device(m).status(sim.now()).to_string();
//! println!("{table}");
//! let line = |start: &str| {
//!     let l = table.lines().find(|l| l.starts_with(start)).unwrap();
//!     l.split_whitespace().collect::<Vec<_>>()
//! };
//! assert_eq!(line("master"), ["master", "node", "0x01", "(0):", "active"]);
//! assert_eq!(line("bus 1")[2], "ok");
//! assert_ne!(line("bus 2")[2], "ok");
//! assert_eq!(line("0 "), ["0", "A", "0x10", "operational", "joined", "0x50", "unknown", "waiting"]);
//! assert!(table.contains("node 0x10 heard on bus 1 only"));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use crate::link::capacity::MergeCapacity;
use crate::link::dual_bus::{DualBus, LinkCommand};
use crate::link::events::LinkEvent;
use crate::link::same_function::PairError;
use crate::pair::Member;
use crate::supervisor::flying_master::MasterRole;
use crate::supervisor::pairs::Phase;
use crate::supervisor::{Supervisor, SupervisorEvent};
use crate::FrameClassifier;
use core::fmt;
use core::ops::{Deref, DerefMut};
use duocan_core::machine::{
    forward_commands, forward_requests, BusLink, Device, PortRequest, PortStatus, Station,
    StationEvent,
};
use duocan_core::od::{DynamicDictionary, ObjectDictionary};
use duocan_core::profile::{IdProfile, Predefined};
use duocan_core::{Frame, Instant};

/// The link a [`SupervisedStation`] runs on: a [`DualBus`], whatever its classifier and
/// capacity (sealed: implemented by `DualBus<C, K>` only). It bundles the layer's two
/// parameters into the one the station names, so that `SupervisedStation<D, L>` has two: the
/// dictionary, and the link whose classifier is also the supervisor's identifier profile.
pub trait SupervisedLink:
    BusLink<Event = LinkEvent, Command = LinkCommand> + sealed::SealedLink
{
    /// The identifier profile: the layer's frame classifier and the supervisor's profile.
    type Classifier: IdProfile + FrameClassifier;
    /// The layer's capacity.
    type Capacity: MergeCapacity;
    /// The layer itself.
    fn dual_bus(&self) -> &DualBus<Self::Classifier, Self::Capacity>;
    /// The layer itself.
    fn dual_bus_mut(&mut self) -> &mut DualBus<Self::Classifier, Self::Capacity>;
}

mod sealed {
    pub trait SealedLink {}
    impl<C, K: super::MergeCapacity> SealedLink for super::DualBus<C, K> {}
}

impl<C: IdProfile + FrameClassifier, K: MergeCapacity> SupervisedLink for DualBus<C, K> {
    type Classifier = C;
    type Capacity = K;
    #[inline]
    fn dual_bus(&self) -> &DualBus<C, K> {
        self
    }
    #[inline]
    fn dual_bus_mut(&mut self) -> &mut DualBus<C, K> {
        self
    }
}

/// The supervisor of a station on the link `L`: its identifier profile is the link's classifier.
type SupOf<D, L> = Supervisor<D, <L as SupervisedLink>::Classifier>;

/// A redundant master on a dual bus: a [`Station`] of a [`DualBus`] and a [`Supervisor`] (which
/// it dereferences to: `link` and `machine`), plus its status table. `D` is the master's
/// dictionary; `L` the link, a [`DualBus`] whose classifier is also the supervisor's
/// identifier profile ([`Predefined`] by default) and whose capacity sizes the merger and the
/// same-function table (the layer's defaults unless a small target sizes them to its network:
/// a microcontroller master with a few pairs needs neither 1,024 merger slots nor 256
/// functions, see [`crate::link::capacity`]):
///
/// ```
/// use duocan_core::od::DynamicDictionary;
/// use duocan_core::profile::Predefined;
/// use duocan_redundancy_core::{Capacity, DualBus, SupervisedStation};
///
/// // A host's master: the predefined connection set and the layer's default capacity.
/// type Host = SupervisedStation<DynamicDictionary>;
/// // A board's: 64 merger slots, 16 same-function values.
/// type Board = SupervisedStation<DynamicDictionary, DualBus<Predefined, Capacity<64, 16>>>;
/// ```
pub struct SupervisedStation<D, L: SupervisedLink = DualBus> {
    station: Station<L, SupOf<D, L>>,
    /// CAN FD frames the layer delivered, for the application (see [`fd`]).
    #[cfg(feature = "fd")]
    fd_rx: duocan_core::frame::queue::Bounded<duocan_core::frame::FdFrame, { fd::FD_RX_QUEUE }>,
}

/// The common redundant master: a dictionary built at run time, on the predefined connection set
/// unless `P` says otherwise.
pub type RedundantMaster<P = Predefined> = SupervisedStation<DynamicDictionary, DualBus<P>>;

impl<D: ObjectDictionary, L: SupervisedLink> SupervisedStation<D, L> {
    /// Puts `sup` on `link`; the supervisor's pairs are configured in the layer (same
    /// identifiers), with no active member until the supervisor says so.
    pub fn new(link: L, sup: SupOf<D, L>) -> Result<Self, PairError> {
        let mut st = Self::unlinked(|| link, || sup);
        st.link_pairs()?;
        Ok(st)
    }

    /// The supervisor `make_sup` builds on the layer `make_link` builds, their pairs not yet
    /// configured in the layer: what [`new`](Self::new) does in two steps, for building the
    /// station in place. The two are called as the station is written, so that constructors
    /// that are not inlined write them straight into it (on a microcontroller every move of
    /// these tens of kilobytes is a copy on the stack); [`link_pairs`](Self::link_pairs) then
    /// does the rest where the station stands.
    #[must_use]
    #[inline(never)]
    pub fn unlinked(make_link: impl FnOnce() -> L, make_sup: impl FnOnce() -> SupOf<D, L>) -> Self {
        // One level of nesting per function that is not inlined: the compiler writes a
        // call's result straight into the caller's result, but not through two levels.
        SupervisedStation {
            station: station(make_link, make_sup),
            #[cfg(feature = "fd")]
            fd_rx: duocan_core::frame::queue::Bounded::new(),
        }
    }

    /// Configures the supervisor's pairs in the layer (same identifiers), with no active
    /// member until the supervisor says so, and hands over what either decided while they were
    /// built: the second step of [`new`](Self::new), once, after the supervisor has its pairs.
    pub fn link_pairs(&mut self) -> Result<(), PairError> {
        let Station { link, machine, .. } = &mut self.station;
        for (id, p) in machine.pairs() {
            let got = link.dual_bus_mut().add_pair(p.spec.a, p.spec.b, p.active)?;
            debug_assert_eq!(got, id);
        }
        // What either decided while they were built applies before the first input.
        forward_requests(Instant::ZERO, link, machine);
        forward_commands(Instant::ZERO, machine, link);
        Ok(())
    }

    /// The status snapshot, printable as a table.
    pub fn status(&self, now: Instant) -> Status<'_, D, L> {
        Status { st: self, now }
    }
}

/// The station of [`SupervisedStation::unlinked`], built where the caller wants it.
#[inline(never)]
fn station<L, M>(make_link: impl FnOnce() -> L, make_sup: impl FnOnce() -> M) -> Station<L, M>
where
    L: duocan_core::machine::BusLink,
    M: duocan_core::Machine,
{
    Station::new(make_link(), make_sup())
}

impl<D, L: SupervisedLink> SupervisedStation<D, L> {
    /// The supervisor.
    pub fn sup(&self) -> &SupOf<D, L> {
        &self.station.machine
    }
    /// The supervisor, for the application's commands (switch-over, NMT, SDO, time).
    pub fn sup_mut(&mut self) -> &mut SupOf<D, L> {
        &mut self.station.machine
    }
    /// The station inside.
    pub fn into_station(self) -> Station<L, SupOf<D, L>> {
        self.station
    }
}

impl<D, L: SupervisedLink> Deref for SupervisedStation<D, L> {
    type Target = Station<L, SupOf<D, L>>;
    fn deref(&self) -> &Self::Target {
        &self.station
    }
}

impl<D, L: SupervisedLink> DerefMut for SupervisedStation<D, L> {
    fn deref_mut(&mut self) -> &mut Self::Target {
        &mut self.station
    }
}

impl<D: ObjectDictionary, L: SupervisedLink> Device for SupervisedStation<D, L> {
    type Event = StationEvent<LinkEvent, SupervisorEvent>;

    fn port_count(&self) -> usize {
        self.station.port_count()
    }
    fn handle_rx(&mut self, now: Instant, port: usize, frame: &Frame) {
        self.station.handle_rx(now, port, frame);
    }
    fn handle_rx_at(&mut self, now: Instant, port: usize, frame: &Frame, at: Instant) {
        self.station.handle_rx_at(now, port, frame, at);
    }
    fn handle_port_status(&mut self, now: Instant, port: usize, status: PortStatus) {
        self.station.handle_port_status(now, port, status);
    }
    fn handle_timeout(&mut self, now: Instant) {
        self.station.handle_timeout(now);
    }
    fn poll_transmit(&mut self) -> Option<(usize, Frame)> {
        self.station.poll_transmit()
    }
    fn poll_port_request(&mut self) -> Option<(usize, PortRequest)> {
        self.station.poll_port_request()
    }
    fn poll_timeout(&self) -> Option<Instant> {
        self.station.poll_timeout()
    }
    #[cfg(feature = "fd")]
    fn fd_capable(&self) -> bool {
        self.station.link.dual_bus().fd_capable()
    }
    #[cfg(feature = "fd")]
    fn handle_rx_fd(
        &mut self,
        now: Instant,
        port: usize,
        frame: &duocan_core::frame::FdFrame,
        at: Instant,
    ) {
        self.rx_fd(now, port, frame, at);
    }
    /// The layer's FD copies, then the supervisor's FD frames (its master's USDO answers)
    /// handed to the layer.
    #[cfg(feature = "fd")]
    fn poll_transmit_fd(&mut self) -> Option<(usize, duocan_core::frame::FdFrame)> {
        self.station.poll_transmit_fd()
    }
    fn poll_event(&mut self) -> Option<Self::Event> {
        let e = self.station.poll_event()?;
        // The audit trail records the layer's switches, toggles and port changes as the
        // application sees them.
        if let StationEvent::Link(l) = &e {
            self.station.machine.audit_link(l);
        }
        Some(e)
    }
}

#[cfg(feature = "fd")]
pub mod fd;

/// A snapshot of a supervised station; `Display` prints it as a table.
pub struct Status<'a, D, L: SupervisedLink = DualBus> {
    st: &'a SupervisedStation<D, L>,
    now: Instant,
}

fn member_word(m: Option<Member>) -> &'static str {
    match m {
        Some(Member::A) => "A",
        Some(Member::B) => "B",
        None => "-",
    }
}

impl<D: ObjectDictionary, L: SupervisedLink> fmt::Display for Status<'_, D, L> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let sup = self.st.sup();
        let fm = sup.flying_master();
        writeln!(f, "status at {}", self.now)?;
        write!(
            f,
            "master {} ({}): {}",
            fm.rank().node,
            fm.rank().priority,
            fm.role()
        )?;
        if fm.is_active() && !fm.may_command(self.now) {
            write!(f, ", commands suspended")?;
        }
        writeln!(f)?;
        for p in fm.peers() {
            let alive = p
                .last
                .is_some_and(|l| l + fm.config().master_timeout > self.now);
            writeln!(
                f,
                "  peer {} priority {}: {}",
                p.rank.node,
                p.rank.priority,
                if alive { "alive" } else { "silent" }
            )?;
        }
        writeln!(f, "port  state       rx        tx        tx failed")?;
        for port in 0..2 {
            let h = self.st.link.dual_bus().port(port);
            let c = h.counters();
            writeln!(
                f,
                "bus {} {:<11} {:<9} {:<9} {}",
                port + 1,
                h.state(),
                c.rx,
                c.tx,
                c.tx_failed
            )?;
        }
        writeln!(
            f,
            "pair  active  A node  A state          A phase      B node  B state          B phase"
        )?;
        for (id, p) in sup.pairs() {
            write!(f, "{:<5} {:<7}", id.0, member_word(p.active))?;
            for m in [Member::A, Member::B] {
                let s = p.member(m);
                let nmt = s.nmt.map_or(
                    heapless::String::<16>::try_from("unknown").unwrap_or_default(),
                    |n| {
                        let mut x = heapless::String::<16>::new();
                        let _ = fmt::write(&mut x, format_args!("{n}"));
                        x
                    },
                );
                let phase = match (s.phase(), s.missing()) {
                    _ if sup.pair_supervisor().is_suspect(s.node) => "suspect",
                    (Phase::Waiting, _) if s.is_rejected() => "rejected",
                    (Phase::Waiting, true) => "missing",
                    (ph, _) => match ph {
                        Phase::Waiting => "waiting",
                        Phase::Configuring => "configuring",
                        Phase::Joined => "joined",
                    },
                };
                write!(
                    f,
                    " {:#04x}    {:<16} {:<12}",
                    s.node.raw(),
                    nmt.as_str(),
                    phase
                )?;
            }
            writeln!(f)?;
        }
        let mut header = false;
        for v in sup
            .slaves()
            .filter(|v| sup.pair_supervisor().locate(v.node).is_none())
        {
            if !header {
                writeln!(f, "slave  state            boot phase   error")?;
                header = true;
            }
            let state = Word(v.state.map(Shown::State).unwrap_or(Shown::Unknown));
            let phase = Word(Shown::Phase(v.phase));
            write!(f, "{:#04x}   {:<16} {:<12}", v.node.raw(), state, phase)?;
            match (v.missing, v.last_error) {
                (true, _) => writeln!(f, " missing")?,
                (false, Some(e)) => writeln!(f, " {}", e.letter())?,
                (false, None) => writeln!(f, " -")?,
            }
        }
        let others: usize = sup
            .node()
            .remotes()
            .filter(|(n, _)| sup.pair_supervisor().locate(*n).is_none())
            .filter(|(n, _)| !sup.master().slave(*n).assignment.is_slave())
            .count();
        writeln!(f, "other nodes heard: {others}")?;
        for (n, heard) in self.st.link.dual_bus().reach().iter() {
            match heard {
                [true, false] => writeln!(f, "node {:#04x} heard on bus 1 only", n.raw())?,
                [false, true] => writeln!(f, "node {:#04x} heard on bus 2 only", n.raw())?,
                _ => {}
            }
        }
        if let MasterRole::Standby(Some(r)) = fm.role() {
            writeln!(f, "following {}", r)?;
        }
        Ok(())
    }
}

/// What a status cell shows.
enum Shown {
    Unknown,
    State(duocan_core::NmtState),
    Phase(duocan_core::master::BootPhase),
}

/// A cell padded like a string (`{:<16}`), written without allocating.
struct Word(Shown);

impl fmt::Display for Word {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        use duocan_core::master::BootPhase as B;
        let mut s = heapless::String::<24>::new();
        let _ = match &self.0 {
            Shown::Unknown => fmt::write(&mut s, format_args!("unknown")),
            Shown::State(n) => fmt::write(&mut s, format_args!("{n}")),
            Shown::Phase(p) => fmt::write(
                &mut s,
                format_args!(
                    "{}",
                    match p {
                        B::Unassigned => "unassigned",
                        B::Observed => "observed",
                        B::WaitBootUp => "wait boot-up",
                        B::WaitState => "wait state",
                        B::Identifying => "identifying",
                        B::Configuring => "configuring",
                        B::WaitStart => "wait start",
                        B::Ready => "ready",
                        B::Started => "started",
                        B::Adopted => "adopted",
                        B::Failed(_) => "failed",
                    }
                ),
            ),
        };
        f.pad(s.as_str())
    }
}
