//! What the monitor knows about the network, without a terminal: fed the network's events,
//! the frames its tap sees and the ports' figures, asked for rows of text ([`View`]).
//!
//! **The rule.** A node's state is the one its last heartbeat (0x700 + node-ID, one byte, the
//! toggle bit aside; a boot-up is `initialising`) or event told. Its heartbeat age is the time
//! since its last heartbeat on any port. It is *silent* once that age passes three of its
//! periods, and 100 ms at least; its period is measured on each port apart (on two ports
//! every heartbeat arrives twice, and a copy is no period), not from a boot-up to the first
//! heartbeat, and not to or from a heartbeat whose state differs from the one before it: a
//! device may send one at once on a state change (CiA 301 allows it; CANopenNode does), which
//! says nothing of its period. Such a heartbeat keeps the period measured before it. A pair's active member is the member that is operational and not silent, its
//! standby the one that is pre-operational; anything else is shown as it is (`both`, `none`,
//! `not heard`). The active master is the node-ID in the latest CiA 302-2 active-master
//! response (0x71: priority, node-ID). Ports are as the network reports them; a port's state
//! change applies at once with its event.
//!
//! **Its log.** The network's events, one line each; a state a node's heartbeat tells is
//! logged from the heartbeat (`node 0x04: operational`), once, whether the network's event for
//! it comes after or came before the monitor listened (a node already running when the monitor
//! starts: its first state event may precede the subscription).
//!
//! **Own observations.** Beside the network's events, the model logs what it concludes itself,
//! as lines starting with `monitor:`: a pair's active member changed (a new one after another
//! is a failover, even with a moment of `none` or `both` between), the active master changed, a
//! node went silent and was heard again.
//!
//! **Memory.** At most 127 nodes (a node-ID is 1–127), [`MAX_PORTS`] ports, [`MAX_PAIRS`]
//! pairs, and a ring of the last [`EVENTS_KEPT`] log lines: when it is full the oldest line
//! goes and is counted ([`View::dropped`]).
//!
//! ```text
//! let mut m = Model::new(Names::new(), vec![(0x10, 0x50)]);
//! m.on_frame(Instant::from_millis(5), Some(0), true, &heartbeat(0x10, 0x05));
//! m.on_frame(Instant::from_millis(5), Some(0), true, &heartbeat(0x50, 0x7F));
//! let view = m.view(Instant::from_millis(105), "");
//! assert_eq!(view.nodes[0].hb_age, "100 ms");
//! assert_eq!((view.pairs[0].active.as_str(), view.pairs[0].standby.as_str()), ("0x10", "0x50"));
//! ```
//! (as `model_tests.rs` runs it)

use duocan::net::{HeardOn, NetEvent};
use duocan::{Frame, Id, Instant, NmtState};
use std::collections::{BTreeMap, VecDeque};

/// Log lines kept for the events panel and the plain output.
pub const EVENTS_KEPT: usize = 1000;
/// Ports shown: one, or two as one logical bus.
pub const MAX_PORTS: usize = 2;
/// Pairs tracked (`--pair` beyond this is refused).
pub const MAX_PAIRS: usize = 63;
/// The active-master response of CiA 302-2 (priority, node-ID).
pub const ACTIVE_MASTER_RESPONSE: u16 = 0x71;
/// A heartbeat counts as silent after this many of the node's own periods…
const SILENT_PERIODS: u64 = 3;
/// … and at least this long (µs): a late beat of a fast heartbeat is jitter, not silence.
const SILENT_MIN: u64 = 100_000;

/// One node as last heard.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct NodeInfo {
    /// Its NMT state, from its heartbeats and events.
    pub state: Option<NmtState>,
    /// Its last heartbeat (or boot-up) frame on each port.
    pub last_hb: [Option<Instant>; MAX_PORTS],
    /// The time between two of its heartbeats on each port, in µs: its period as heard (the
    /// latest steady one: see the module's rule).
    pub period: [Option<u64>; MAX_PORTS],
    /// Its last heartbeat's state code on each port, the toggle bit aside.
    pub last_code: [Option<u8>; MAX_PORTS],
    /// Whether that heartbeat changed the state heard before it on its port.
    pub changed: [bool; MAX_PORTS],
    /// Its last emergency: code, text, when.
    pub emcy: Option<(u16, &'static str, Instant)>,
    /// True while its heartbeat is silent (logged once).
    pub silent: bool,
    /// The bus(es) it was heard on, if the network says (two ports).
    pub heard_on: Option<String>,
}

