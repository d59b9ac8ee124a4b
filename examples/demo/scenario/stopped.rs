//! An active board that stops running by itself, from the run: its application (or its CiA 301
//! error behaviour, 0x1029) puts it in pre-operational or stopped, and it goes on beating,
//! saying so. The rule it shows: such a heartbeat is a failure at that heartbeat, as silence
//! would be at the consumer time.
//!
//! What must hold: the computer in charge changes the pair's active member at exactly the end
//! of the first heartbeat that shows the new state (reason: active member not operational
//! without a command of this master), records it in its audit trail, and loses the board at
//! that instant; the standby's NMT start is on the wire within a millisecond of that heartbeat;
//! the stopped board is reset, boots again, is configured and rejoins as standby
//! (non-revertive: the pair stays on the board that took over), so at the end exactly one board
//! runs, the one the table names; no application message of the rack is lost or handled twice
//! from the stop until [`AFTER`] later.

use super::analysis::{Analysis, Failover, Line, Traffic};
use super::station::{board_node, MASTER_NAMES};
use super::Happened;
use duocan::machine::StationEvent;
use duocan::{Duration, Instant, NmtCommand, NmtState};
use duocan_redundancy::supervisor::audit::AuditEntry;
use duocan_redundancy::supervisor::pairs::{LossReason, PairsEvent, RoleChange, RoleReason};
use duocan_redundancy::{Member, NetworkEventKind as K, SupervisorEvent};

/// The rack's application messages are looked at this long after the stop.
pub const AFTER: Duration = Duration::from_millis(500);
/// The standby's NMT start is on the wire within this of the heartbeat that shows the stop.
pub const START_BOUND: Duration = Duration::from_millis(1);

/// A board that stopped by itself, as the run shows it.
#[derive(Clone, Debug)]
pub struct Stopped {
    /// The rack.
    pub rack: &'static str,
    /// The pair.
    pub pair: usize,
    /// The pair's field device ("T9").
    pub label: String,
    /// The board that stopped (the active member then).
    pub member: Member,
    /// The state its application put it in.
    pub state: NmtState,
    /// When its application stopped it.
    pub at: Instant,
    /// The computer in charge then.
    pub master: Option<usize>,
    /// The end of the first copy of its first heartbeat saying so.
    pub shown: Option<Instant>,
    /// The pair's role change at that computer.
    pub role: Option<RoleChange>,
    /// That role change as the audit trail prints it.
    pub audit: Option<String>,
    /// The board lost from the table: when, why.
    pub lost: Option<(Instant, LossReason)>,
    /// The partner's NMT start on the wire.
    pub started: Option<Instant>,
    /// The stopped board's NMT reset on the wire.
    pub reset: Option<Instant>,
    /// Its boot-up after the reset.
    pub booted: Option<Instant>,
    /// It rejoined the pair.
    pub rejoined: Option<Instant>,
    /// At the end of the day: the pair's running members, the active member in the computer's
    /// table, the stopped board's state.
    pub end: (Vec<Member>, Option<Member>, NmtState),
    /// The rack's application messages from the stop until [`AFTER`] later.
    pub traffic: Traffic,
}

impl Stopped {
    /// Whether everything the module's doc lists held.
    pub fn held(&self) -> bool {
        let other = self.member.other();
        let Some(v) = self.shown else { return false };
        let role = self.role.is_some_and(|r| {
            (r.pair.0 as usize, r.at, r.from, r.to, r.reason)
                == (
                    self.pair,
                    v,
                    Some(self.member),
                    Some(other),
                    RoleReason::ActiveNotOperational { state: self.state },
                )
        });
        let order = match (self.started, self.reset, self.booted, self.rejoined) {
            (Some(s), Some(r), Some(b), Some(j)) => v < s && s <= r && r < b && b <= j,
            _ => false,
        };
        role && self.audit.is_some()
            && self.at <= v
            && self.lost == Some((v, LossReason::NotOperational { state: self.state }))
            && self.started.is_some_and(|s| s - v <= START_BOUND)
            && order
            && self.end == (vec![other], Some(other), NmtState::PreOperational)
            && self.traffic.lost_total() == 0
            && self.traffic.duplicates_total() == 0
            && self.traffic.wrong == 0
    }

    /// The verdict the demo prints.
    pub fn summary(&self) -> String {
        let t = &self.traffic;
        format!(
            "board stopping by itself: {} {}'s board {} replaced by {} at the heartbeat that showed it ({}), reset and back as standby; {} of {} state changes delivered once in the {} ms after",
            self.rack,
            self.label,
            self.member,
            self.member.other(),
            self.master.map_or("no computer in charge", |w| MASTER_NAMES[w]),
            t.delivered,
            t.reports,
            AFTER.as_millis()
        )
    }
}

fn ms(d: Duration) -> String {
    format!("{:.1} ms", d.as_micros() as f64 / 1000.0)
}

