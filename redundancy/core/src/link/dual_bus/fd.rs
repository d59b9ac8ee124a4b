//! CAN FD frames through the layer (feature `fd`): sent on both ports, received from both and
//! merged exactly, counted by port health as classic frames are.
//!
//! # The rule for a network
//!
//! A classic-only controller answers an FD frame on its bus with error frames, so FD frames
//! belong only where every port is FD-capable. The driver says which of its ports are
//! ([`DualBus::set_port_fd`]; none by default): [`DualBus::send_fd`] on a layer with a
//! classic-only port is an error naming the port ([`FdSendError`]), and nothing is queued for
//! either port (an FD frame on one bus only would leave the other bus's receivers without it,
//! a twin the merge waits for in vain). Receiving needs no such rule: a port that hands over an
//! FD frame has carried one.
//!
//! # What an FD frame goes through
//!
//! - **Send** ([`DualBus::send_fd`]): the channel policy routes it as a classic frame of its
//!   identifier (both ports in active-active, the active channel in CiA 302-6 and ECSS); each
//!   copy has the next logical frame number, shared with classic frames, so port health's
//!   transmit-stall rule sees one sequence; [`DualBus::poll_transmit_fd`] hands the copies out
//!   (a queue of [`FD_FRAME_QUEUE`](crate::link::outbox::FD_FRAME_QUEUE) per port beside the
//!   classic one: a driver asks for FD frames after classic ones, each kind keeps its order).
//! - **Receive** ([`DualBus::handle_rx_fd_at`]): reachability, the bus's idle witness, the
//!   channel policy and the sticky merge see it as a frame of its identifier and first eight
//!   bytes; the exact merge keys it on every byte (see [`crate::link::merge`]); port health
//!   counts it, with the merge's outcome, as a classic frame; the same-function merge of a pair
//!   judges it by its identifier and first eight bytes. An FD frame is never a heartbeat (CANopen
//!   error control is classic), so plausibility's heartbeat rules do not apply to it.
//! - **Up and down a station**: as a [`BusLink`](duocan_core::BusLink), the layer carries
//!   CAN FD frames for the machine above it (a node serving USDO, a master's USDO client)
//!   through the same paths: what a port receives goes up merged, once per occurrence; what the
//!   machine sends goes out as [`DualBus::send_fd`] routes it. On a layer with a classic-only
//!   port the machine's FD frames are dropped and counted
//!   ([`LinkStats::fd_refused`](super::LinkStats::fd_refused)): a machine has no error to take.
//! - **Lag**: a twin within the window measures the lag as a classic one does; a twin beyond
//!   the window (a *late* sample) is not taken from FD frames, as the layer holds a classic
//!   frame only to withdraw such a sample (see `rx`).
//!
//! ```
//! use duocan_core::frame::FdFrame;
//! use duocan_core::{Id, Instant};
//! use duocan_redundancy_core::link::dual_bus::fd::FdSendError;
//! use duocan_redundancy_core::{DualBus, DualBusConfig};
//!
//! let mut link: DualBus = DualBus::new(DualBusConfig::default());
//! let t = Instant::from_millis;
//! let pdo = FdFrame::new(Id::Standard(0x185), &[0x5A; 64]).unwrap().with_brs(true);
//! // Port 1's bus is classic-only: no FD frame on either bus.
//! link.set_port_fd(0, true);
//! assert_eq!(link.send_fd(t(1), &pdo), Err(FdSendError::ClassicPort { port: 1 }));
//! link.set_port_fd(1, true);
//! link.send_fd(t(1), &pdo).unwrap();
//! let out: Vec<_> = std::iter::from_fn(|| link.poll_transmit_fd()).collect();
//! assert_eq!(out, [(0, pdo), (1, pdo)]);
//! // Received on both buses (on port 1 from a sender error passive there): delivered once.
//! assert_eq!(link.handle_rx_fd(t(10), 0, &pdo), Some(pdo));
//! assert_eq!(link.handle_rx_fd(t(11), 1, &pdo.with_esi(true)), None);
//! assert_eq!(link.port(0).counters().rx + link.port(1).counters().rx, 2);
//! ```

use super::DualBus;
use crate::link::capacity::{MergeCapacity, MergerStorage};
use crate::link::channel::{ChannelPolicy, FrameInfo, RxRoute};
use crate::link::classify::FrameClassifier;
use crate::link::health::RxOutcome;
use crate::link::merge::Verdict;
use core::fmt;
use duocan_core::frame::FdFrame;
use duocan_core::{Frame, Instant};

/// Why [`DualBus::send_fd`] sent nothing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FdSendError {
    /// Port `port` is classic-only (or not said to be FD-capable, see
    /// [`DualBus::set_port_fd`]): its bus's classic nodes would answer the frame with error
    /// frames.
    ClassicPort {
        /// The first classic-only port.
        port: usize,
    },
}

impl fmt::Display for FdSendError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FdSendError::ClassicPort { port } => write!(
                f,
                "CAN FD frame not sent: port {port} is classic-only (FD frames need every port FD-capable)"
            ),
        }
    }
}

impl core::error::Error for FdSendError {}

/// A classic frame of `f`'s identifier and first (up to) eight bytes: what the parts that look
/// at identifiers, or at a value's first bytes, see of an FD frame.
fn stand_in(f: &FdFrame) -> Frame {
    let data = f.data();
    // At most eight bytes of a standard or extended identifier: cannot fail.
    Frame::new(f.id(), &data[..data.len().min(8)]).unwrap_or(Frame::from_array(f.id(), []))
}

