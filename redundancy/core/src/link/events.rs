//! What the dual-bus layer reports: every port-state change, channel switch, toggle,
//! reachability change, A/B discrepancy and lagging bus, with its reason and the instant it
//! happened.
//!
//! Ports are numbered 0 and 1 in the API and printed as "bus 1" and "bus 2".

use crate::link::health::PortState;
use crate::pair::{Member, PairId};
use core::fmt;
use duocan_core::{Duration, Frame, Id, Instant, NodeId};

/// One thing that happened in the layer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LinkEvent {
    /// When (for timer-driven changes: exactly the deadline).
    pub at: Instant,
    /// What.
    pub kind: LinkEventKind,
}

/// The kinds of [`LinkEvent`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum LinkEventKind {
    /// A port changed health state.
    Port {
        /// Port index (0 = bus 1).
        port: u8,
        /// Previous state.
        from: PortState,
        /// New state.
        to: PortState,
        /// Why.
        reason: PortReason,
    },
    /// The set of buses a node is heard on changed (`heard[p]`: heard on port `p` within the
    /// reachability timeout). The first report of a node comes one skew window after it was
    /// first heard, so that its twin has had time to arrive.
    Reach {
        /// The node.
        node: NodeId,
        /// Heard on port 0, on port 1.
        heard: [bool; 2],
    },
    /// The active channel changed (CiA 302-6 and ECSS modes).
    Channel {
        /// Previous active port.
        from: u8,
        /// New active port.
        to: u8,
        /// Why.
        reason: SwitchReason,
    },
    /// ECSS: the redundancy master's heartbeat was lost on the active bus. The node on top must
    /// enter pre-operational (`Node::set_nmt_state`); toggling starts.
    MasterLost {
        /// The redundancy master.
        master: NodeId,
        /// The bus it was lost on.
        bus: u8,
    },
    /// ECSS: the bus was toggled while searching for the master.
    Toggle {
        /// Previous bus.
        from: u8,
        /// New bus.
        to: u8,
        /// Toggle counter (0x2000 sub 4) after this toggle.
        ctoggle: u8,
    },
    /// ECSS: Ntoggle toggles without finding the master; the layer stays on `bus`, which
    /// becomes the default bus (0x2000 sub 1). Reported with the last toggle, once per loss.
    NoMaster {
        /// The bus it stays on.
        bus: u8,
        /// Toggle counter.
        ctoggle: u8,
    },
    /// ECSS: the master's heartbeat is back on `bus`, which becomes the default bus
    /// (0x2000 sub 1).
    MasterFound {
        /// The redundancy master.
        master: NodeId,
        /// The bus, now the default.
        bus: u8,
    },
    /// CiA 302-6: the channel error counter (0x1F60 sub 5) reached its threshold; the default
    /// channel is disabled until transmissions on it succeed again.
    DefaultDisabled {
        /// The counter.
        counter: u8,
    },
    /// The A and B members of a pair have carried different values for one function for longer
    /// than the discrepancy time. The event's time is the instant the discrepancy time ran out:
    /// the values started to differ that long before. (Not repeated here: every event of the
    /// layer's queue, in every device, would be 8 bytes larger.)
    Discrepancy {
        /// The pair.
        pair: PairId,
        /// The function key (e.g. the TPDO number).
        function: u32,
        /// The latest frame of member A.
        a: Frame,
        /// The latest frame of member B.
        b: Frame,
    },
    /// A reported discrepancy ended: the two members agree again.
    DiscrepancyCleared {
        /// The pair.
        pair: PairId,
        /// The function key.
        function: u32,
    },
    /// A pair member's value could not be kept for comparison because the function table is
    /// full (delivery is unaffected); reported once per pair.
    PairTableFull {
        /// The pair.
        pair: PairId,
        /// The member whose frame arrived.
        member: Member,
    },
    /// The heartbeats of a watched node became implausible (see
    /// [`crate::link::plausible`]): reported at the onset of each reason.
    Suspect {
        /// The node.
        node: NodeId,
        /// Why.
        why: Suspicion,
    },
    /// Every reason to suspect the node's heartbeats has ended.
    Trusted {
        /// The node.
        node: NodeId,
    },
    /// A babbling identifier: the heartbeat identifier `id` of `node` arrived on `port` at
    /// `rate` frames/s, measured over one producer period after the verdict at `since`; the
    /// producer time allows `allowed` per second. Its frames on that bus are dropped until the
    /// rate falls back.
    Babbling {
        /// The node whose heartbeat identifier it is.
        node: NodeId,
        /// The identifier.
        id: Id,
        /// Port index (0 = bus 1).
        port: u8,
        /// Frames per second measured.
        rate: u32,
        /// Heartbeats per second the node's producer time gives.
        allowed: u32,
        /// When its heartbeats there were found far too fast.
        since: Instant,
    },
    /// Two or more devices share `node`'s node-ID: its heartbeats arrived on `port` at `rate`
    /// per second (measured over one producer period after the verdict at `since`), a small
    /// multiple of the `allowed` rate. A period that held one heartbeat is no measure: while
    /// the verdict holds the next period is measured instead (`since` is then that period's
    /// start), and a verdict that ends first was a burst (a sender or a reader that stalled
    /// and caught up), reported by the suspicion alone, as for [`LinkEventKind::Babbling`].
    DuplicateNode {
        /// The node-ID.
        node: NodeId,
        /// Port index (0 = bus 1).
        port: u8,
        /// Heartbeats per second measured.
        rate: u32,
        /// Heartbeats per second the node's producer time gives.
        allowed: u32,
        /// When its heartbeats there were found too fast.
        since: Instant,
    },
    /// The frames of `port` arrive `lag` after their twins on the other port (measured from
    /// matched twins, see [`crate::link::lag`]): reported when the port starts lagging and
    /// whenever the window its lag needs changes. `window` is that window: the skew window plus
    /// the lag in whole milliseconds. Beyond the maximum window the port is distrusted (a port
    /// event says so); its window then only serves to recognise its twins.
    Lag {
        /// Port index (0 = bus 1).
        port: u8,
        /// The measured lag.
        lag: Duration,
        /// The window the lag needs.
        window: Duration,
    },
    /// The port no longer lags (under half the skew window): its window is the skew window
    /// again.
    LagCleared {
        /// Port index (0 = bus 1).
        port: u8,
    },
}

