//! Same-function merge: the A and B boards of a pair carry the same function; the application
//! gets one logical stream, from the member that is currently active.
//!
//! The layer delivers the active member's frames of each function; the standby's frames are
//! kept as its latest values (available through [`SameFunction::latest`]) but not delivered. The
//! supervisor decides who is active ([`SameFunction::set_active`]); a pair without an active
//! member delivers neither (its data cannot be trusted). Frames that are not process-data
//! functions (heartbeats, SDO, EMCY) of both members are always delivered: the supervisor needs
//! them.
//!
//! Whenever the latest values of A and B for one function differ for longer than the
//! discrepancy time, a [`LinkEventKind::Discrepancy`] is raised (exactly at the instant they
//! started to differ + the time), and [`LinkEventKind::DiscrepancyCleared`] when they agree
//! again.

use crate::link::events::{LinkEvent, LinkEventKind};
use crate::link::outbox::Outbox;
use crate::pair::{Member, PairId, MAX_PAIRS};
use core::fmt;
use duocan_core::frame::instant::shift_back;
use duocan_core::{Duration, Frame, Instant, NodeId};
use heapless::index_map::FnvIndexMap;

/// (pair, function) values a layer keeps for comparison by default (a power of two). A board
/// that supervises no pairs can use a tiny table (a `DualBus<C, Capacity<SLOTS, 2>>`): each entry
/// costs ~100 B.
pub const MAX_FUNCTIONS: usize = 256;

/// Why a pair could not be configured.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PairError {
    /// [`MAX_PAIRS`] pairs are configured already.
    Full,
    /// The node already belongs to a pair.
    NodeTaken(NodeId),
    /// A and B are the same node.
    SameNode(NodeId),
}

impl fmt::Display for PairError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PairError::Full => write!(f, "at most {MAX_PAIRS} pairs can be configured"),
            PairError::NodeTaken(n) => write!(f, "{n} already belongs to a pair"),
            PairError::SameNode(n) => write!(f, "{n} cannot be both members of a pair"),
        }
    }
}

impl core::error::Error for PairError {}

#[derive(Clone, Copy, Debug)]
struct PairEntry {
    nodes: [NodeId; 2],
    active: Option<Member>,
    table_full_reported: bool,
}

#[derive(Clone, Copy, Debug)]
struct Values {
    latest: [Option<(Instant, Frame)>; 2],
    differ_since: Option<Instant>,
    reported: bool,
}

/// What to do with a process-data frame of a pair member.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PairVerdict {
    /// Not a pair member: not this module's business.
    NotPaired,
    /// From the active member: deliver.
    Active,
    /// From the standby (or no member is active): kept, not delivered.
    Standby,
}

/// The pair table and the latest values per (pair, function); room for `FUNCTIONS` of those.
#[derive(Debug)]
pub struct SameFunction<const FUNCTIONS: usize = MAX_FUNCTIONS> {
    pairs: heapless::Vec<PairEntry, MAX_PAIRS>,
    /// node-ID → pair index + 1 (0: none) in the low 7 bits, member B in bit 7.
    by_node: [u8; 128],
    values: FnvIndexMap<(u8, u32), Values, FUNCTIONS>,
    discrepancy_time: Duration,
    next_check: Option<Instant>,
    dropped_values: u32,
}

impl<const FUNCTIONS: usize> SameFunction<FUNCTIONS> {
    /// No pairs; values differing for `discrepancy_time` are reported (zero: never).
    #[must_use]
    pub fn new(discrepancy_time: Duration) -> Self {
        SameFunction {
            pairs: heapless::Vec::new(),
            by_node: [0; 128],
            values: FnvIndexMap::new(),
            discrepancy_time,
            next_check: None,
            dropped_values: 0,
        }
    }

    /// Configures a pair; `active` is who delivers until [`SameFunction::set_active`] says
    /// otherwise.
    pub fn add_pair(
        &mut self,
        a: NodeId,
        b: NodeId,
        active: Option<Member>,
    ) -> Result<PairId, PairError> {
        if a == b {
            return Err(PairError::SameNode(a));
        }
        for n in [a, b] {
            if self.by_node[n.raw() as usize] != 0 {
                return Err(PairError::NodeTaken(n));
            }
        }
        let id = self.pairs.len();
        self.pairs
            .push(PairEntry {
                nodes: [a, b],
                active,
                table_full_reported: false,
            })
            .map_err(|_| PairError::Full)?;
        self.by_node[a.raw() as usize] = id as u8 + 1;
        self.by_node[b.raw() as usize] = (id as u8 + 1) | 0x80;
        Ok(PairId(id as u8))
    }

    /// Number of pairs.
    pub fn len(&self) -> usize {
        self.pairs.len()
    }
    /// True when no pair is configured.
    pub fn is_empty(&self) -> bool {
        self.pairs.is_empty()
    }

