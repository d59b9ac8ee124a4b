//! The audit trail: every switch-over, toggle and role change with its reason and time.
//!
//! A fixed-capacity ring: when full, the oldest record is overwritten and counted
//! ([`AuditTrail::overwritten`]), so memory stays bounded and the loss is visible. Records carry
//! a sequence number, so an exporter that reads periodically can tell whether it missed some.
//! Export as text lines ([`AuditTrail::write_text`]) or CSV ([`AuditTrail::write_csv`]) into any
//! [`core::fmt::Write`].

use crate::link::events::{LinkEvent, LinkEventKind};
use crate::pair::{Member, PairId};
use crate::supervisor::flying_master::{MasterRole, MasterRoleChange};
use crate::supervisor::pairs::RoleChange;
use core::fmt::{self, Write};
use duocan_core::cia305::LssAddress;
#[cfg(feature = "alloc")]
use duocan_core::frame::storage::Heap;
use duocan_core::frame::storage::{BoundedVec, Inline, Storage};
use duocan_core::{Instant, NodeId};

/// Records a trail holds unless chosen otherwise.
pub const AUDIT_CAPACITY: usize = 256;

/// What is recorded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AuditEntry {
    /// A pair's active member changed.
    Pair(RoleChange),
    /// This master's role changed.
    Master(MasterRoleChange),
    /// A port state change, channel switch or bus toggle of the dual-bus layer.
    Link(LinkEvent),
    /// This master suspended its NMT commands (another active master suspected).
    Suspended {
        /// Until when.
        until: Instant,
    },
    /// A board that arrived without a node-ID was given a pair member's node-ID by LSS.
    Addressed(BoardAddressed),
}

/// A replacement board given a pair slot's node-ID by LSS (CiA 305): it joins through the
/// normal boot (identity check, configuration) from there.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BoardAddressed {
    /// When the board took the node-ID.
    pub at: Instant,
    /// The pair.
    pub pair: PairId,
    /// The slot.
    pub member: Member,
    /// The node-ID it was given.
    pub node: NodeId,
    /// The board's identity (its serial number included).
    pub address: LssAddress,
}

impl BoardAddressed {
    /// Its line without the time (the event streams print the time apart, the audit trail in
    /// front of it).
    /// Public for the front door of duocan-redundancy, not for applications.
    #[doc(hidden)]
    pub fn fmt_untimed(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "pair {} member {}: a board without node-ID ({}) given {} by LSS",
            self.pair.0,
            role(Some(self.member)),
            self.address,
            self.node
        )
    }
}

impl fmt::Display for BoardAddressed {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: ", self.at)?;
        self.fmt_untimed(f)
    }
}

impl AuditEntry {
    /// Whether a link event belongs in the trail (state changes, switches, toggles, verdicts on
    /// a node's heartbeats: impostor, babbling identifier, duplicate node-ID; not reachability or
    /// discrepancy reports).
    pub fn link_worth_recording(e: &LinkEvent) -> bool {
        matches!(
            e.kind,
            LinkEventKind::Port { .. }
                | LinkEventKind::Channel { .. }
                | LinkEventKind::Toggle { .. }
                | LinkEventKind::MasterLost { .. }
                | LinkEventKind::MasterFound { .. }
                | LinkEventKind::NoMaster { .. }
                | LinkEventKind::DefaultDisabled { .. }
                | LinkEventKind::Suspect { .. }
                | LinkEventKind::Trusted { .. }
                | LinkEventKind::Babbling { .. }
                | LinkEventKind::DuplicateNode { .. }
        )
    }
    fn kind(&self) -> &'static str {
        match self {
            AuditEntry::Pair(_) => "pair",
            AuditEntry::Master(_) => "master",
            AuditEntry::Link(_) => "link",
            AuditEntry::Suspended { .. } => "suspend",
            AuditEntry::Addressed(_) => "lss",
        }
    }
}

/// One record.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AuditRecord {
    /// Sequence number, from 1, never reused.
    pub seq: u32,
    /// When it happened.
    pub at: Instant,
    /// What.
    pub entry: AuditEntry,
}

fn role(r: Option<Member>) -> &'static str {
    match r {
        Some(Member::A) => "A",
        Some(Member::B) => "B",
        None => "none",
    }
}

/// `#12 1.250000s pair 3 (A node 0x10, B node 0x11) active A -> B: active member silent since …`
impl fmt::Display for AuditRecord {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "#{} ", self.seq)?;
        match &self.entry {
            AuditEntry::Pair(r) => write!(f, "{r}"),
            AuditEntry::Master(m) => write!(f, "{m}"),
            AuditEntry::Link(l) => write!(f, "{l}"),
            AuditEntry::Suspended { until } => write!(
                f,
                "{}: NMT commands suspended until {until}: another active master suspected",
                self.at
            ),
            AuditEntry::Addressed(b) => write!(f, "{b}"),
        }
    }
}