impl NodeInfo {
    /// Its last heartbeat on any port.
    fn last_heartbeat(&self) -> Option<Instant> {
        self.last_hb.iter().flatten().max().copied()
    }
}

/// One port's row.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PortInfo {
    /// Its name (`can0`, `sim-bus1`).
    pub name: String,
    /// Its state: ok, suspect, failed, recovering (two ports); ok, error, down (one).
    pub state: String,
    /// Frames received.
    pub rx: u64,
    /// Frames sent.
    pub tx: u64,
    /// Errors (error frames, failed sends).
    pub errors: u64,
}

/// The active master as its last 0x71 frame announced it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Master {
    /// Its node-ID.
    pub node: u8,
    /// Its priority (lower wins).
    pub priority: u8,
    /// When it was announced.
    pub at: Instant,
}

/// One line of the log: a network event or an observation of the monitor.
#[derive(Clone, Debug, PartialEq)]
pub struct Logged {
    /// Its number since the monitor started (the plain output prints each once).
    pub seq: u64,
    /// When (the network's clock).
    pub at: Instant,
    /// The node it is about.
    pub node: Option<u8>,
    /// Its kind, for `--json`: `boot-up`, `state`, `heartbeat-lost`, `heartbeat-back`, `emcy`,
    /// `pdo`, `port`, `lagged`, `monitor`, `other`.
    pub kind: &'static str,
    /// The line (the event's Display, or the observation).
    pub text: String,
}

/// Names of the nodes, from the descriptions attached (device names).
pub type Names = BTreeMap<u8, String>;

/// The whole state of the monitor.
#[derive(Clone, Debug, Default)]
pub struct Model {
    names: Names,
    nodes: BTreeMap<u8, NodeInfo>,
    /// As the network reports them ([`Model::set_ports`]); a port state change is applied at
    /// once from its event.
    ports: Vec<PortInfo>,
    pairs: Vec<(u8, u8)>,
    /// Each pair's active member as last seen, and the last one there was (for the failover
    /// observation).
    active: Vec<(Option<u8>, Option<u8>)>,
    master: Option<Master>,
    log: VecDeque<Logged>,
    seq: u64,
    dropped: u64,
}

/// A pair's roles, as text.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PairRow {
    /// The members' node-IDs.
    pub members: [u8; 2],
    /// `0x10/0x50`.
    pub pair: String,
    /// The active member (`0x10`), `none` or `both`.
    pub active: String,
    /// The standby member, `-` if none.
    pub standby: String,
}

/// A node's row, as text.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct NodeRow {
    /// The node-ID.
    pub node: u8,
    /// Milliseconds since its last heartbeat.
    pub age_ms: Option<u64>,
    /// `0x05`.
    pub id: String,
    /// `operational`, `-` if not known yet.
    pub state: String,
    /// `80 ms`, `2.4 s`, `-` if never heard; ` silent` appended while silent.
    pub hb_age: String,
    /// `0x8130 life guard or heartbeat error`, `-`.
    pub emcy: String,
    /// The device name, `-`.
    pub name: String,
    /// Bus(es) heard on, `-` if not known.
    pub heard_on: String,
}

/// What a screen or a status line shows at one moment.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct View {
    /// Node rows matching the filter, by node-ID.
    pub nodes: Vec<NodeRow>,
    /// Nodes known in all (filter or not).
    pub known: usize,
    /// Port rows.
    pub ports: Vec<PortInfo>,
    /// Pair rows.
    pub pairs: Vec<PairRow>,
    /// `0x01 (priority 0), heartbeat 80 ms`, or `-` before the first 0x71.
    pub master: String,
    /// The active master as announced.
    pub master_info: Option<Master>,
    /// Log lines matching the filter, oldest first: `time`, `text`.
    pub events: Vec<(Instant, String)>,
    /// Log lines the ring has dropped (the oldest, when it was full).
    pub dropped: u64,
}

impl Model {
    /// A model with the device names known and the pairs declared (at most [`MAX_PAIRS`]).
    pub fn new(names: Names, mut pairs: Vec<(u8, u8)>) -> Model {
        pairs.truncate(MAX_PAIRS);
        Model {
            names,
            active: vec![(None, None); pairs.len()],
            pairs,
            ..Model::default()
        }
    }

    /// The device names, from the descriptions attached.
    pub fn set_names(&mut self, names: Names) {
        self.names = names;
    }

    /// The ports as the network reports them (names, states, counters).
    pub fn set_ports(&mut self, ports: Vec<PortInfo>) {
        self.ports = ports;
        self.ports.truncate(MAX_PORTS);
    }

