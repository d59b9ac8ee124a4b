//! The board replacement scene, from the run: a spare board arrives without node-ID, the active
//! master finds it by LSS (identify non-configured remote slave, then fastscan), gives it the
//! node-ID of the vacant pair slot whose identity it has, and the board boots, has its identity
//! checked, is configured and joins as standby.
//!
//! Every instant comes from the master's events (LSS, pair supervision, audit trail) and from
//! the wire (the board's boot-up, the master's reads of its identity object); the fastscan's
//! cost is set against what the protocol predicts for the board's identity ([`fastscan_cost`]).

use super::analysis::{Analysis, Failover, Line, Wire};
use super::station::{board_node, MASTER_NAMES};
use super::Happened;
use duocan::cia305::codec::{MASTER_TO_SLAVE, SLAVE_TO_MASTER};
use duocan::cia305::{
    fastscan_cost, FastscanCost, LssMasterConfig, LssMasterEventKind, LssOutcome, LssService,
};
use duocan::machine::StationEvent;
use duocan::od::comm;
use duocan::{Duration, Instant, NmtState, NodeId};
use duocan_redundancy::supervisor::audit::{AuditEntry, BoardAddressed};
use duocan_redundancy::supervisor::pairs::PairsEvent;
use duocan_redundancy::{Member, NetworkEventKind as K, SupervisorEvent};

/// A board replaced by a spare without node-ID, as the run shows it.
#[derive(Clone, Debug)]
pub struct Replacement {
    /// The rack.
    pub rack: &'static str,
    /// The pair.
    pub pair: usize,
    /// The pair's field device ("P2").
    pub label: String,
    /// The slot the spare went into.
    pub member: Member,
    /// The spare plugged in and powered on.
    pub plugged: Instant,
    /// The computer that addressed it (the active one).
    pub master: usize,
    /// Its look for a board without node-ID answered: the fastscan starts.
    pub heard: Option<Instant>,
    /// The spare given its slot's node-ID (the master's event and audit record).
    pub addressed: Option<BoardAddressed>,
    /// That audit record, as the trail prints it.
    pub audit: Option<String>,
    /// The fastscan's end (its last reset unanswered).
    pub scan_end: Option<Instant>,
    /// LSS frames on each bus from the spare's power-on to the scan's end.
    pub lss_frames: usize,
    /// What the protocol predicts the fastscan costs for the spare's identity.
    pub predicted: FastscanCost,
    /// The board's boot-up on the wire, with its new node-ID.
    pub booted: Option<Instant>,
    /// The master's first read of the board's identity object (0x1018) after the boot-up.
    pub identity_read: Option<Instant>,
    /// It joined its pair.
    pub joined: Option<Instant>,
    /// The pair's active member in that master's table at the end of the day.
    pub active: Option<Member>,
    /// The board's node-ID and NMT state at the end of the day.
    pub end: (Option<NodeId>, NmtState),
}

impl Replacement {
    /// The node-ID of the slot.
    pub fn node(&self) -> NodeId {
        board_node(self.pair, self.member)
    }
    /// Whether the scene went as it must: the spare heard and given its slot's node-ID (event
    /// and audit record), then booted with it, its identity read, joined; the fastscan took
    /// at least the protocol's waiting time, and the LSS frames on the wire were the look that
    /// found the spare (request and answer) and exactly the fastscan's the protocol predicts;
    /// at the end the board has that node-ID and is the pair's standby (pre-operational) while
    /// its partner stays active.
    pub fn held(&self) -> bool {
        let addressed = self.addressed.is_some_and(|b| {
            (b.node, b.member, b.pair.0 as usize) == (self.node(), self.member, self.pair)
        });
        let order = match (
            self.heard,
            self.addressed,
            self.booted,
            self.identity_read,
            self.joined,
            self.scan_end,
        ) {
            (Some(h), Some(a), Some(b), Some(i), Some(j), Some(e)) => {
                self.plugged <= h
                    && h <= a.at
                    && a.at <= b
                    && b <= i
                    && i <= j
                    && a.at <= e
                    && e - h >= self.predicted.waiting
            }
            _ => false,
        };
        let p = self.predicted;
        addressed
            && self.audit.is_some()
            && order
            && self.lss_frames == (p.requests + p.answers + 2) as usize
            && self.end == (Some(self.node()), NmtState::PreOperational)
            && self.active == Some(self.member.other())
    }
}