/// Why a watched node's heartbeats are implausible.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Suspicion {
    /// Heard far faster than its producer time on `port` (a babbling identifier, or devices
    /// sharing its node-ID).
    TooFast {
        /// Port index (0 = bus 1).
        port: u8,
    },
    /// Heard on port `heard` only, while the other bus, healthy, heard it before.
    OneBus {
        /// The port it is still heard on.
        heard: u8,
    },
}

pub use duocan_core::machine::PortReason;

/// Why the active channel changed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SwitchReason {
    /// 302-6 power-on evaluation: `node` gave `count` (< 3) heartbeats on the default channel.
    PowerOnEvaluation {
        /// The producer with the fewest heartbeats.
        node: NodeId,
        /// Its heartbeats in the window.
        count: u8,
    },
    /// 302-6 evaluation after reset communication: `node` gave no heartbeat on default.
    ResetEvaluation {
        /// The silent producer.
        node: NodeId,
    },
    /// 302-6: every producer gave 3 or more heartbeats on the default channel again.
    HeartbeatsBack,
    /// 302-6: the channel error counter reached its threshold.
    TxErrors {
        /// The counter.
        counter: u8,
    },
    /// 302-6: "indicate active interface" (0x7F) heard on the new channel.
    Indicated,
    /// Reset communication returned to the default channel.
    ResetCommunication,
    /// The application asked.
    Command,
}

fn bus(p: u8) -> u8 {
    p + 1
}

impl fmt::Display for SwitchReason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SwitchReason::PowerOnEvaluation { node, count } => write!(
                f,
                "power-on evaluation: {node} gave {count} heartbeat(s) on the default channel"
            ),
            SwitchReason::ResetEvaluation { node } => write!(
                f,
                "evaluation after reset communication: no heartbeat of {node} on the default channel"
            ),
            SwitchReason::HeartbeatsBack => {
                f.write_str("every producer's heartbeat is back on the default channel")
            }
            SwitchReason::TxErrors { counter } => {
                write!(f, "channel error counter reached {counter}")
            }
            SwitchReason::Indicated => f.write_str("indicate-active-interface (0x7F) received"),
            SwitchReason::ResetCommunication => f.write_str("reset communication"),
            SwitchReason::Command => f.write_str("commanded"),
        }
    }
}