    #[cfg(test)]
    /// The node-IDs known.
    pub fn node_ids(&self) -> Vec<u8> {
        self.nodes.keys().copied().collect()
    }

    fn node(&mut self, id: u8) -> Option<&mut NodeInfo> {
        // 1–127 only: the map holds at most 127 nodes.
        (1..=127)
            .contains(&id)
            .then(|| self.nodes.entry(id).or_default())
    }

    /// One event of the network.
    pub fn on_event(&mut self, e: &NetEvent) {
        let node = e.node().map(|n| n.raw());
        let at = e.at().unwrap_or_else(|| self.latest());
        let kind = match e {
            NetEvent::BootUp { .. } => "boot-up",
            NetEvent::State { .. } => "state",
            NetEvent::HeartbeatLost { .. } => "heartbeat-lost",
            NetEvent::HeartbeatResumed { .. } => "heartbeat-back",
            NetEvent::Emcy { .. } => "emcy",
            NetEvent::Pdo { .. } => "pdo",
            NetEvent::Port { .. } | NetEvent::PortState { .. } => "port",
            NetEvent::Reach { .. } => "reach",
            NetEvent::Lagged(_) => "lagged",
            _ => "other",
        };
        let mut known = false;
        if let (Some(id), Some(state)) = (node, e.state()) {
            // A state the node's heartbeat already told is logged (see `on_frame`).
            known = !self.set_state(id, state) && matches!(e, NetEvent::State { .. });
        }
        if let Some((id, msg)) = e.emcy() {
            if let Some(n) = self.node(id.raw()) {
                n.emcy = Some((msg.code, msg.text(), at));
            }
        }
        match e {
            NetEvent::PortState { port, to, .. } => {
                if let Some(p) = self.ports.get_mut(usize::from(*port)) {
                    p.state = to.as_str().into();
                }
            }
            NetEvent::Reach { node, heard, .. } => self.set_heard_on(node.raw(), *heard),
            _ => {}
        }
        if !known {
            self.push(at, node, kind, e.to_string());
        }
        if e.state().is_some() {
            self.check_pairs(at);
        }
    }

    /// Where node `id` was heard, from a network on more than one port: `bus 1+2`, `bus 2`,
    /// `none`.
    pub fn set_heard_on(&mut self, id: u8, heard: HeardOn) {
        if let Some(n) = self.node(id) {
            let buses: Vec<String> = heard.iter().map(|b| (b + 1).to_string()).collect();
            n.heard_on = Some(if buses.is_empty() {
                "none".into()
            } else {
                format!("bus {}", buses.join("+"))
            });
        }
    }

    /// Node `id` is in `state` (from its heartbeat or an event); true if that is a change.
    fn set_state(&mut self, id: u8, state: NmtState) -> bool {
        match self.node(id) {
            Some(n) if n.state != Some(state) => {
                n.state = Some(state);
                true
            }
            _ => false,
        }
    }

    /// One frame the tap saw on port `port` (`None`: above the dual-bus layer), received
    /// (`rx`) or sent.
    pub fn on_frame(&mut self, at: Instant, port: Option<usize>, rx: bool, f: &Frame) {
        let Id::Standard(cob) = f.id() else {
            return;
        };
        if !rx || f.is_remote() {
            return;
        }
        match (cob, f.data()) {
            (0x701..=0x77F, [byte]) => {
                let id = (cob - 0x700) as u8;
                // Each port's heartbeats apart: on two ports each one arrives twice, and a
                // copy is not a period.
                let p = port.unwrap_or(0).min(MAX_PORTS - 1);
                let mut back = false;
                if let Some(n) = self.node(id) {
                    // A heartbeat that changes the state may have been sent at once on the
                    // change: no period ends or starts at it.
                    let code = byte & 0x7F;
                    let changed = n.last_code[p].is_some_and(|c| c != code);
                    let steady = !changed && !n.changed[p];
                    // A boot-up starts the count again: the first heartbeat follows it at no
                    // particular time.
                    match (n.last_hb[p], *byte) {
                        (_, 0) => n.period = [None; MAX_PORTS],
                        (Some(last), _) if steady && n.state != Some(NmtState::Initialising) => {
                            n.period[p] = Some(at.saturating_since(last).as_micros());
                        }
                        _ => {}
                    }
                    n.last_hb[p] = Some(at);
                    n.last_code[p] = Some(code);
                    n.changed[p] = changed;
                    back = std::mem::take(&mut n.silent);
                }
                // The toggle bit (guarding) is not part of the state.
                if let Some(state) = NmtState::from_code(byte & 0x7F) {
                    if self.set_state(id, state) {
                        // Logged here, as the network's state event would log it: that event
                        // may have come before the monitor listened (a node heard at once).
                        // A boot-up has its own event.
                        if state != NmtState::Initialising {
                            self.push(at, Some(id), "state", format!("node {id:#04x}: {state}"));
                        }
                        self.check_pairs(at);
                    }
                }
                if back {
                    self.check_pairs(at);
                    self.observe(
                        at,
                        Some(id),
                        format!("monitor: node {id:#04x} heartbeat heard again"),
                    );
                }
            }
            (ACTIVE_MASTER_RESPONSE, [priority, node]) if (1..=127).contains(node) => {
                let was = self.master.map(|m| m.node);
                self.master = Some(Master {
                    node: *node,
                    priority: *priority,
                    at,
                });
                if was != Some(*node) {
                    let text = match was {
                        Some(w) => format!(
                            "monitor: active master now {node:#04x} (was {w:#04x}), priority {priority}"
                        ),
                        None => format!("monitor: active master {node:#04x}, priority {priority}"),
                    };
                    self.observe(at, Some(*node), text);
                }
            }
            _ => {}
        }
    }

