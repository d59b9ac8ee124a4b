//! The sticky merge: each sender's frames from one bus at a time, switching to the other bus
//! after a silence. An alternative to the exact merge ([`crate::link::merge`]) for the
//! active-active mode, chosen per network ([`MergePolicy`]).
//!
//! # The rule
//!
//! The frames are grouped into **streams** (see below). A stream's frames are delivered from one
//! bus only, the bus it is **bound** to; the other bus's copies are dropped
//! ([`StickyVerdict::Dropped`]). A frame on the other bus whose receive timestamp is more than
//! `timeout` after the stream's newest frame on the bound bus **switches** the stream: it is
//! delivered and the stream is bound to that bus from then on ([`StickyVerdict::Switched`]). A
//! stream's first frame binds it to the bus that brought it. The stamps are those the exact merge
//! uses (taken where the frame arrived, see
//! [`Device::handle_rx_at`](duocan_core::Device::handle_rx_at)). Nothing is matched and nothing is
//! kept per frame.
//!
//! - **Never a duplicate**, whatever the frames carry (unchanged repeats: SYNC, heartbeats,
//!   cyclic PDOs need no care), however late a port's reader hands frames over, as long as a
//!   frame's two copies are stamped less than the timeout apart: the other bus's copy of an
//!   occurrence the bound bus delivered is stamped less than a timeout after the stream's newest
//!   frame there, so it cannot switch the stream. (And as long as a bus does not repeat a frame itself.)
//! - **A late reader.** The rule judges each frame when it is handed over: a bound port whose
//!   reader runs behind the other's by more than the timeout less the gap between a stream's
//!   frames shows that stream silent for the timeout, and the stream switches (losing as at any
//!   switch). Its stamps keep it from doubling anything.
//! - **Losses.** A frame the bound bus misses is lost, unless that bus then carries nothing of
//!   the stream for a timeout: at a switch, what is lost is what the other bus carried of the
//!   stream within one timeout after its last frame on the old bus. Every loss lies within one
//!   timeout after the stream's last frame on the bus it was bound to; a stream never switched
//!   away from a bus that misses nothing loses nothing.
//! - **Pauses.** With both buses working, a stream whose frames never pause for longer than the
//!   timeout less the skew between the buses never switches. One that pauses longer switches to
//!   the bus that brings its next frame first, without loss, unless the pause ends within about
//!   a skew of the timeout and frames follow closer than the skew: the new bus's copies stamped
//!   before the timeout ran out are dropped, the old bus's come after the switch, and those
//!   frames are lost. Keep the timeout away from the streams' periods (40 ms, between the usual
//!   10, 20, 50 and 100 ms, does).
//!
//! The rule is the one the redundant transports of OpenCyphal apply per source node: they stay
//! with the interface a node's transfers came from and move to another one only when it has
//! delivered nothing of that node for the transfer-ID timeout (two seconds by default there;
//! here a bound on the lag between the buses, see [`MergePolicy`]). CAN frames carry no
//! transfer-ID, hence the stamps.
//!
//! # Streams
//!
//! A frame whose sender the classifier knows ([`FrameClassifier::sender`]: with the predefined
//! set, error control, EMCY, TPDOs and SDO responses) belongs to that node's stream: a fault that
//! takes a node off one bus (its port, its stub) concerns all its frames alike, and a node's
//! frames keep their order. A frame without a known sender (NMT, SYNC, TIME, LSS, RPDOs, SDO
//! requests, remote frames) belongs to the stream of its identifier (with the remote bit): in
//! CANopen one producer sends a given identifier, so that is the finest grain the frame tells.
//!
//! # A port not trusted yet
//!
//! A bus that comes back may first carry frames queued before its fault. A port the layer does
//! not trust yet ([`Trust::Unproven`]) neither starts a stream nor takes one over while the other
//! port has received anything, of any stream, within a timeout before the frame
//! ([`StickyVerdict::Unproven`]): while the other bus works, its streams stay there. A failed
//! bound port does not make its streams switch at once: the timeout is what keeps the other
//! bus's copies of what the failed bus delivered last from coming twice. They switch as always,
//! a timeout after their last frame on it; port health fails a silent port later than that (its
//! silence limit).
//!
//! # Memory
//!
//! One stream per node-ID (128) and [`ID_STREAMS`] identifier streams, 8 bytes each plus a
//! 4-byte key, one shared stream, each port's newest stamp: fixed, under 2 KB, nothing per
//! frame. O(1) per frame with a known sender; a scan of the identifier table otherwise.
//!
//! # Overflow
//!
//! An identifier stream is **done** once the port it is not bound to has received frames stamped
//! more than a timeout after its newest one (or that port failed): no copy of what it delivered
//! can still come, and its next frame may start it afresh. A new identifier takes the entry of
//! the oldest stream if that is done ([`StickyStats::evicted`]). If none is, the identifiers
//! without an entry share one stream ([`StickyStats::overflow`] counts their frames): coarser
//! (a fault that takes some of them off its bound bus loses those until all of them pause for a
//! timeout) but as free of duplicates as any stream. New identifiers get entries again once
//! that shared stream is done.
//!
//! # Order
//!
//! Between switches a stream is delivered from one bus, in that bus's order, which is the order
//! sent. The first frame after a switch is stamped more than a timeout after the last one
//! delivered from the old bus, so (copies stamped less than the timeout apart) it was sent after
//! it: each stream keeps the order sent. Frames of two streams bound to different buses come in
//! the order their buses bring them.
//!
//! # Against the exact merge
//!
//! The exact merge delivers every occurrence exactly once while either bus carries it: a frame
//! one bus misses is taken from the other at once, and a dead bus costs nothing. It needs the
//! twins' stamps within the skew window, or a lag it measures from frames whose content changes;
//! until it has, a lag beyond the window can bring copies twice, and a repeat may be paired one
//! occurrence off when a bus misses frames and then dies; a reader running behind costs
//! nothing up to its horizon. The sticky merge never delivers a copy twice, whatever the
//! content, with any lag of the stamps below the timeout and any reader delay, and keeps
//! nothing per frame; it pays with losses: a frame its bound bus misses, and up to a timeout of
//! a stream at each switch (after a fault, a reader that fell behind, or a pause of about the
//! timeout). Choose it where a duplicate is worse than a short gap (commands, counters a
//! consumer cannot deduplicate) or where the lag between the buses is large or not measurable
//! (no frames whose content changes).
//!
//! ```
//! use duocan_core::{Duration, Instant, NodeId};
//! use duocan_redundancy_core::link::merge::Trust;
//! use duocan_redundancy_core::link::sticky::{StickyMerger, StickyVerdict, StreamKey};
//!
//! let mut m = StickyMerger::new(Duration::from_millis(40));
//! let t = Instant::from_millis;
//! let node5 = StreamKey::Node(NodeId::must(5));
//! let mut arrive = |ms, port| m.arrive_at(t(ms), t(ms), port, node5, Trust::Trusted);
//! // Node 5 sends every 10 ms; bus 2's copies are stamped 3 ms later. Bus 1 came first.
//! for k in 0..5 {
//!     assert_eq!(arrive(10 * k, 0), StickyVerdict::Deliver);
//!     assert_eq!(arrive(10 * k + 3, 1), StickyVerdict::Dropped);
//! }
//! // Bus 1 loses node 5 after its frame at 40 ms: bus 2's copies up to 40 ms later are lost,
//! // the next one switches the stream.
//! for k in 5..8 {
//!     assert_eq!(arrive(10 * k + 3, 1), StickyVerdict::Dropped);
//! }
//! assert_eq!(arrive(83, 1), StickyVerdict::Switched);
//! assert_eq!(arrive(93, 1), StickyVerdict::Deliver);
//! assert_eq!(arrive(90, 0), StickyVerdict::Dropped); // bus 1 back: its copies are dropped
//! ```