/// One line, e.g. `1.250000s: node 0x12 heard on bus 2 only`.
impl fmt::Display for LinkEvent {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.at, self.kind)
    }
}

/// One line without the time, e.g. `node 0x12 heard on bus 2 only`.
impl fmt::Display for LinkEventKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            LinkEventKind::Port {
                port,
                from,
                to,
                reason,
            } => write!(f, "bus {} port {from} -> {to}: {reason}", bus(port)),
            LinkEventKind::Reach { node, heard } => match heard {
                [true, true] => write!(f, "{node} heard on both buses"),
                [true, false] => write!(f, "{node} heard on bus 1 only"),
                [false, true] => write!(f, "{node} heard on bus 2 only"),
                [false, false] => write!(f, "{node} heard on no bus"),
            },
            LinkEventKind::Channel { from, to, reason } => write!(
                f,
                "active channel bus {} -> bus {}: {reason}",
                bus(from),
                bus(to)
            ),
            LinkEventKind::MasterLost { master, bus: b } => write!(
                f,
                "heartbeat of redundancy master {master} lost on bus {}: enter pre-operational",
                bus(b)
            ),
            LinkEventKind::Toggle { from, to, ctoggle } => write!(
                f,
                "toggled bus {} -> bus {} (Ctoggle {ctoggle})",
                bus(from),
                bus(to)
            ),
            LinkEventKind::NoMaster { bus: b, ctoggle } => write!(
                f,
                "no master found after {ctoggle} toggle(s): staying on bus {}",
                bus(b)
            ),
            LinkEventKind::MasterFound { master, bus: b } => write!(
                f,
                "redundancy master {master} heard on bus {}: now the default bus",
                bus(b)
            ),
            LinkEventKind::DefaultDisabled { counter } => write!(
                f,
                "default channel disabled: channel error counter {counter}"
            ),
            LinkEventKind::Discrepancy {
                pair,
                function,
                a,
                b,
            } => write!(
                f,
                "pair {} function {function}: A sends {a}, B sends {b}",
                pair.0
            ),
            LinkEventKind::DiscrepancyCleared { pair, function } => {
                write!(
                    f,
                    "pair {} function {function}: A and B agree again",
                    pair.0
                )
            }
            LinkEventKind::PairTableFull { pair, member } => write!(
                f,
                "pair {} member {member}: function table full, values not compared",
                pair.0
            ),
            LinkEventKind::Suspect { node, why } => match why {
                Suspicion::TooFast { port } => write!(
                    f,
                    "{node} suspect: its heartbeat comes far faster than its period on bus {}",
                    bus(port)
                ),
                Suspicion::OneBus { heard } => write!(
                    f,
                    "{node} suspect: heard on bus {} only while bus {} is healthy",
                    bus(heard),
                    bus(1 - heard.min(1))
                ),
            },
            LinkEventKind::Trusted { node } => {
                write!(f, "{node} trusted again: its heartbeats are plausible")
            }
            LinkEventKind::Babbling {
                node,
                id,
                port,
                rate,
                allowed,
                since,
            } => write!(
                f,
                "identifier {id} ({node}'s heartbeat) babbling on bus {}: {rate} frames/s, its period allows {allowed}/s (since {since})",
                bus(port)
            ),
            LinkEventKind::DuplicateNode {
                node,
                port,
                rate,
                allowed,
                since,
            } => write!(
                f,
                "{node} on bus {}: {rate} heartbeats/s where its period gives {allowed}/s: devices share its node-ID (since {since})",
                bus(port)
            ),
            LinkEventKind::Lag { port, lag, window } => write!(
                f,
                "bus {} lags {lag} behind bus {}: merge window {window}",
                bus(port),
                bus(1 - port.min(1))
            ),
            LinkEventKind::LagCleared { port } => {
                write!(f, "bus {} no longer lags", bus(port))
            }
        }
    }
}
