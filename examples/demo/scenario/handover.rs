//! The maintainer's hand-over between a rack's two buses, from the run: one bus has been cut
//! for a while; the instant it is repaired the other one is cut (no overlap: exactly one bus
//! works at every instant), and later that one is repaired too.
//!
//! The rule it shows: traffic on a repaired bus is evidence that it works, so every station
//! sends and merges on it at once, whatever its port's re-initialisation back-off says. What
//! must hold, from the first cut until [`AFTER`] past the last repair: at each computer the
//! repaired bus is in use again (recovering) within one board heartbeat period of the repair
//! (every node beats on a failed port too, so a frame arrives within a period) and ok within
//! two (then one probation period, a guard period, of frames), the newly cut bus is failed
//! within the silence limit; no CAN frame is lost (a frame on the cut bus's wire at the
//! cut had its twin on the other bus unless that bus was just coming back: it is counted, not
//! excused); no application message is lost or handled twice; the computer active at the
//! first cut stays the one active master (no role change at either computer); no pair
//! switches over and no board is reset; SYNC goes on with a gap of at most two periods and a
//! millisecond (the longest the loss of one SYNC at the cut could make it).

use super::analysis::{Analysis, Failover, Line, Traffic};
use super::station::{MASTER_NAMES, STRONG, WEAK};
use super::{Act, Happened, BOARD_HB, SILENCE_LIMIT, SYNC};
use duocan::sim::{TraceRecord, TxOutcome};
use duocan::{Duration, Frame, Instant};
use duocan_redundancy::link::health::PortState;
use duocan_redundancy::supervisor::pairs::PairsEvent;
use duocan_redundancy::{NetworkEventKind as K, SupervisorEvent};
use std::collections::HashMap;

/// Consequences of the hand-over are looked for this long after the last repair.
pub const AFTER: Duration = Duration::from_millis(500);
/// A frame's copy on the other bus is its twin if it ends within this of it.
const TWIN: Duration = Duration::from_millis(5);

/// A hand-over as the run shows it.
#[derive(Clone, Debug)]
pub struct HandOver {
    /// The rack.
    pub rack: &'static str,
    /// The bus repaired at the swap (0 = bus 1); the other one was cut then.
    pub repaired: usize,
    /// When the repaired bus had been cut.
    pub first_cut: Instant,
    /// The swap: one bus repaired, the other cut.
    pub swap: Instant,
    /// When the bus cut at the swap was repaired.
    pub restored: Option<Instant>,
    /// Per computer: the repaired bus in use again (recovering: sending and merging).
    pub revived: [Option<Instant>; 2],
    /// Per computer: the repaired bus ok again (trusted after its probation, a guard period).
    pub trusted: [Option<Instant>; 2],
    /// Per computer: the bus cut at the swap failed.
    pub failed: [Option<Instant>; 2],
    /// CAN frames sent on the rack from the first cut on that reached no one on either bus:
    /// when the attempt ended, its sender, the frame.
    pub lost: Vec<(Instant, String, Frame)>,
    /// The computer active at the first cut.
    pub active: Option<usize>,
    /// Role changes of either computer over the window.
    pub master_changes: usize,
    /// Whether the computer active at the first cut is active at the window's end.
    pub still_active: bool,
    /// Pair switch-overs over the window.
    pub switch_overs: usize,
    /// Boards lost from the pair table (reset) over the window.
    pub resets: usize,
    /// The longest gap between SYNCs over the window.
    pub sync_gap: Duration,
    /// The application messages of the window.
    pub traffic: Traffic,
}

impl HandOver {
    /// The bound of the SYNC gap: two periods (one SYNC lost at the cut) and a millisecond.
    pub const SYNC_BOUND: Duration = Duration::from_micros(2 * SYNC.as_micros() + 1_000);

    /// Whether everything the module's doc lists held.
    pub fn held(&self) -> bool {
        let within = |t: &Option<Instant>, b: Duration| t.is_some_and(|t| t - self.swap <= b);
        self.revived.iter().all(|t| within(t, BOARD_HB))
            && self.trusted.iter().all(|t| within(t, BOARD_HB + BOARD_HB))
            && self.failed.iter().all(|t| within(t, SILENCE_LIMIT))
            && self.restored.is_some()
            && self.lost.is_empty()
            && self.active.is_some()
            && self.master_changes == 0
            && self.still_active
            && self.switch_overs == 0
            && self.resets == 0
            && self.sync_gap <= Self::SYNC_BOUND
            && self.traffic.lost_total() == 0
            && self.traffic.duplicates_total() == 0
            && self.traffic.wrong == 0
    }