mod table;

use crate::link::merge::Trust;
use duocan_core::{Duration, Frame, Id, Instant, NodeId};
use table::{id_key, IdTable, Stream, UNBOUND};

#[cfg(doc)]
use crate::link::{classify::FrameClassifier, config::MergePolicy};

/// Identifier streams (frames without a known sender) a [`StickyMerger`] holds.
pub const ID_STREAMS: usize = 64;
/// Node streams: one per node-ID (index 0 unused).
const NODES: usize = 128;

/// Which stream a frame belongs to (see the module documentation).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum StreamKey {
    /// The frames of a known sender.
    Node(NodeId),
    /// The frames of one identifier whose sender is not known.
    Id {
        /// The identifier.
        id: Id,
        /// A remote frame.
        remote: bool,
    },
}

impl StreamKey {
    /// The stream of `frame`, sent by `sender` if the classifier knows.
    #[inline]
    pub fn of(frame: &Frame, sender: Option<NodeId>) -> Self {
        match sender {
            Some(n) => StreamKey::Node(n),
            None => StreamKey::Id {
                id: frame.id(),
                remote: frame.is_remote(),
            },
        }
    }
}

/// What to do with an arrival.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StickyVerdict {
    /// From the stream's bound port (or its first frame): deliver it.
    Deliver,
    /// From the other port, more than a timeout after the stream's newest frame on its bound
    /// port: deliver it, the stream is bound to this port now.
    Switched,
    /// From the port the stream is not bound to: dropped.
    Dropped,
    /// From a port not trusted yet while the other port works: dropped.
    Unproven,
}