impl Analysis<'_> {
    /// The stop `h` of `pair`'s active board on `rack`: what it shows, the lines of the
    /// timeline and the reactions measured.
    pub(super) fn stopped(
        &self,
        h: &Happened,
        rack: usize,
        pair: usize,
        state: NmtState,
    ) -> Option<(Stopped, Vec<Line>, Vec<Failover>)> {
        let st = self.station();
        let r = &st.racks[rack];
        let m = h.member?;
        let (node, other) = (board_node(pair, m), board_node(pair, m.other()));
        let label = r.kind().label(pair);
        let at = h.at;
        let mut lines = vec![Line {
            at,
            depth: 0,
            text: format!(
                "{}: {label}'s active board {m} ({node}) stops running by itself: its application puts it in {state}; it goes on beating",
                r.name()
            ),
        }];
        let mut failovers = Vec::new();
        let dev = r.board_dev(pair, m);
        let (hb, nmt) = (r.heartbeat_id(node), r.nmt_id());
        let shown = self.first_after(rack, at, |w| {
            w.sender == dev && w.frame.id() == hb && w.frame.data() == [state.code()]
        });
        let from = shown.unwrap_or(at);
        let command = |cs: NmtCommand, n: u8| {
            self.first_after(rack, from, |w| {
                w.frame.id() == nmt && w.frame.data() == [cs.code(), n]
            })
        };
        let started = command(NmtCommand::Start, other.raw());
        let reset = command(NmtCommand::ResetNode, node.raw());
        let booted = self.first_after(rack, reset.unwrap_or(from), |w| {
            w.sender == dev
                && w.frame.id() == hb
                && w.frame.data() == [NmtState::Initialising.code()]
        });
        let master = self.in_charge(rack, at);
        let events: Vec<_> = master.map_or(Vec::new(), |w| {
            self.net_events(rack, w).filter(|e| e.at >= at).collect()
        });
        let role = events.iter().find_map(|e| match &e.kind {
            K::PairRole(rc) if rc.pair.0 as usize == pair => Some(*rc),
            _ => None,
        });
        let pairs_event = |e: &&duocan_redundancy::NetworkEvent| match &e.kind {
            K::Other(StationEvent::Machine(SupervisorEvent::Pairs(p))) => Some(*p),
            _ => None,
        };
        let lost = events.iter().filter_map(pairs_event).find_map(|p| match p {
            PairsEvent::Lost {
                at,
                node: n,
                reason,
                ..
            } if n == node => Some((at, reason)),
            _ => None,
        });
        let rejoined = events.iter().filter_map(pairs_event).find_map(|p| match p {
            PairsEvent::Joined { at, node: n, .. } if n == node => Some(at),
            _ => None,
        });
        let audit = master.and_then(|w| {
            r.audit(&st.sim, w)
                .into_iter()
                .find_map(|rec| match rec.entry {
                    AuditEntry::Pair(rc) if Some(rc) == role => Some(rec.to_string()),
                    _ => None,
                })
        });
        if let (Some(v), Some(w)) = (shown, master) {
            let switch = match role {
                Some(rc) if rc.at == v => "at that heartbeat".to_string(),
                Some(rc) => format!("{} after that heartbeat", ms(rc.at.saturating_since(v))),
                None => "never".to_string(),
            };
            lines.push(Line {
                at: v,
                depth: 1,
                text: format!(
                    "{}: {m}'s heartbeat says {state} {} after the stop; {label} switches to {} {switch}",
                    MASTER_NAMES[w],
                    ms(v - at),
                    m.other()
                ),
            });
            if let Some(a) = &audit {
                lines.push(Line {
                    at: v,
                    depth: 1,
                    text: format!("{}'s audit trail: {a}", MASTER_NAMES[w]),
                });
            }
            if let Some(s) = started {
                let f = Failover {
                    rack: r.name(),
                    what: format!(
                        "{label}: board {} started after {m}'s heartbeat saying {state}",
                        m.other()
                    ),
                    from: v,
                    at: s,
                    bound: Some(START_BOUND),
                };
                lines.push(Line { at: s, depth: 1, text: format!("{label}: board {} ({other}) started {} after {m}'s heartbeat saying {state} (bound {}); {m} is reset", m.other(), ms(f.took()), ms(START_BOUND)) });
                failovers.push(f);
            }
        }
        if let (Some(b), Some(j), Some(w)) = (booted, rejoined, master) {
            lines.push(Line { at: j, depth: 1, text: format!("{m} ({node}) sends its boot-up {} after the reset command, is configured by the {} and rejoins as standby {} after its stop; {label} stays on {} (non-revertive)", ms(b - reset.unwrap_or(b)), MASTER_NAMES[w], ms(j - at), m.other()) });
            failovers.push(Failover {
                rack: r.name(),
                what: format!("{label}: board {m} back as standby after its stop"),
                from: at,
                at: j,
                bound: None,
            });
        }
        let end = (
            [Member::A, Member::B]
                .into_iter()
                .filter(|x| {
                    st.sim.is_powered(r.board_dev(pair, *x))
                        && r.board_state(&st.sim, pair, *x) == NmtState::Operational
                })
                .collect(),
            master.and_then(|w| r.active_member(&st.sim, w, pair)),
            r.board_state(&st.sim, pair, m),
        );
        let s = Stopped {
            rack: r.name(),
            pair,
            label,
            member: m,
            state,
            at,
            master,
            shown,
            role,
            audit,
            lost,
            started,
            reset,
            booted,
            rejoined,
            end,
            traffic: self.traffic_between(rack, at, at + AFTER),
        };
        Some((s, lines, failovers))
    }
}