impl<C: FrameClassifier, K: MergeCapacity> DualBus<C, K> {
    /// Says whether port `port` (0 or 1; others are ignored) is FD-capable: its controller and
    /// every node on its bus speak CAN FD (see the [module](self)).
    pub fn set_port_fd(&mut self, port: usize, fd: bool) {
        if let Some(p) = self.fd.get_mut(port) {
            *p = fd;
        }
    }

    /// Whether every port is FD-capable: [`DualBus::send_fd`] sends.
    pub fn fd_capable(&self) -> bool {
        self.fd == [true, true]
    }

    /// A logical CAN FD frame to send: queued for the ports the channel policy routes it to,
    /// or, with a classic-only port, an error and nothing queued.
    pub fn send_fd(&mut self, now: Instant, frame: &FdFrame) -> Result<(), FdSendError> {
        if let Some(port) = self.fd.iter().position(|fd| !fd) {
            return Err(FdSendError::ClassicPort { port });
        }
        self.watch_clock(now);
        self.out.next_frame();
        let info = FrameInfo { heartbeat: None };
        let mask = self
            .policy
            .route_tx(now, &stand_in(frame), &info, &self.health, &mut self.out);
        self.show_status();
        for p in 0..2 {
            if mask & (1 << p) != 0 {
                self.out.fd_frame(p, *frame);
            }
        }
        Ok(())
    }

    /// Next CAN FD frame for a port; port health counts it sent as a classic one.
    pub fn poll_transmit_fd(&mut self) -> Option<(usize, FdFrame)> {
        self.poll_numbered_fd().map(|(p, f, _)| (p, f))
    }

    /// As [`DualBus::poll_transmit_fd`], with the number of the logical frame the copy is of
    /// (see [`DualBus::frame_number`]).
    pub fn poll_numbered_fd(&mut self) -> Option<(usize, FdFrame, u32)> {
        let (p, f, n) = self.out.pop_fd_numbered()?;
        self.health.count_tx(self.clock.latest(), p, n);
        self.plausible.on_handed(self.clock.latest(), p);
        Some((p, f, n))
    }

    /// A CAN FD frame from `port`, stamped when it is handed over (a driver without receive
    /// timestamps); returns the logical frame to deliver upward, if any.
    pub fn handle_rx_fd(&mut self, now: Instant, port: usize, frame: &FdFrame) -> Option<FdFrame> {
        self.rx_fd(now, port, frame, now, false)
    }

    /// A CAN FD frame from `port` that arrived at `at`, its receive timestamp, handled at
    /// `now` (as [`BusLink::handle_rx_at`](duocan_core::BusLink::handle_rx_at)).
    pub fn handle_rx_fd_at(
        &mut self,
        now: Instant,
        port: usize,
        frame: &FdFrame,
        at: Instant,
    ) -> Option<FdFrame> {
        self.rx_fd(now, port, frame, at, true)
    }

    /// The receive path of an FD frame (see the [module](self)); the classic one is `rx`.
    fn rx_fd(
        &mut self,
        now: Instant,
        port: usize,
        frame: &FdFrame,
        at: Instant,
        stamped: bool,
    ) -> Option<FdFrame> {
        if !self.rx_begins(now, port, stamped) {
            return None;
        }
        let at = at.min(now);
        let stand = stand_in(frame);
        if self.reach_enabled {
            if let Some(n) = self.classifier.sender(&stand) {
                self.reach.on_heard(now, n, port, &mut self.out);
            }
        }
        self.plausible.on_frame(at, port, &self.health);
        let info = FrameInfo { heartbeat: None };
        let route = self.policy.on_rx(now, port, &stand, &info, &mut self.out);
        self.show_status();
        let outcome = match route {
            RxRoute::Ignore => RxOutcome::Ignored,
            RxRoute::Direct => RxOutcome::Direct,
            #[cfg(feature = "sticky")]
            RxRoute::Merge if self.sticky.is_some() => self.stick(now, at, port, &stand),
            RxRoute::Merge => self.merge_fd(now, at, port, frame),
        };
        if !self.settled(now, at, port, outcome) {
            return None;
        }
        if self.held_as_standby(now, &stand) {
            return None;
        }
        self.stats.delivered += 1;
        Some(*frame)
    }

    /// An FD frame stamped `at` on `port` through the exact merge: as `merge` for classic
    /// frames, without late samples (see the [module](self)).
    fn merge_fd(&mut self, now: Instant, at: Instant, port: usize, frame: &FdFrame) -> RxOutcome {
        let s = self.lag.correct(port, at);
        let trust = self.trust(port);
        let (verdict, sample) = self.merger.arrive_fd_at(now, s, port, frame, trust);
        // A classic late sample held: an FD frame is never its copy's twin, but one of the
        // other port stamped past where that twin would be settles it, as a classic one does.
        if self.late.is_some_and(|l| l.stands_after(port, s)) {
            self.late = None;
        }
        let slipped = sample.is_some_and(|m| m.late && self.intact_between(port, s, &m));
        if let Some(m) = sample.filter(|m| !m.late) {
            let before = [self.lag.lag(0), self.lag.lag(1)];
            if self.lag.sample(now, port, m, &mut self.out) {
                for (p, was) in before.into_iter().enumerate() {
                    let by = self.lag.lag(p).as_micros() as i64 - was.as_micros() as i64;
                    self.merger.shift(p, by);
                }
                self.follow_lag(now);
            }
        }
        match verdict {
            Verdict::Deliver if slipped => RxOutcome::Slipped,
            Verdict::Deliver => RxOutcome::Delivered,
            Verdict::Duplicate => RxOutcome::Duplicate,
            Verdict::Late | Verdict::Unproven => RxOutcome::Stale,
        }
    }
}