/// What a sticky merger has done since it was created.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StickyStats {
    /// Arrivals delivered (switches included).
    pub delivered: u64,
    /// Arrivals dropped: copies from the port their stream is not bound to.
    pub dropped: u64,
    /// Arrivals from a port not trusted yet dropped ([`StickyVerdict::Unproven`]).
    pub unproven: u64,
    /// Streams switched to the other port.
    pub switches: u64,
    /// Arrivals judged in the shared stream because the identifier table was full.
    pub overflow: u64,
    /// Identifier streams forgotten, done, to make room for a new identifier.
    pub evicted: u64,
    /// Arrivals on a port other than 0 and 1 (delivered, not judged).
    pub bad_port: u64,
}

/// The sticky receive merger for two ports (0 and 1).
pub struct StickyMerger {
    timeout: u64,
    nodes: [Stream; NODES],
    ids: IdTable,
    /// The stream of identifiers beyond the table.
    shared: Stream,
    /// Per port: the newest stamp it received (µs; 0: none).
    frontier: [u64; 2],
    /// Per port: failed, as the layer last said ([`StickyMerger::set_failed`]).
    failed: [bool; 2],
    stats: StickyStats,
}

impl StickyMerger {
    /// An empty merger switching a stream after `timeout` of silence on its bound port.
    #[must_use]
    pub const fn new(timeout: Duration) -> Self {
        StickyMerger {
            timeout: timeout.as_micros(),
            nodes: [Stream::FREE; NODES],
            ids: IdTable::new(),
            shared: Stream::FREE,
            frontier: [0; 2],
            failed: [false; 2],
            stats: StickyStats {
                delivered: 0,
                dropped: 0,
                unproven: 0,
                switches: 0,
                overflow: 0,
                evicted: 0,
                bad_port: 0,
            },
        }
    }

    /// The silence after which a stream switches.
    pub fn timeout(&self) -> Duration {
        Duration::from_micros(self.timeout)
    }
    /// Counters.
    pub fn stats(&self) -> StickyStats {
        self.stats
    }
    /// Identifier streams held now.
    pub fn id_streams(&self) -> usize {
        self.ids.len()
    }
    /// The port `key`'s stream is bound to, if any (identifiers beyond the table: the shared
    /// stream's).
    pub fn bound(&self, key: StreamKey) -> Option<usize> {
        let s = match key {
            StreamKey::Node(n) => self.nodes[n.raw() as usize % NODES],
            StreamKey::Id { .. } => *self.ids.get(id_key(key)).unwrap_or(&self.shared),
        };
        (s.bound() != UNBOUND).then_some(s.bound() as usize)
    }

    /// The caller's clock stepped back `by` (the clock contract, see [`crate::link`]): every
    /// stamp held moves back with it, so that a stream keeps the silence it has left. Runs
    /// through the whole table: rare, not on the frame path.
    #[cold]
    pub fn step_back(&mut self, by: Duration) {
        let by = by.as_micros();
        let back = |s: &mut Stream| *s = Stream::new(s.last().saturating_sub(by), s.bound());
        self.nodes.iter_mut().for_each(back);
        self.ids.streams_mut().iter_mut().for_each(back);
        back(&mut self.shared);
        for f in &mut self.frontier {
            // A port that received something keeps a stamp (0 means none).
            if *f > 0 {
                *f = f.saturating_sub(by).max(1);
            }
        }
    }

    /// Port `p` (0 or 1) is failed, or no longer (the layer's port health says so before each
    /// arrival): a stream bound to a failed port is done, its frames cannot come twice.
    pub fn set_failed(&mut self, p: usize, failed: bool) {
        if let Some(f) = self.failed.get_mut(p) {
            *f = failed;
        }
    }