    /// The pair and member `node` belongs to.
    pub fn member_of(&self, node: NodeId) -> Option<(PairId, Member)> {
        let v = self.by_node[node.raw() as usize];
        if v == 0 {
            return None;
        }
        let m = if v & 0x80 != 0 { Member::B } else { Member::A };
        Some((PairId((v & 0x7F) - 1), m))
    }

    /// The node of a member.
    pub fn node(&self, pair: PairId, member: Member) -> Option<NodeId> {
        self.pairs
            .get(pair.0 as usize)
            .map(|p| p.nodes[member.index()])
    }

    /// Who is active.
    pub fn active(&self, pair: PairId) -> Option<Member> {
        self.pairs.get(pair.0 as usize).and_then(|p| p.active)
    }

    /// Makes `member` the one whose frames are delivered (`None`: neither). Returns false for an
    /// unknown pair.
    pub fn set_active(&mut self, pair: PairId, member: Option<Member>) -> bool {
        match self.pairs.get_mut(pair.0 as usize) {
            Some(p) => {
                p.active = member;
                true
            }
            None => false,
        }
    }

    /// The latest frame (and its arrival) of one member for one function.
    pub fn latest(&self, pair: PairId, member: Member, function: u32) -> Option<(Instant, Frame)> {
        self.values
            .get(&(pair.0, function))
            .and_then(|v| v.latest[member.index()])
    }

    /// Forgets a member's values (after it was reset): nothing stale is compared.
    pub fn forget(&mut self, pair: PairId, member: Member) {
        for ((p, _), v) in self.values.iter_mut() {
            if *p == pair.0 {
                v.latest[member.index()] = None;
                v.differ_since = None;
                v.reported = false;
            }
        }
    }

    /// The caller's clock stepped back `by` (the clock contract, see [`crate::link`]): the
    /// members' latest values, the instants they started to differ and the next check move
    /// back with it.
    pub(crate) fn step_back(&mut self, by: Duration) {
        for v in self.values.values_mut() {
            for (t, _) in v.latest.iter_mut().flatten() {
                *t = *t - by;
            }
            shift_back(&mut v.differ_since, by);
        }
        shift_back(&mut self.next_check, by);
    }

    /// Values that could not be kept because the table was full.
    pub fn dropped_values(&self) -> u32 {
        self.dropped_values
    }

    /// A delivered frame carrying `function` of `node`; A and B values compared byte for byte.
    #[cfg(test)]
    pub(crate) fn on_frame(
        &mut self,
        now: Instant,
        node: NodeId,
        function: u32,
        frame: &Frame,
        out: &mut Outbox,
    ) -> PairVerdict {
        self.on_frame_by(now, node, function, frame, out, |a, b| a.data() == b.data())
    }

    /// A delivered frame carrying `function` of `node`; `same` tells whether A's and B's
    /// latest frames carry the same value.
    pub(crate) fn on_frame_by(
        &mut self,
        now: Instant,
        node: NodeId,
        function: u32,
        frame: &Frame,
        out: &mut Outbox,
        same: impl Fn(&Frame, &Frame) -> bool,
    ) -> PairVerdict {
        let Some((pair, member)) = self.member_of(node) else {
            return PairVerdict::NotPaired;
        };
        let Some(entry) = self.pairs.get_mut(pair.0 as usize) else {
            return PairVerdict::NotPaired;
        };
        let verdict = if entry.active == Some(member) {
            PairVerdict::Active
        } else {
            PairVerdict::Standby
        };
        let key = (pair.0, function);
        if !self.values.contains_key(&key) {
            let fresh = Values {
                latest: [None, None],
                differ_since: None,
                reported: false,
            };
            if self.values.insert(key, fresh).is_err() {
                self.dropped_values = self.dropped_values.saturating_add(1);
                if !entry.table_full_reported {
                    entry.table_full_reported = true;
                    out.event(LinkEvent {
                        at: now,
                        kind: LinkEventKind::PairTableFull { pair, member },
                    });
                }
                return verdict;
            }
        }
        let Some(v) = self.values.get_mut(&key) else {
            return verdict;
        };
        v.latest[member.index()] = Some((now, *frame));
        let differ = match v.latest {
            [Some((_, a)), Some((_, b))] => !same(&a, &b),
            _ => false,
        };
        match (differ, v.differ_since) {
            (true, None) => {
                v.differ_since = Some(now);
                if !self.discrepancy_time.is_zero() {
                    let due = now + self.discrepancy_time;
                    self.next_check = Some(self.next_check.map_or(due, |c| c.min(due)));
                }
            }
            (false, Some(_)) => {
                v.differ_since = None;
                if v.reported {
                    v.reported = false;
                    out.event(LinkEvent {
                        at: now,
                        kind: LinkEventKind::DiscrepancyCleared { pair, function },
                    });
                }
            }
            _ => {}
        }
        verdict
    }