/// A bounded trail of [`AuditRecord`]s, kept in `S`: inline ([`Inline`], the default: `N`
/// records, no allocator) or on the heap ([`Heap`], `alloc`:
/// the room given to [`with_capacity`](AuditTrail::with_capacity), allocated once).
pub struct AuditTrail<const N: usize = AUDIT_CAPACITY, S: Storage = Inline> {
    /// Filled up to `room`, then overwritten in place from `head` (the oldest record).
    ring: S::Vec<AuditRecord, N>,
    room: usize,
    head: usize,
    seq: u32,
    overwritten: u32,
}

impl<const N: usize> Default for AuditTrail<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> AuditTrail<N> {
    /// An empty trail of `N` records.
    #[must_use]
    pub fn new() -> Self {
        Self::build(N)
    }
}

#[cfg(feature = "alloc")]
impl<const N: usize> AuditTrail<N, Heap> {
    /// An empty trail of `records` records (at least 1), allocated now, never grown.
    #[must_use]
    pub fn with_capacity(records: usize) -> Self {
        Self::build(records.max(1))
    }
}

impl<const N: usize, S: Storage> AuditTrail<N, S> {
    fn build(room: usize) -> Self {
        AuditTrail {
            ring: S::vec(room),
            room,
            head: 0,
            seq: 0,
            overwritten: 0,
        }
    }
    /// Records `entry` at `at`; overwrites (and counts) the oldest record when full.
    pub fn record(&mut self, at: Instant, entry: AuditEntry) {
        self.seq = self.seq.wrapping_add(1);
        let r = AuditRecord {
            seq: self.seq,
            at,
            entry,
        };
        if self.ring.len() < self.room {
            // Cannot fail: the vector was built with room for `room` records.
            let _ = self.ring.try_push(r);
        } else if let Some(oldest) = self.ring.get_mut(self.head) {
            *oldest = r;
            self.head = (self.head + 1) % self.room;
            self.overwritten = self.overwritten.saturating_add(1);
        }
    }
    /// The records kept, oldest first.
    pub fn iter(&self) -> impl Iterator<Item = &AuditRecord> {
        // Until the ring is full the head stays 0: the first part is everything.
        let (newer, older) = self.ring.split_at(self.head);
        older.iter().chain(newer)
    }
    /// Records kept.
    pub fn len(&self) -> usize {
        self.ring.len()
    }
    /// Records the trail holds before it overwrites the oldest.
    pub fn capacity(&self) -> usize {
        self.room
    }
    /// True when nothing was recorded (or all was cleared).
    pub fn is_empty(&self) -> bool {
        self.ring.is_empty()
    }
    /// Records overwritten because the trail was full.
    pub fn overwritten(&self) -> u32 {
        self.overwritten
    }
    /// Records ever made.
    pub fn total(&self) -> u32 {
        self.seq
    }
    /// Records with a sequence number above `seq` (what an exporter has not read yet).
    pub fn since(&self, seq: u32) -> impl Iterator<Item = &AuditRecord> {
        self.iter().filter(move |r| r.seq > seq)
    }
    /// Forgets every record (the counters stay).
    pub fn clear(&mut self) {
        self.ring.clear();
        self.head = 0;
    }

    /// One line per record ([`AuditRecord`]'s `Display`).
    pub fn write_text(&self, out: &mut impl Write) -> fmt::Result {
        if self.overwritten > 0 {
            writeln!(out, "({} older records overwritten)", self.overwritten)?;
        }
        for r in self.iter() {
            writeln!(out, "{r}")?;
        }
        Ok(())
    }

    /// CSV with a header: `seq,time_us,kind,subject,from,to,reason`. The reason is quoted.
    pub fn write_csv(&self, out: &mut impl Write) -> fmt::Result {
        writeln!(out, "seq,time_us,kind,subject,from,to,reason")?;
        for r in self.iter() {
            write!(out, "{},{},{},", r.seq, r.at.as_micros(), r.entry.kind())?;
            match &r.entry {
                AuditEntry::Pair(c) => write!(
                    out,
                    "pair {} ({}/{}),{},{},\"{}\"",
                    c.pair.0,
                    c.nodes[0],
                    c.nodes[1],
                    role(c.from),
                    role(c.to),
                    Quoted(&c.reason)
                )?,
                AuditEntry::Master(m) => write!(
                    out,
                    "master,{},{},\"{}\"",
                    RoleWord(m.from),
                    RoleWord(m.to),
                    Quoted(&m.reason)
                )?,
                AuditEntry::Link(l) => write!(out, "link,,,\"{}\"", Quoted(l))?,
                AuditEntry::Suspended { until } => {
                    write!(out, "master,active,suspended,\"until {until}\"")?
                }
                AuditEntry::Addressed(b) => write!(
                    out,
                    "pair {} ({}),none,{},\"{}\"",
                    b.pair.0,
                    role(Some(b.member)),
                    b.node,
                    Quoted(&b.address)
                )?,
            }
            writeln!(out)?;
        }
        Ok(())
    }
}

impl<const N: usize, S: Storage> fmt::Debug for AuditTrail<N, S> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("AuditTrail")
            .field("len", &self.ring.len())
            .field("total", &self.seq)
            .field("overwritten", &self.overwritten)
            .finish()
    }
}