    /// A frame of stream `key` arrived on `port` (0 or 1) at `now`, stamped `now`, on a trusted
    /// port: the merger for a driver without receive timestamps.
    #[inline]
    pub fn arrive(&mut self, now: Instant, port: usize, key: StreamKey) -> StickyVerdict {
        self.arrive_at(now, now, port, key, Trust::Trusted)
    }

    /// A frame of stream `key` that arrived on `port` (0 or 1) at `at`, its receive timestamp,
    /// handled at `now`; `trust` says whether the layer trusts the port yet. A stamp later than
    /// `now` is taken as `now`.
    #[inline]
    pub fn arrive_at(
        &mut self,
        now: Instant,
        at: Instant,
        port: usize,
        key: StreamKey,
        trust: Trust,
    ) -> StickyVerdict {
        if port > 1 {
            self.stats.bad_port += 1;
            self.stats.delivered += 1;
            return StickyVerdict::Deliver;
        }
        // Zero is "nothing received" in the frontier: stamps start at 1 µs.
        let s = at.min(now).as_micros().max(1);
        let verdict = self.judge(s, port, key, trust);
        if self.frontier[port] < s {
            self.frontier[port] = s;
        }
        match verdict {
            StickyVerdict::Deliver => self.stats.delivered += 1,
            StickyVerdict::Switched => {
                self.stats.delivered += 1;
                self.stats.switches += 1;
            }
            StickyVerdict::Dropped => self.stats.dropped += 1,
            StickyVerdict::Unproven => self.stats.unproven += 1,
        }
        verdict
    }

    #[inline]
    fn judge(&mut self, s: u64, port: usize, key: StreamKey, trust: Trust) -> StickyVerdict {
        let timeout = self.timeout;
        // A port not trusted yet leads a stream only when the other port has fallen silent.
        let other = self.frontier[1 - port];
        let may_lead = trust != Trust::Unproven || other == 0 || other + timeout < s;
        let stream = self.stream(key);
        if stream.bound() == port as u8 {
            *stream = Stream::new(stream.last().max(s), stream.bound());
            return StickyVerdict::Deliver;
        }
        let (verdict, silent) = if stream.bound() == UNBOUND {
            (StickyVerdict::Deliver, true)
        } else {
            (
                StickyVerdict::Switched,
                s > stream.last().saturating_add(timeout),
            )
        };
        if !silent {
            StickyVerdict::Dropped
        } else if !may_lead {
            StickyVerdict::Unproven
        } else {
            *stream = Stream::new(s, port as u8);
            verdict
        }
    }

    /// The stream of `key`: an identifier without an entry gets one, the oldest done stream's
    /// if the table is full, or else shares the overflow stream.
    #[inline]
    fn stream(&mut self, key: StreamKey) -> &mut Stream {
        let k = match key {
            StreamKey::Node(n) => return &mut self.nodes[n.raw() as usize % NODES],
            StreamKey::Id { .. } => id_key(key),
        };
        if let Some(i) = self.ids.find(k) {
            return &mut self.ids.streams[i];
        }
        self.new_id_stream(k)
    }

    #[cold]
    fn new_id_stream(&mut self, k: u32) -> &mut Stream {
        if self.shared.bound() != UNBOUND {
            if !self.done(self.shared) {
                self.stats.overflow += 1;
                return &mut self.shared;
            }
            // Its identifiers may have entries again: no copy of what it delivered can come.
            self.shared = Stream::FREE;
        }
        let i = match self.ids.insert(k) {
            Some(i) => i,
            None => match self.ids.oldest() {
                Some(old) if self.done(self.ids.streams[old]) => {
                    self.ids.remove(old);
                    self.stats.evicted += 1;
                    self.ids.insert(k).unwrap_or(old)
                }
                _ => {
                    self.stats.overflow += 1;
                    return &mut self.shared;
                }
            },
        };
        &mut self.ids.streams[i]
    }

    /// True if no copy of what `s` delivered can still come: the port it is not bound to has
    /// received frames stamped more than a timeout after its newest one, or failed.
    fn done(&self, s: Stream) -> bool {
        if s.bound() == UNBOUND {
            return true;
        }
        let q = 1 - s.bound() as usize;
        self.failed[q] || self.frontier[q] > s.last().saturating_add(self.timeout)
    }
}

impl core::fmt::Debug for StickyMerger {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("StickyMerger")
            .field("timeout", &self.timeout())
            .field("id_streams", &self.ids.len())
            .field("stats", &self.stats)
            .finish()
    }
}

#[cfg(test)]
mod tests;