    /// What the window shows, counted.
    pub fn counts(&self) -> String {
        let t = &self.traffic;
        format!(
            "{} CAN frame(s) lost, {} of {} commands executed once and answered, {} of {} state changes delivered once, {} duplicate(s); {} the only active master, {} pair switch-over(s), {} board reset(s), longest SYNC gap {:.1} ms",
            self.lost.len(),
            t.answered.min(t.executed_once),
            t.commands,
            t.delivered,
            t.reports,
            t.duplicates_total(),
            self.active.map_or("no computer", |w| MASTER_NAMES[w]),
            self.switch_overs,
            self.resets,
            self.sync_gap.as_micros() as f64 / 1000.0
        )
    }

    /// The verdict the demo prints.
    pub fn summary(&self) -> String {
        format!(
            "bus hand-over on the {} (bus {} cut at {}, repaired at {} as bus {} is cut, bus {} repaired at {}): {}",
            self.rack,
            self.repaired + 1,
            secs(self.first_cut),
            secs(self.swap),
            2 - self.repaired,
            2 - self.repaired,
            self.restored.map_or("never".into(), secs),
            self.counts()
        )
    }
}

fn secs(t: Instant) -> String {
    format!("{:.3} s", t.as_micros() as f64 / 1e6)
}

fn ms(d: Duration) -> String {
    format!("{:.1} ms", d.as_micros() as f64 / 1000.0)
}