    /// Time passes: heartbeats silent for three of their periods (100 ms at least) are logged once.
    pub fn tick(&mut self, now: Instant) {
        let mut silent = Vec::new();
        for (id, n) in &mut self.nodes {
            let (Some(last), Some(&period)) = (n.last_heartbeat(), n.period.iter().flatten().min())
            else {
                continue;
            };
            let age = now.saturating_since(last).as_micros();
            if !n.silent && age > period.saturating_mul(SILENT_PERIODS).max(SILENT_MIN) {
                n.silent = true;
                silent.push((*id, age));
            }
        }
        if !silent.is_empty() {
            self.check_pairs(now);
        }
        for (id, age) in silent {
            self.observe(
                now,
                Some(id),
                format!(
                    "monitor: node {id:#04x} heartbeat silent for {}",
                    age_text(age)
                ),
            );
        }
    }

    /// Logs the monitor's own observation.
    fn observe(&mut self, at: Instant, node: Option<u8>, text: String) {
        self.push(at, node, "monitor", text);
    }

    fn push(&mut self, at: Instant, node: Option<u8>, kind: &'static str, text: String) {
        if self.log.len() == EVENTS_KEPT {
            self.log.pop_front();
            self.dropped += 1;
        }
        self.seq += 1;
        self.log.push_back(Logged {
            seq: self.seq,
            at,
            node,
            kind,
            text,
        });
    }

    fn latest(&self) -> Instant {
        self.log.back().map_or(Instant::ZERO, |l| l.at)
    }

    /// Empties the log (the `c` key).
    pub fn clear_log(&mut self) {
        self.log.clear();
    }

    /// The log lines numbered after `seq`, oldest first, and how many of them the ring has
    /// already dropped.
    pub fn log_since(&self, seq: u64) -> (Vec<Logged>, u64) {
        let first = self.log.front().map_or(self.seq + 1, |l| l.seq);
        let missed = first.saturating_sub(seq + 1);
        let lines = self.log.iter().filter(|l| l.seq > seq).cloned().collect();
        (lines, missed)
    }

    #[cfg(test)]
    /// The number of the last log line.
    pub fn seq(&self) -> u64 {
        self.seq
    }

    /// The roles of pair `i` from its members' states.
    fn roles(&self, (a, b): (u8, u8)) -> (Option<u8>, Option<u8>, bool) {
        // A silent node is no member to count on, whatever it said last.
        let state = |id| {
            self.nodes
                .get(&id)
                .filter(|n| !n.silent)
                .and_then(|n| n.state)
        };
        let op = |id| state(id) == Some(NmtState::Operational);
        let pre = |id| state(id) == Some(NmtState::PreOperational);
        match (op(a), op(b)) {
            (true, true) => (None, None, true),
            (true, false) => (Some(a), pre(b).then_some(b), false),
            (false, true) => (Some(b), pre(a).then_some(a), false),
            (false, false) => (None, None, false),
        }
    }