    /// Earliest discrepancy deadline (may be early).
    #[must_use]
    pub fn poll_timeout(&self) -> Option<Instant> {
        self.next_check
    }

    /// Raises the discrepancies due at `now`, each at its own instant.
    pub(crate) fn handle_timeout(&mut self, now: Instant, out: &mut Outbox) {
        if self.next_check.is_none_or(|c| c > now) {
            return;
        }
        let mut next: Option<Instant> = None;
        for (&(p, function), v) in self.values.iter_mut() {
            let (Some(since), false) = (v.differ_since, v.reported) else {
                continue;
            };
            let due = since + self.discrepancy_time;
            if due <= now {
                v.reported = true;
                if let [Some((_, a)), Some((_, b))] = v.latest {
                    out.event(LinkEvent {
                        at: due,
                        kind: LinkEventKind::Discrepancy {
                            pair: PairId(p),
                            function,
                            a,
                            b,
                        },
                    });
                }
            } else {
                next = Some(next.map_or(due, |x| x.min(due)));
            }
        }
        self.next_check = next;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use duocan_core::Id;

    fn ms(x: u64) -> Instant {
        Instant::from_millis(x)
    }
    fn tpdo(node: u8, v: u8) -> Frame {
        Frame::from_array(Id::Standard(0x180 + node as u16), [v])
    }

    #[test]
    fn active_member_delivers_standby_is_kept_and_roles_switch() {
        let mut s: SameFunction = SameFunction::new(Duration::from_millis(50));
        let mut out = Outbox::new();
        let (a, b) = (NodeId::must(0x10), NodeId::must(0x11));
        let p = s.add_pair(a, b, Some(Member::A)).unwrap();
        assert_eq!(
            s.add_pair(a, NodeId::must(3), None),
            Err(PairError::NodeTaken(a))
        );
        assert_eq!(
            s.on_frame(ms(0), a, 1, &tpdo(0x10, 1), &mut out),
            PairVerdict::Active
        );
        assert_eq!(
            s.on_frame(ms(1), b, 1, &tpdo(0x11, 1), &mut out),
            PairVerdict::Standby
        );
        assert_eq!(s.latest(p, Member::B, 1), Some((ms(1), tpdo(0x11, 1))));
        assert_eq!(
            s.on_frame(ms(1), NodeId::must(5), 1, &tpdo(5, 1), &mut out),
            PairVerdict::NotPaired
        );
        assert!(s.set_active(p, Some(Member::B)));
        assert_eq!(
            s.on_frame(ms(2), b, 1, &tpdo(0x11, 1), &mut out),
            PairVerdict::Active
        );
        assert_eq!(
            s.on_frame(ms(2), a, 1, &tpdo(0x10, 1), &mut out),
            PairVerdict::Standby
        );
        s.set_active(p, None);
        assert_eq!(
            s.on_frame(ms(3), b, 1, &tpdo(0x11, 1), &mut out),
            PairVerdict::Standby
        );
    }

    #[test]
    fn discrepancy_is_raised_after_the_time_and_cleared() {
        let mut s: SameFunction = SameFunction::new(Duration::from_millis(50));
        let mut out = Outbox::new();
        let (a, b) = (NodeId::must(0x10), NodeId::must(0x11));
        let p = s.add_pair(a, b, Some(Member::A)).unwrap();
        s.on_frame(ms(0), a, 1, &tpdo(0x10, 1), &mut out);
        s.on_frame(ms(0), b, 1, &tpdo(0x11, 1), &mut out);
        // Differ from 10 ms, agree again at 40 ms: too short.
        s.on_frame(ms(10), a, 1, &tpdo(0x10, 2), &mut out);
        s.on_frame(ms(40), b, 1, &tpdo(0x11, 2), &mut out);
        assert_eq!(s.poll_timeout(), Some(ms(60)));
        s.handle_timeout(ms(60), &mut out);
        assert!(out.events.is_empty());
        assert_eq!(s.poll_timeout(), None);
        // Differ from 100 ms on: raised at 150 ms exactly, cleared when B follows.
        s.on_frame(ms(100), a, 1, &tpdo(0x10, 3), &mut out);
        s.handle_timeout(ms(149), &mut out);
        assert!(out.events.is_empty());
        s.handle_timeout(ms(170), &mut out);
        assert_eq!(
            out.events.pop(),
            Some(LinkEvent {
                at: ms(150),
                kind: LinkEventKind::Discrepancy {
                    pair: p,
                    function: 1,
                    a: tpdo(0x10, 3),
                    b: tpdo(0x11, 2),
                }
            })
        );
        s.on_frame(ms(200), b, 1, &tpdo(0x11, 3), &mut out);
        assert_eq!(
            out.events.pop().map(|e| e.kind),
            Some(LinkEventKind::DiscrepancyCleared {
                pair: p,
                function: 1
            })
        );
    }
}