impl Analysis<'_> {
    /// The hand-over `h` on `rack`: what it shows, the lines of the timeline and the reactions
    /// measured.
    pub(super) fn hand_over(
        &self,
        h: &Happened,
        rack: usize,
        repaired: usize,
    ) -> (HandOver, Vec<Line>, Vec<Failover>) {
        let st = self.station();
        let r = &st.racks[rack];
        let (swap, cut) = (h.at, 1 - repaired);
        let first_cut = st
            .happened
            .iter()
            .filter(|x| {
                x.at <= swap
                    && x.act
                        == Act::BusCut {
                            rack,
                            bus: repaired,
                        }
            })
            .map(|x| x.at)
            .next_back()
            .unwrap_or(swap);
        let restored = st
            .happened
            .iter()
            .find(|x| x.at > swap && x.act == Act::BusRestored { rack, bus: cut })
            .map(|x| x.at);
        let until = restored.unwrap_or(st.sim.now()) + AFTER;
        let (b1, b2) = (repaired + 1, cut + 1);
        let mut lines = vec![Line {
            at: swap,
            depth: 0,
            text: format!(
                "{}: a maintainer repairs bus {b1} and cuts bus {b2} in the same instant (no overlap)",
                r.name()
            ),
        }];
        let mut failovers = Vec::new();
        let mut revived = [None; 2];
        let mut trusted = [None; 2];
        let mut failed = [None; 2];
        for w in [STRONG, WEAK] {
            revived[w] = self.port_event(rack, w, repaired as u8, swap, PortState::Recovering);
            trusted[w] = self.port_event(rack, w, repaired as u8, swap, PortState::Ok);
            failed[w] = self.port_event(rack, w, cut as u8, swap, PortState::Failed);
            if let Some(t) = revived[w] {
                let f = Failover {
                    rack: r.name(),
                    what: format!("bus {b1} in use again at the {}", MASTER_NAMES[w]),
                    from: swap,
                    at: t,
                    bound: Some(BOARD_HB),
                };
                let ok = trusted[w].map_or("never".into(), |o| {
                    format!("{} after the repair", ms(o - swap))
                });
                lines.push(Line { at: t, depth: 1, text: format!("{}: bus {b1} in use again (sending and merging) {} after the repair, at its first frame, whatever its back-off (bound: a heartbeat period, {}); ok after its probation (a heartbeat period of frames): {ok}", MASTER_NAMES[w], ms(f.took()), ms(BOARD_HB)) });
                failovers.push(f);
            }
            if let Some(t) = failed[w] {
                let f = Failover {
                    rack: r.name(),
                    what: format!("bus {b2} failed at the {}", MASTER_NAMES[w]),
                    from: swap,
                    at: t,
                    bound: Some(SILENCE_LIMIT),
                };
                lines.push(Line {
                    at: t,
                    depth: 1,
                    text: format!(
                        "{} detects the cut of bus {b2} after {} (silence limit {})",
                        MASTER_NAMES[w],
                        ms(f.took()),
                        ms(SILENCE_LIMIT)
                    ),
                });
                failovers.push(f);
            }
        }
        let sync_gap = self.sync_gap(rack, first_cut, until);
        failovers.push(Failover {
            rack: r.name(),
            what: "SYNC gap over the hand-over".into(),
            from: swap,
            at: swap + sync_gap,
            bound: Some(HandOver::SYNC_BOUND),
        });
        let active = [STRONG, WEAK]
            .into_iter()
            .find(|w| self.active_at(rack, *w, first_cut));
        let master_changes = [STRONG, WEAK]
            .into_iter()
            .flat_map(|w| self.net_events(rack, w))
            .filter(|e| matches!(e.kind, K::MasterRole(_)) && first_cut <= e.at && e.at <= until)
            .count();
        let still_active = active.is_some_and(|w| self.active_at(rack, w, until));
        let table = active.map_or(Vec::new(), |w| {
            self.net_events(rack, w)
                .filter(|e| first_cut <= e.at && e.at <= until)
                .collect()
        });
        let switch_overs = table
            .iter()
            .filter(|e| matches!(e.kind, K::PairRole(_)))
            .count();
        let resets = table
            .iter()
            .filter(|e| {
                matches!(
                    e.kind,
                    K::Other(duocan::machine::StationEvent::Machine(
                        SupervisorEvent::Pairs(PairsEvent::Lost { .. })
                    ))
                )
            })
            .count();
        let lost = self.lost_frames(rack, first_cut, until);
        let traffic = self.traffic_between(rack, first_cut, until);
        let ho = HandOver {
            rack: r.name(),
            repaired,
            first_cut,
            swap,
            restored,
            revived,
            trusted,
            failed,
            lost,
            active,
            master_changes,
            still_active,
            switch_overs,
            resets,
            sync_gap,
            traffic,
        };
        lines.push(Line {
            at: restored.unwrap_or(swap),
            depth: 1,
            text: format!(
                "over the hand-over, from the first cut to {} ms after the last repair: {}",
                AFTER.as_millis(),
                ho.counts()
            ),
        });
        (ho, lines, failovers)
    }

    /// The CAN frames sent on `rack` in `[from, to]` that reached no one: attempts that failed
    /// (bus down, no acknowledgement, sender cut off) whose sender got no copy of the same frame
    /// through on either bus within [`TWIN`].
    fn lost_frames(
        &self,
        rack: usize,
        from: Instant,
        to: Instant,
    ) -> Vec<(Instant, String, Frame)> {
        let st = self.station();
        let buses = st.racks[rack].buses();
        let attempts = st.sim.trace().iter().filter_map(|rec| match rec {
            TraceRecord::Tx(x)
                if buses.contains(&x.bus) && !x.babble && from <= x.end && x.end <= to + TWIN =>
            {
                Some(x)
            }
            _ => None,
        });
        let mut through: HashMap<_, Vec<Instant>> = HashMap::new();
        let mut failed = Vec::new();
        for x in attempts {
            match x.outcome {
                TxOutcome::Delivered { .. } => through
                    .entry((x.sender.device, x.frame))
                    .or_default()
                    .push(x.end),
                // Retransmitted by the sender: not an end.
                TxOutcome::ErrorFrame | TxOutcome::Aborted => {}
                _ if x.end <= to => failed.push(x),
                _ => {}
            }
        }
        failed
            .into_iter()
            .filter(|x| {
                !through.get(&(x.sender.device, x.frame)).is_some_and(|v| {
                    v.iter()
                        .any(|e| e.saturating_since(x.end).max(x.end.saturating_since(*e)) <= TWIN)
                })
            })
            .map(|x| (x.end, x.sender_name.to_string(), x.frame))
            .collect()
    }
}