    /// After a state change: a pair whose active member changed is logged; a new active
    /// member after another one (with or without a moment of none or both between) is a
    /// failover.
    fn check_pairs(&mut self, at: Instant) {
        for i in 0..self.pairs.len() {
            let (a, b) = self.pairs[i];
            let (now, _, both) = self.roles((a, b));
            let (was, definite) = self.active[i];
            if now == was {
                continue;
            }
            self.active[i] = (now, now.or(definite));
            let text = match (now, definite) {
                (Some(n), Some(d)) if n != d => format!("failover: {n:#04x} active (was {d:#04x})"),
                (Some(n), _) => format!("{n:#04x} active"),
                (None, _) if both => "both members operational".to_string(),
                (None, _) => "no active member".to_string(),
            };
            self.observe(at, None, format!("monitor: pair {a:#04x}/{b:#04x}: {text}"));
        }
    }

    /// What to show at `now`, with only the nodes and log lines that contain `filter`
    /// (without regard to case; empty: everything).
    pub fn view(&self, now: Instant, filter: &str) -> View {
        let filter = filter.trim().to_lowercase();
        let matches = |s: &str| filter.is_empty() || s.to_lowercase().contains(&filter);
        let nodes = self
            .nodes
            .iter()
            .map(|(id, n)| self.node_row(*id, n, now))
            .filter(|r| {
                let emcy = if r.emcy == "-" { "" } else { "emcy " };
                matches(&format!(
                    "node {} {} {} {emcy}{} {}",
                    r.id, r.state, r.name, r.emcy, r.heard_on
                ))
            })
            .collect();
        let pairs = self
            .pairs
            .iter()
            .map(|&(a, b)| {
                let (active, standby, both) = self.roles((a, b));
                PairRow {
                    members: [a, b],
                    pair: format!("{a:#04x}/{b:#04x}"),
                    active: match (active, both) {
                        (_, true) => "both".into(),
                        (Some(x), _) => format!("{x:#04x}"),
                        (None, _)
                            if !self.nodes.contains_key(&a) && !self.nodes.contains_key(&b) =>
                        {
                            "not heard".into()
                        }
                        (None, _) => "none".into(),
                    },
                    standby: standby.map_or_else(|| "-".into(), |x| format!("{x:#04x}")),
                }
            })
            .collect();
        let master = match self.master {
            None => "-".into(),
            Some(m) => {
                let hb = self
                    .nodes
                    .get(&m.node)
                    .and_then(NodeInfo::last_heartbeat)
                    .map_or_else(
                        || "-".into(),
                        |t| age_text(now.saturating_since(t).as_micros()),
                    );
                format!("{:#04x} (priority {}), heartbeat {hb}", m.node, m.priority)
            }
        };
        View {
            nodes,
            known: self.nodes.len(),
            ports: self.ports.clone(),
            pairs,
            master,
            master_info: self.master,
            events: self
                .log
                .iter()
                .filter(|l| matches(&l.text))
                .map(|l| (l.at, l.text.clone()))
                .collect(),
            dropped: self.dropped,
        }
    }

    fn node_row(&self, id: u8, n: &NodeInfo, now: Instant) -> NodeRow {
        let dash = || "-".to_string();
        NodeRow {
            node: id,
            age_ms: n
                .last_heartbeat()
                .map(|t| now.saturating_since(t).as_millis()),
            id: format!("{id:#04x}"),
            state: n.state.map_or_else(dash, |s| s.to_string()),
            hb_age: n.last_heartbeat().map_or_else(dash, |t| {
                let age = age_text(now.saturating_since(t).as_micros());
                if n.silent {
                    format!("{age} silent")
                } else {
                    age
                }
            }),
            emcy: n
                .emcy
                .map_or_else(dash, |(code, text, _)| format!("{code:#06x} {text}")),
            name: self.names.get(&id).cloned().unwrap_or_else(dash),
            heard_on: n.heard_on.clone().unwrap_or_else(dash),
        }
    }
}

/// An age for a person: `80 ms` below ten seconds' worth of milliseconds, then `12.3 s`,
/// then `3 min`.
pub fn age_text(us: u64) -> String {
    let ms = us / 1_000;
    match ms {
        0..=9_999 => format!("{ms} ms"),
        10_000..=599_999 => format!("{}.{} s", ms / 1_000, ms % 1_000 / 100),
        _ => format!("{} min", ms / 60_000),
    }
}

/// A wall-clock time of day in UTC, `08:21:03.120`, from milliseconds since 1970.
pub fn clock_text(unix_ms: u64) -> String {
    let day_ms = unix_ms % 86_400_000;
    format!(
        "{:02}:{:02}:{:02}.{:03}",
        day_ms / 3_600_000,
        day_ms / 60_000 % 60,
        day_ms / 1_000 % 60,
        day_ms % 1_000
    )
}

#[cfg(test)]
#[path = "model_tests.rs"]
mod tests;
