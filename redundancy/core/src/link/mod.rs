//! Layer 1, the **dual-bus abstraction layer**: [`DualBus`](dual_bus::DualBus), a sans-IO
//! [`BusLink`](duocan_core::BusLink) with two ports below and one logical bus above, so that a node
//! of the standard stack runs on top unchanged.
//!
//! | Part | Module |
//! | --- | --- |
//! | The layer itself: ports below, logical bus above, one of three policies | [`dual_bus`] |
//! | Exact duplicate merge of the two ports' receptions (active-active) | [`merge`] |
//! | Sticky merge, the alternative: each sender from one bus, switching after a silence | [`sticky`] |
//! | Each port's lag from matched twins: the merge window, distrust beyond the maximum | [`lag`] |
//! | Port health: counters, error causes, ok / suspect / failed / recovering, re-initialisation | [`health`] |
//! | Per-node, per-bus reachability | [`reach`] |
//! | Heartbeat plausibility per node and bus: babbling identifiers, duplicate node-IDs, impostors on one bus | [`plausible`] |
//! | The channel policies: active-active, CiA 302-6, ECSS bus toggle | [`channel`] |
//! | Same-function merge of the two boards of a pair | [`same_function`] |
//! | Which frames carry which node's process data | [`classify`] |
//! | Configuration ([`DualBusConfig`](config::DualBusConfig)), from code or from the dictionary (0x1F60, 0x2000) | [`config`] |
//! | What the layer reports, and the bounded queues it reports through | [`events`], [`outbox`] |
//! | CAN FD frames through the layer (feature `fd`): merged exactly, sent only where every port is FD-capable | `dual_bus::fd` |
//!
//! Nothing here knows the supervisor: the layer is told which board of a pair is active, and
//! that is all it knows of pairs.
//!
//! A frame that arrives on both buses goes up once; a frame sent on the logical bus goes out
//! on both:
//!
//! ```
//! use duocan_core::{BusLink, Frame, Id, Instant};
//! use duocan_redundancy_core::{DualBus, DualBusConfig};
//!
//! let mut link: DualBus = DualBus::new(DualBusConfig::default());
//! let t = Instant::from_millis;
//! let tpdo = Frame::from_array(Id::Standard(0x185), [0x34, 0x12]);
//! // Port 0 hears it first; the copy on port 1, 2 ms later, is its twin and is dropped.
//! assert_eq!(link.handle_rx(t(10), 0, &tpdo), Some(tpdo));
//! assert_eq!(link.handle_rx(t(12), 1, &tpdo), None);
//! assert_eq!(link.stats().delivered, 1);
//!
//! // Sending fans out to every port that has not failed.
//! let sync = Frame::from_array(Id::Standard(0x080), []);
//! link.send(t(20), &sync);
//! let out: Vec<_> = std::iter::from_fn(|| link.poll_transmit()).collect();
//! assert_eq!(out, [(0, sync), (1, sync)]);
//! ```
//!
//! # The clock contract
//!
//! The layer keeps [duocan's clock contract](duocan_core::frame::instant#the-clock-contract) as the
//! stack's machines do, for every time its parts hold:
//!
//! - **A step back** is noticed by one [`TimeWatch`](duocan_core::frame::instant::TimeWatch) in the
//!   [`DualBus`](dual_bus::DualBus), on every input that carries a time it uses (a frame, a port
//!   status, a send, `handle_timeout`, a channel selection), and measured from the latest time the
//!   layer was given; on the frame path that is one comparison. The layer then moves back
//!   by the step every time held: port health's silence references, missed first copies, error
//!   times, the hand-over times of waiting frames and the transmit-stall references
//!   (`last_sent`, `overtaken`), back-off and probation, the counters' last times; the merger's
//!   records (their window and horizon keep the time they had to run); the lag meter's periods
//!   and twins; reachability's last frames; plausibility's buckets, last heartbeats and each bus's last frame and idle instant; the
//!   same-function values and their discrepancy clocks; the CiA 302-6 evaluation windows and
//!   transmit delays; the ECSS heartbeat deadline and toggle instants. A bus that dies right
//!   after the step fails exactly the silence limit after its last frame, as measured in the
//!   new time line. Events already queued keep the instant they were reported at. A time older
//!   than the step lands on the new time line's origin (instants are unsigned).
//! - The parts that can be used on their own ([`Merger`](merge::Merger),
//!   [`LagMeter`](lag::LagMeter), a [`ChannelPolicy`](channel::ChannelPolicy)) do not watch the
//!   clock themselves: their owner tells them of a step (`step_back`).
//! - **A jump ahead** is time that passed: each deadline in between is handled once, at its own
//!   instant (the events carry it), in a bounded number of rounds whatever the jump: port
//!   health takes at most its two silence steps per call, the lag meter at most three period
//!   ends before it computes the period of the new time, the CiA 302-6 redundancy window is
//!   computed, the ECSS slave toggles at most Ntoggle times (once for zero).
//! - **One clock for both ports.** A frame's receive stamps on the two ports are compared
//!   with each other and with the layer's time, so they are read from the clock that time
//!   comes from ([`Device::handle_rx_at`](duocan_core::machine::Device::handle_rx_at)). A driver
//!   with a clock per controller converts its stamps first: clocks that drift apart are
//!   followed as a changing lag only while both buses carry frames and nothing else goes wrong.
//! - **At [`Instant::MAX`](duocan_core::Instant::MAX)** no deadline is reported, so nothing stays
//!   due; a frame heard then counts as heard a microsecond before (the tables use the end of
//!   time for "never heard").

pub mod capacity;
pub mod channel;
pub mod classify;
pub mod config;
pub mod dual_bus;
pub mod events;
pub mod health;
pub mod lag;
pub mod merge;
pub mod outbox;
pub mod plausible;
pub mod reach;
pub mod same_function;
#[cfg(feature = "sticky")]
pub mod sticky;
