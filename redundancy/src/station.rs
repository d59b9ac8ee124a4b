//! A redundant master as a driver runs it: the dual-bus layer below, the [`Supervisor`] above,
//! and the glue that tells the layer which pair member is active.
//!
//! [`SupervisedStation`] is a [`Device`] like [`duocan::Station`], plus: after every input it
//! forwards the supervisor's [`LinkCommand`]s to the [`DualBus`] (so the same-function merge
//! delivers the active member's process data from the instant the role changes), mirrors the
//! supervisor's pairs into the layer, and records the layer's port changes, channel switches and
//! toggles in the supervisor's audit trail. [`SupervisedStation::status`] is the snapshot the
//! application prints: ports, master role, pairs, the other slaves, and the nodes heard on one
//! bus only.

use crate::link::dual_bus::DualBus;
use crate::link::events::LinkEvent;
use crate::link::same_function::PairError;
use crate::pair::Member;
use crate::supervisor::flying_master::MasterRole;
use crate::supervisor::pairs::Phase;
use crate::supervisor::{LinkCommand, Supervisor, SupervisorEvent};
use crate::FrameClassifier;
use core::fmt;
use duocan::frame::instant::earliest;
use duocan::machine::{
    forward_requests, BusLink, Device, Machine, PortRequest, PortStatus, StationEvent,
};
use duocan::od::ObjectDictionary;
use duocan::profile::{IdProfile, Predefined};
use duocan::{Frame, Instant};

/// A redundant master on a dual bus: `C` and `N` are the [`DualBus`]'s (frame classifier,
/// merge slots), `P`, `S`, `T`, `R` the [`Supervisor`]'s.
pub struct SupervisedStation<
    D,
    C = Predefined,
    const N: usize = { crate::DEFAULT_MERGE_SLOTS },
    P = Predefined,
    const S: usize = 8,
    const T: usize = 4,
    const R: usize = 4,
> {
    /// The dual-bus layer.
    pub link: DualBus<C, N>,
    /// The supervisor.
    pub sup: Supervisor<D, P, S, T, R>,
    now: Instant,
}

impl<
        D: ObjectDictionary,
        C: FrameClassifier,
        const N: usize,
        P: IdProfile,
        const S: usize,
        const T: usize,
        const R: usize,
    > SupervisedStation<D, C, N, P, S, T, R>
{
    /// Puts `sup` on `link`; the supervisor's pairs are configured in the layer (same
    /// identifiers), with no active member until the supervisor says so.
    pub fn new(mut link: DualBus<C, N>, sup: Supervisor<D, P, S, T, R>) -> Result<Self, PairError> {
        for (id, p) in sup.pairs() {
            let got = link.add_pair(p.spec.a, p.spec.b, p.active)?;
            debug_assert_eq!(got, id);
        }
        let mut s = SupervisedStation {
            link,
            sup,
            now: Instant::ZERO,
        };
        s.forward();
        Ok(s)
    }

    /// The status snapshot, printable as a table.
    pub fn status(&self, now: Instant) -> Status<'_, D, C, N, P, S, T, R> {
        Status { st: self, now }
    }

    fn forward(&mut self) {
        // The layer's requests (status entries, ECSS pre-operational) go to the master's node.
        forward_requests(self.now, &mut self.link, self.sup.node_mut());
        while let Some(c) = self.sup.poll_link_command() {
            match c {
                LinkCommand::SetActive(p, m) => {
                    self.link.set_active(p, m);
                }
                LinkCommand::Forget(p, m) => self.link.forget_member(p, m),
            }
        }
    }
}

impl<
        D: ObjectDictionary,
        C: FrameClassifier,
        const N: usize,
        P: IdProfile,
        const S: usize,
        const T: usize,
        const R: usize,
    > Device for SupervisedStation<D, C, N, P, S, T, R>
{
    type Event = StationEvent<LinkEvent, SupervisorEvent>;

    fn port_count(&self) -> usize {
        2
    }
    fn handle_rx(&mut self, now: Instant, port: usize, frame: &Frame) {
        self.now = now;
        let f = self.link.handle_rx(now, port, frame);
        self.forward();
        if let Some(f) = f {
            self.sup.handle_frame(now, &f);
            self.forward();
        }
    }
    fn handle_port_status(&mut self, now: Instant, port: usize, status: PortStatus) {
        self.now = now;
        self.link.handle_port_status(now, port, status);
        self.forward();
    }
    fn handle_timeout(&mut self, now: Instant) {
        self.now = now;
        self.link.handle_timeout(now);
        self.sup.handle_timeout(now);
        self.forward();
    }
    fn poll_transmit(&mut self) -> Option<(usize, Frame)> {
        loop {
            if let Some(x) = self.link.poll_transmit() {
                return Some(x);
            }
            let f = self.sup.poll_transmit()?;
            self.link.send(self.now, &f);
        }
    }
    fn poll_port_request(&mut self) -> Option<(usize, PortRequest)> {
        self.link.poll_port_request()
    }
    fn poll_timeout(&self) -> Option<Instant> {
        earliest(self.link.poll_timeout(), self.sup.poll_timeout())
    }
    fn poll_event(&mut self) -> Option<Self::Event> {
        if let Some(e) = self.link.poll_event() {
            self.sup.audit_link(&e);
            return Some(StationEvent::Link(e));
        }
        self.sup.poll_event().map(StationEvent::Machine)
    }
}

/// A snapshot of a supervised station; `Display` prints it as a table.
pub struct Status<'a, D, C, const N: usize, P, const S: usize, const T: usize, const R: usize> {
    st: &'a SupervisedStation<D, C, N, P, S, T, R>,
    now: Instant,
}

fn member_word(m: Option<Member>) -> &'static str {
    match m {
        Some(Member::A) => "A",
        Some(Member::B) => "B",
        None => "-",
    }
}

impl<
        D: ObjectDictionary,
        C: FrameClassifier,
        const N: usize,
        P: IdProfile,
        const S: usize,
        const T: usize,
        const R: usize,
    > fmt::Display for Status<'_, D, C, N, P, S, T, R>
{
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let sup = &self.st.sup;
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
            let h = self.st.link.port(port);
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
        for (n, heard) in self.st.link.reach().iter() {
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
    State(duocan::NmtState),
    Phase(duocan::master::BootPhase),
}

/// A cell padded like a string (`{:<16}`), written without allocating.
struct Word(Shown);

impl fmt::Display for Word {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        use duocan::master::BootPhase as B;
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