/// A role as one CSV word.
struct RoleWord(MasterRole);

impl fmt::Display for RoleWord {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self.0 {
            MasterRole::Off => "off",
            MasterRole::Detecting => "detecting",
            MasterRole::Negotiating => "negotiating",
            MasterRole::Active => "active",
            MasterRole::Standby(_) => "standby",
        })
    }
}

/// Displays `T` with `"` doubled, for a quoted CSV field.
struct Quoted<'a, T>(&'a T);

impl<T: fmt::Display> fmt::Display for Quoted<'_, T> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        struct Esc<'a, 'b>(&'a mut fmt::Formatter<'b>);
        impl Write for Esc<'_, '_> {
            fn write_str(&mut self, s: &str) -> fmt::Result {
                for (i, part) in s.split('"').enumerate() {
                    if i > 0 {
                        self.0.write_str("\"\"")?;
                    }
                    self.0.write_str(part)?;
                }
                Ok(())
            }
        }
        write!(Esc(f), "{}", self.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pair::PairId;
    use crate::supervisor::flying_master::MasterReason;
    use crate::supervisor::pairs::RoleReason;
    use duocan_core::NodeId;

    fn change(at: u64) -> AuditEntry {
        AuditEntry::Pair(RoleChange {
            at: Instant::from_millis(at),
            pair: PairId(3),
            nodes: [NodeId::must(0x10), NodeId::must(0x11)],
            from: Some(Member::A),
            to: Some(Member::B),
            reason: RoleReason::ActiveSilent {
                last: Instant::from_millis(at - 50),
            },
        })
    }

    #[test]
    fn the_ring_overwrites_the_oldest_and_counts() {
        let mut t: AuditTrail<4> = AuditTrail::new();
        for i in 0..6 {
            t.record(Instant::from_millis(100 + i), change(100 + i));
        }
        assert_eq!(t.len(), 4);
        assert_eq!(t.overwritten(), 2);
        assert_eq!(t.total(), 6);
        assert_eq!(
            t.iter().map(|r| r.seq).collect::<std::vec::Vec<_>>(),
            [3, 4, 5, 6]
        );
        assert_eq!(t.since(5).count(), 1);
    }

    #[cfg(feature = "alloc")]
    #[test]
    fn a_heap_ring_of_the_room_asked_for_keeps_the_newest_in_order() {
        let mut t: AuditTrail<AUDIT_CAPACITY, Heap> = AuditTrail::with_capacity(3);
        assert_eq!(t.capacity(), 3);
        let seqs = |t: &AuditTrail<AUDIT_CAPACITY, Heap>| {
            t.iter().map(|r| r.seq).collect::<std::vec::Vec<_>>()
        };
        for i in 0..8 {
            t.record(Instant::from_millis(100 + i), change(100 + i));
            let kept = (i + 1).min(3);
            assert_eq!(t.len() as u64, kept);
            // Oldest first across the wrap-around, at every position of the head.
            let want: std::vec::Vec<u32> = ((i + 2 - kept)..=(i + 1)).map(|s| s as u32).collect();
            assert_eq!(seqs(&t), want, "after record {}", i + 1);
        }
        assert_eq!((t.overwritten(), t.total()), (5, 8));
        assert_eq!(
            t.since(6).map(|r| r.seq).collect::<std::vec::Vec<_>>(),
            [7, 8]
        );
        t.clear();
        assert!(t.is_empty());
        t.record(Instant::from_millis(200), change(200));
        assert_eq!(seqs(&t), [9]);
    }

    #[test]
    fn text_and_csv_export() {
        let mut t: AuditTrail<8> = AuditTrail::new();
        t.record(Instant::from_millis(115), change(115));
        t.record(
            Instant::from_millis(200),
            AuditEntry::Master(MasterRoleChange {
                at: Instant::from_millis(200),
                from: MasterRole::Standby(None),
                to: MasterRole::Active,
                reason: MasterReason::HeartbeatLost {
                    master: NodeId::must(1),
                    last: Instant::from_millis(150),
                },
            }),
        );
        let mut s = std::string::String::new();
        t.write_text(&mut s).unwrap();
        let lines: std::vec::Vec<&str> = s.lines().collect();
        assert_eq!(lines.len(), 2);
        assert!(lines[0].starts_with("#1 0.115000s: pair 3"), "{}", lines[0]);
        assert!(lines[0].contains("active A -> B: active member silent since 0.065000s"));
        assert!(
            lines[1].contains("master standby -> active"),
            "{}",
            lines[1]
        );
        let mut c = std::string::String::new();
        t.write_csv(&mut c).unwrap();
        let rows: std::vec::Vec<&str> = c.lines().collect();
        assert_eq!(rows[0], "seq,time_us,kind,subject,from,to,reason");
        assert!(rows[1].starts_with("1,115000,pair,pair 3 ("), "{}", rows[1]);
        assert!(
            rows[1].contains(",A,B,\"active member silent"),
            "{}",
            rows[1]
        );
        assert!(rows[2].starts_with("2,200000,master,master,standby,active,\""));
    }
}