fn ms(d: Duration) -> String {
    format!("{:.1} ms", d.as_micros() as f64 / 1000.0)
}

fn secs(t: Instant) -> String {
    format!("{:.4} s", t.as_micros() as f64 / 1e6)
}

impl Analysis<'_> {
    /// The replacement `h` of a board of `pair` on `rack`: what it shows, the lines of the
    /// timeline and the reactions measured.
    pub(super) fn replacement(
        &self,
        h: &Happened,
        rack: usize,
        pair: usize,
    ) -> Option<(Replacement, Vec<Line>, Vec<Failover>)> {
        let st = self.station();
        let r = &st.racks[rack];
        let m = h.member?;
        let node = board_node(pair, m);
        let label = r.kind().label(pair);
        let plugged = h.at;
        let (address, _) = r.board_lss(&st.sim, pair, m);
        let mut lines = vec![Line {
            at: plugged,
            depth: 0,
            text: format!(
                "{}: {label}'s board {m} replaced by a spare (serial {:#010x}) that has no node-ID, powered on",
                r.name(),
                address.serial
            ),
        }];
        let mut failovers = Vec::new();
        let w = self.in_charge(rack, plugged)?;
        let events = || self.net_events(rack, w).filter(move |e| e.at >= plugged);
        let heard = events().find_map(|e| match &e.kind {
            K::Other(StationEvent::Machine(SupervisorEvent::Lss(l)))
                if l.kind
                    == LssMasterEventKind::Done(LssOutcome::Identified(
                        LssService::IdentifyNonConfigured,
                        true,
                    )) =>
            {
                Some(l.at)
            }
            _ => None,
        });
        let addressed = events().find_map(|e| match &e.kind {
            K::Other(StationEvent::Machine(SupervisorEvent::Addressed(b))) if b.node == node => {
                Some(*b)
            }
            _ => None,
        });
        let scan_end = events().find_map(|e| match &e.kind {
            K::Other(StationEvent::Machine(SupervisorEvent::Lss(l)))
                if matches!(l.kind, LssMasterEventKind::ScanFinished { .. }) =>
            {
                Some(l.at)
            }
            _ => None,
        });
        let joined = events().find_map(|e| match &e.kind {
            K::Other(StationEvent::Machine(SupervisorEvent::Pairs(PairsEvent::Joined {
                node: n,
                ..
            }))) if *n == node => Some(e.at),
            _ => None,
        });
        let audit = r
            .audit(&st.sim, w)
            .into_iter()
            .find_map(|rec| match rec.entry {
                AuditEntry::Addressed(b) if Some(b) == addressed => Some(rec.to_string()),
                _ => None,
            });
        let lss = |x: &Wire| x.frame.id() == MASTER_TO_SLAVE || x.frame.id() == SLAVE_TO_MASTER;
        let lss_frames = self
            .frames(rack, plugged, scan_end.unwrap_or(plugged), lss)
            .count()
            / 2;
        let predicted = fastscan_cost(&mut [address], &LssMasterConfig::default(), false);
        let since = addressed.map_or(plugged, |b| b.at);
        let hb = r.heartbeat_id(node);
        let booted = self
            .frames(rack, since, st.sim.now(), |x| {
                x.frame.id() == hb && x.frame.data() == [0]
            })
            .next()
            .map(|x| x.end);
        let read = r.sdo_request_id(node);
        let identity_read = self
            .frames(rack, booted.unwrap_or(since), st.sim.now(), |x| {
                let d = x.frame.data();
                x.frame.id() == read
                    && d.len() == 8
                    && d[0] == 0x40
                    && d[1..3] == comm::IDENTITY.to_le_bytes()
            })
            .next()
            .map(|x| x.end);

        if let Some(t) = heard {
            // The look that found it: its request and the spare's answer on the wire.
            let on = |id| {
                self.frames(rack, plugged, t, move |x| x.frame.id() == id)
                    .next()
                    .map(|x| x.end)
            };
            let wire = match (on(MASTER_TO_SLAVE), on(SLAVE_TO_MASTER)) {
                (Some(q), Some(a)) => format!(
                    " (request at {}, the spare's answer at {})",
                    secs(q),
                    secs(a)
                ),
                _ => String::new(),
            };
            lines.push(Line {
                at: t,
                depth: 1,
                text: format!(
                    "{}: its look for a board without node-ID (LSS identify non-configured remote slave) answered{wire}; fastscan starts",
                    MASTER_NAMES[w],
                ),
            });
        }
        if let Some(b) = addressed {
            let scan = heard.map_or(String::new(), |t| {
                format!(" ({} after the fastscan started)", ms(b.at - t))
            });
            lines.push(Line {
                at: b.at,
                depth: 1,
                text: format!(
                    "fastscan found {} and gave it {label}'s slot {m}: {}{scan}",
                    b.address, b.node
                ),
            });
            if let Some(a) = &audit {
                lines.push(Line {
                    at: b.at,
                    depth: 1,
                    text: format!("{}'s audit trail: {a}", MASTER_NAMES[w]),
                });
            }
            failovers.push(Failover {
                rack: r.name(),
                what: format!("{label}: spare given {} by LSS", b.node),
                from: plugged,
                at: b.at,
                bound: None,
            });
        }
        if let Some(t) = booted {
            let after = addressed.map_or(String::new(), |b| {
                format!(" {} after it took the node-ID", ms(t - b.at))
            });
            lines.push(Line {
                at: t,
                depth: 1,
                text: format!("{m} ({node}) sends its boot-up{after}"),
            });
        }
        if let (Some(t), Some(h)) = (scan_end, heard) {
            lines.push(Line {
                at: t,
                depth: 1,
                text: format!(
                    "fastscan over (its last reset unanswered) {} after it started: the protocol's {} of timeouts and settle times for this identity, plus {} frames on the wire ({} requests, {} answers); {lss_frames} LSS frames on each bus since the power-on",
                    ms(t - h),
                    ms(predicted.waiting),
                    predicted.requests + predicted.answers,
                    predicted.requests,
                    predicted.answers
                ),
            });
        }
        let active = r.active_member(&st.sim, w, pair);
        if let Some(t) = joined {
            let checked = identity_read.map_or(String::new(), |i| {
                format!("identity (0x1018) checked from {}, ", secs(i))
            });
            let role = if active == Some(m.other()) {
                format!("{label} stays on {} (non-revertive)", m.other())
            } else {
                format!("{label} active member: {active:?}")
            };
            lines.push(Line {
                at: t,
                depth: 1,
                text: format!(
                    "{m}: {checked}configured, joined as standby {} after the power-on; {role}",
                    ms(t - plugged)
                ),
            });
            failovers.push(Failover {
                rack: r.name(),
                what: format!("{label}: board {m} joined"),
                from: plugged,
                at: t,
                bound: None,
            });
        }
        let rep = Replacement {
            rack: r.name(),
            pair,
            label: label.clone(),
            member: m,
            plugged,
            master: w,
            heard,
            addressed,
            audit,
            scan_end,
            lss_frames,
            predicted,
            booted,
            identity_read,
            joined,
            active,
            end: (
                r.board_lss(&st.sim, pair, m).1,
                r.board_state(&st.sim, pair, m),
            ),
        };
        Some((rep, lines, failovers))
    }
}
