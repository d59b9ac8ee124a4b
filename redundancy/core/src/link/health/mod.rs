//! Port health: counters, error causes and an explicit state per port.
//!
//! ```text
//!            error report                 silence limit / bus-off / down
//!   ok ──────────────────────▶ suspect ────────────────────────────────▶ failed
//!    ▲  ◀── frame, no error for        ◀──┐                               │ back-off elapsed:
//!    │       the hold time                │                               │ PortRequest::Reinit
//!    │                                    │ silence limit                 ▼   (or Up, a frame,
//!    └──────── frames for the probation ─ recovering ◀────────────────────┘    a TxOk)
//! ```
//!
//! - **Silence.** A port is silent when it has received nothing while the other port received
//!   *first copies* (frames the merger delivered, whose twins this port should have seen within
//!   the skew window). Twins do not count, so a network that simply goes quiet fails nobody. A
//!   port silent for `suspect_after` becomes suspect, for `silence_limit` failed; the instant is
//!   exact: last frame + limit (or first missed frame + window + the port's receive delay, if
//!   later: a port whose reader runs behind hands its twins over that much later). Failing
//!   also takes that the other port received a first copy within the last `suspect_after` (a
//!   quarter of the limit without the suspect step) before that instant; otherwise the port
//!   fails at the next first copy, if still silent. So a network that goes quiet right after a
//!   frame only the other bus carried (a node cut from this bus, answering what nobody else
//!   answers: LSS fastscan steps) does not fail this port; with cyclic traffic on a dead bus
//!   the instant is unchanged. A port
//!   whose driver confirms its transmissions (someone on its bus acknowledged them) is failed
//!   for silence only once it has had none confirmed for the silence limit either: its bus
//!   works and its frames reach the peers there, only its receive path is silent or behind;
//!   failed, it would carry nothing but probes.
//! - **Controller reports.** Bus-off, interface down and transceiver faults fail the port at
//!   once; other errors (error passive, CRC, no-ack, …) make an ok port suspect. Only
//!   transmit errors take a controller bus-off, so a port that goes bus-off again before it
//!   was back (recovering after a restart, or failed that way already) is treated like one
//!   failed for a transmit stall: neither the controller's restart (`Up`) nor received
//!   frames revive it (a transceiver that receives but cannot send hears the network fine,
//!   and goes bus-off again within a millisecond of every restart), only a probe confirmed
//!   or its re-initialisation with its back-off. After any bus-off (with a driver that
//!   confirms transmissions) the port's probation ends only once a transmission was confirmed
//!   too, so a quiet node's port is not ok between two of its heartbeats (with a producer
//!   time longer than the probation, a transceiver that cannot send was back for a moment
//!   after its first bus-off, every time). Its state no longer flaps at the pace of the
//!   controller's restarts.
//! - **Traffic is proof.** A failed port that receives a frame, or whose driver confirms a
//!   transmission (someone on its bus acknowledged it), is recovering at once, whatever its
//!   back-off: the bus works (and the other one may fail the next instant).
//! - **Re-initialisation.** A failed port is re-initialised (`PortRequest::Reinit`) after a
//!   back-off that doubles on every failed attempt up to a maximum, and is reset when the port
//!   is ok again. It is then *recovering*: the transmit fan-out includes it again, and it
//!   returns to ok after receiving frames for the probation time, or fails again after the
//!   silence limit.
//! - **Reaching anyone.** A port is *proven* while it is ok or suspect and its last
//!   transmission was not left unacknowledged (no-ack: nobody on its bus, a cut next to this
//!   node) with no frame on its bus since: a frame its reader hands over later but that was on
//!   the bus before the no-ack (its receive timestamp says so) is no such news. With no port
//!   proven, the transmit fan-out sends on both; and a failed port still
//!   carries the node's own heartbeats, one at a time (see
//!   [`crate::link::channel::active_active`]), so that peers hear at once that its bus works
//!   again.
//! - **Transmit stall** (active-active, drivers that report transmit outcomes). A frame that
//!   reaches the receivers more than the skew window after its twin on the other bus is not
//!   matched with it, i.e. arrives as a duplicate. So when the other port has sent the twin of
//!   this port's oldest waiting frame, or a later frame (the layer numbers its logical frames:
//!   a SYNC and the heartbeat due with it are handed over in the same instant), and this port
//!   still has no outcome for it `tx_stall` later (the window less a frame's time on the
//!   bus: a copy let go then still reaches the receivers within the window of its twin), the
//!   port is re-initialised at once (flushing its queue) and failed. Receiving says nothing of its transmitter (a
//!   babbling controller fills its bus with frames; a controller that sends late hears the
//!   network fine), so such a port comes back when a frame it was handed is confirmed in time
//!   (the node's heartbeat, which goes there as a probe, one at a time, and is judged by the
//!   same rule: late, it is flushed and the port stays failed without a new event) or through
//!   re-initialisation. Waiting alone is no stall:
//!   a low-priority frame can lose arbitration for longer than the window on a busy network,
//!   and then it waits on both buses alike and its twins still match. Nor is a port judged
//!   while the other port sends nothing (failed, or its driver never confirms): without a twin
//!   there is no duplicate. A port is judged once either port's driver has confirmed a
//!   transmission (both ports have the same kind of driver; a port held by a babble from the
//!   start never confirms one). A port failed for silence is judged too: the heartbeat it
//!   carries as a probe waits behind a babble that began while the port sent nothing, and is
//!   flushed like any frame (the port then counts as failed for the stall).
//! - **Trust.** A failed or recovering port, while the other port is ok or suspect, is not
//!   proven yet for delivery: the merger delivers its copies only where the other port has not
//!   already passed their time (see [`crate::link::merge`]). A repaired segment can first flush
//!   frames that were queued before the fault; the other port delivers every occurrence
//!   meanwhile, so they are dropped, and when the other port fails the instant this one
//!   returns, its first frames are delivered.
//! - **Intact.** Since when frames on a port's bus have reached it, as far as its health
//!   knows: since it was last ok after being failed, recovering, or suspect for anything but
//!   a lag (for silence: with receive timestamps only). A lag sample across a port's return
//!   is no lag (see [`crate::link::lag`]).
//! - **Lag.** A port whose copies come later than the other port's by more than the maximum
//!   skew window even after the correction (measured by [`crate::link::lag`]) is suspect for
//!   that (reason `Lag`), and not ok again on traffic until its lag is within the maximum
//!   (reason `LagWithin`).

mod config;
mod port;
mod timers;

pub use config::{cause_index, HealthConfig, HealthCounters, ERROR_CAUSES};
pub use port::{PortHealth, PortState};

use port::{is_fatal, Condition, Handed};

use crate::link::events::{LinkEvent, LinkEventKind, PortReason};
use crate::link::outbox::Outbox;
use duocan_core::machine::{ErrorCause, PortStatus};
use duocan_core::{Duration, Instant};

/// The health of both ports.
#[derive(Clone, Debug)]
pub struct Health {
    cfg: HealthConfig,
    window: Duration,
    ports: [PortHealth; 2],
    /// State changes so far (wrapping): lets the layer follow them without asking per frame.
    changes: u32,
}

impl Health {
    /// Both ports ok. `window` is the merger's skew window: the time a twin may take.
    #[must_use]
    pub fn new(cfg: HealthConfig, window: Duration) -> Self {
        Health {
            cfg,
            window,
            ports: [PortHealth::new(&cfg), PortHealth::new(&cfg)],
            changes: 0,
        }
    }
    /// How many state changes there have been (wrapping): a different number means a port
    /// changed state.
    #[inline]
    pub fn changes(&self) -> u32 {
        self.changes
    }
    /// The configuration.
    pub fn config(&self) -> &HealthConfig {
        &self.cfg
    }
    /// One port (0 or 1; anything else reads port 1).
    #[inline]
    pub fn port(&self, p: usize) -> &PortHealth {
        &self.ports[p.min(1)]
    }
    /// True if frames from `p` may be delivered: `p` is ok or suspect, or the other port is not.
    pub fn trusted(&self, p: usize) -> bool {
        self.ports[p].state().is_trusted() || !self.ports[1 - p].state().is_trusted()
    }
    /// True if transmissions may go to `p` (not failed).
    pub fn usable(&self, p: usize) -> bool {
        self.ports[p].state() != PortState::Failed
    }

    /// The caller's clock stepped back `by` (the clock contract, see [`crate::link`]): every
    /// time held moves back with it, counters' last times included.
    pub(crate) fn step_back(&mut self, by: Duration) {
        for port in &mut self.ports {
            port.step_back(by);
        }
    }

    /// The merge window changed (a lagging port): the time a twin may take.
    pub(crate) fn set_window(&mut self, window: Duration) {
        self.window = window;
    }

    /// Port `p`, lagging `lag` behind the other one, lags beyond the maximum skew window
    /// (`beyond`) or not: an ok port becomes suspect, and one that was suspect for that alone is
    /// ok again when it ends. (A port suspect for errors stays so; the lag event says why.)
    pub(crate) fn set_lagging(
        &mut self,
        now: Instant,
        p: usize,
        lag: Duration,
        beyond: bool,
        out: &mut Outbox,
    ) {
        let port = &mut self.ports[p];
        match (port.lagging, beyond) {
            (None, true) => {
                port.lagging = Some(lag);
                if port.cond == Condition::Ok {
                    self.set(now, p, PortState::Suspect, PortReason::Lag { lag }, out);
                }
            }
            (Some(_), false) => {
                port.lagging = None;
                let held = port
                    .last_error
                    .is_some_and(|e| now.saturating_since(e) < self.cfg.error_hold);
                if port.cond == Condition::Suspect && !held {
                    self.set(now, p, PortState::Ok, PortReason::LagWithin { lag }, out);
                }
            }
            _ => {}
        }
    }

    /// Port `p`'s last frame was handed over `delay` after its receive timestamp: its twins
    /// take that much longer (see the silence rule).
    pub(crate) fn rx_delay(&mut self, p: usize, delay: Duration) {
        self.ports[p].rx_delay = delay;
    }

    /// A copy of the layer's logical frame number `seq` was handed to port `p` at `now`.
    pub(crate) fn count_tx(&mut self, now: Instant, p: usize, seq: u32) {
        let port = &mut self.ports[p];
        port.counters.tx += 1;
        let moved = port.outstanding.is_empty() || port.outstanding.is_full();
        if port.outstanding.is_full() {
            port.outstanding.pop_front();
        }
        let _ = port.outstanding.push_back(Handed { at: now, seq });
        if moved {
            self.front_moved(now, p);
        }
    }

    /// Port `p`'s oldest waiting frame is another one: the stall rule's reference starts over,
    /// if the other port already sent this frame's twin or a later frame, from the instant the
    /// other port confirmed the twin (or, the twin further back than its last confirmations,
    /// the earliest of them: a bound never early; without the `stall-log` feature, from its
    /// last confirmation, a bound never early either, but later). (From now, a frame that waited behind
    /// earlier ones got the whole stall time again when they went out: a heartbeat after a
    /// boot-up came 5.3 ms after its twin, past the window, and was delivered twice. From the
    /// other port's last confirmation, a frame that waited behind retransmissions on a noisy
    /// bus got the time since its twin over again: an SDO request 5 ms after its twin, twice.)
    fn front_moved(&mut self, now: Instant, p: usize) {
        let [a, b] = &mut self.ports;
        let (port, other) = if p == 0 { (a, &*b) } else { (b, &*a) };
        port.overtaken = match (port.outstanding.front(), other.last_sent) {
            (Some(f), Some(s)) if f.no_later_than(s) => {
                #[cfg(feature = "stall-log")]
                let twin = f.twin_confirmed(&other.confirmations);
                #[cfg(not(feature = "stall-log"))]
                let twin = None;
                Some(twin.or(other.confirmed).unwrap_or(now))
            }
            _ => None,
        };
    }

    /// Port `p` confirmed a frame: the other port's oldest waiting frame, if it is that
    /// frame's twin or an earlier frame, is overtaken now (ports send in the order they were
    /// given, so a frame sent means every earlier one was). The frames are told apart by their
    /// number, not their hand-over time: a SYNC and the heartbeat due with it are handed over
    /// in the same instant. (By time, the rule waited for a frame handed over later, a cycle
    /// on; the frames waiting behind a babble that long came out later than the window when
    /// it ended.)
    fn sent(&mut self, now: Instant, p: usize, handed: Handed) {
        let port = &mut self.ports[p];
        port.last_sent = Some(handed);
        #[cfg(feature = "stall-log")]
        {
            if port.confirmations.is_full() {
                port.confirmations.pop_front();
            }
            let _ = port.confirmations.push_back(Handed {
                at: now,
                seq: handed.seq,
            });
        }
        let other = &mut self.ports[1 - p];
        if other.overtaken.is_none()
            && other
                .outstanding
                .front()
                .is_some_and(|f| f.no_later_than(handed))
        {
            other.overtaken = Some(now);
        }
    }

    /// Forgets port `p`'s waiting frames (flushed or gone with the interface).
    fn flushed(&mut self, p: usize) {
        let port = &mut self.ports[p];
        port.outstanding.clear();
        port.overtaken = None;
    }

    /// A frame arrived on `p` at `now`, on its bus at `at` (its receive timestamp); `outcome`:
    /// what the merge made of it.
    pub(crate) fn on_rx(
        &mut self,
        now: Instant,
        at: Instant,
        p: usize,
        outcome: RxOutcome,
        out: &mut Outbox,
    ) {
        let o = 1 - p;
        {
            let c = &mut self.ports[p].counters;
            c.rx += 1;
            c.last_rx = Some(now);
            match outcome {
                RxOutcome::Delivered | RxOutcome::Direct | RxOutcome::Slipped => c.delivered += 1,
                RxOutcome::Duplicate => c.duplicates += 1,
                RxOutcome::Stale => c.stale += 1,
                RxOutcome::Ignored => {}
            }
        }
        let port = &mut self.ports[p];
        port.silence_ref = Some(now);
        port.first_missed = None;
        port.last_missed = None;
        // A frame from before the unacknowledged transmission says nothing of the bus now.
        port.unacknowledged &= at < port.unacknowledged_at;
        if outcome == RxOutcome::Delivered {
            let other = &mut self.ports[o];
            other.first_missed.get_or_insert(now);
            other.last_missed = Some(now);
            // Observation of the other port starts with the first traffic seen at all.
            other.silence_ref.get_or_insert(now);
        }
        let port = &mut self.ports[p];
        match &mut port.cond {
            Condition::Ok => {}
            Condition::Suspect => {
                if port.lagging.is_none()
                    && port
                        .last_error
                        .is_none_or(|e| now.saturating_since(e) >= self.cfg.error_hold)
                {
                    self.set(now, p, PortState::Ok, PortReason::Traffic, out);
                }
            }
            // Not after a transmit stall: receiving tells nothing of a transmitter (a slow
            // controller hears the network fine; a babble floods its bus with frames). Its
            // probes, or its re-initialisation, test it (see `on_status`).
            Condition::Failed { revive_on_rx, .. } if *revive_on_rx => {
                self.set(now, p, PortState::Recovering, PortReason::Traffic, out);
                self.ports[p].cond = Condition::Recovering {
                    probation_from: Some(now),
                };
                self.end_probation(now, p, out);
            }
            Condition::Failed { .. } => {}
            Condition::Recovering { probation_from } => {
                probation_from.get_or_insert(now);
                self.end_probation(now, p, out);
            }
        }
    }

    fn end_probation(&mut self, now: Instant, p: usize, out: &mut Outbox) {
        if let Condition::Recovering {
            probation_from: Some(from),
        } = self.ports[p].cond
        {
            if now.saturating_since(from) >= self.cfg.probation && !self.ports[p].tx_unproven {
                // Back, but still lagging beyond the maximum: suspect for that.
                match self.ports[p].lagging {
                    Some(lag) => self.set(now, p, PortState::Suspect, PortReason::Lag { lag }, out),
                    None => self.set(now, p, PortState::Ok, PortReason::Traffic, out),
                }
            }
        }
    }

    /// The driver of `p` reports something.
    pub(crate) fn on_status(
        &mut self,
        now: Instant,
        p: usize,
        status: PortStatus,
        out: &mut Outbox,
    ) {
        let port = &mut self.ports[p];
        match status {
            PortStatus::TxOk => {
                port.counters.tx_ok += 1;
                port.reports_outcomes = true;
                port.confirmed = Some(now);
                port.unacknowledged = false;
                port.tx_unproven = false;
                // Someone on its bus acknowledged the frame: the bus works again, whatever the
                // back-off says (as a received frame shows). After a transmit stall, a frame
                // it was handed (a probe) confirmed before the stall rule flushed it: its
                // transmitter keeps time again.
                if port.revives_on_traffic() || (port.stalled() && !port.outstanding.is_empty()) {
                    self.set(now, p, PortState::Recovering, PortReason::Traffic, out);
                }
                let port = &mut self.ports[p];
                if let Some(handed) = port.outstanding.pop_front() {
                    self.front_moved(now, p);
                    self.sent(now, p, handed);
                }
            }
            PortStatus::TxFailed(c) => {
                port.counters.tx_failed += 1;
                // Failures alone do not arm the stall check: a driver that never confirms a
                // success (embedded-can has no way to) would look stalled after every failure.
                if c == ErrorCause::TxTimeout {
                    // Refused at hand-over (queue full): the newest frame.
                    port.outstanding.pop_back();
                    if port.outstanding.is_empty() {
                        self.front_moved(now, p);
                    }
                } else if port.outstanding.pop_front().is_some() {
                    self.front_moved(now, p);
                }
                self.error(now, p, c, PortReason::TxFailed(c), out);
            }
            PortStatus::Error(ErrorCause::Restarted) => {
                port.counters.errors[cause_index(ErrorCause::Restarted)] =
                    port.counters.errors[cause_index(ErrorCause::Restarted)].saturating_add(1);
                if port.revives_on_traffic() {
                    self.set(
                        now,
                        p,
                        PortState::Recovering,
                        PortReason::Controller(ErrorCause::Restarted),
                        out,
                    );
                }
            }
            PortStatus::Error(c) => self.error(now, p, c, PortReason::Controller(c), out),
            PortStatus::Down(c) => {
                self.flushed(p);
                self.count(now, p, c);
                self.fail(now, p, PortReason::Down(c), c == ErrorCause::BusOff, out);
            }
            PortStatus::Up => {
                // After a transmit stall the driver's "up" answers the flush, not the cause.
                if port.revives_on_traffic() {
                    self.set(now, p, PortState::Recovering, PortReason::Up, out);
                }
            }
        }
    }

    fn error(
        &mut self,
        now: Instant,
        p: usize,
        c: ErrorCause,
        reason: PortReason,
        out: &mut Outbox,
    ) {
        self.count(now, p, c);
        let port = &mut self.ports[p];
        if c == ErrorCause::NoAck {
            port.unacknowledged = true;
            port.unacknowledged_at = now;
        }
        if is_fatal(c) {
            self.fail(now, p, reason, c == ErrorCause::BusOff, out);
        } else if port.cond == Condition::Ok {
            self.set(now, p, PortState::Suspect, reason, out);
        }
    }

    /// Counts the error `c` of port `p`.
    fn count(&mut self, now: Instant, p: usize, c: ErrorCause) {
        let port = &mut self.ports[p];
        let n = &mut port.counters.errors[cause_index(c)];
        *n = n.saturating_add(1);
        port.counters.last_error = Some((now, c));
        port.last_error = Some(now);
    }

    /// Fails port `p` for `reason` (`bus_off`: its controller's bus-off, however reported).
    fn fail(
        &mut self,
        now: Instant,
        p: usize,
        reason: PortReason,
        bus_off: bool,
        out: &mut Outbox,
    ) {
        // A bus-off again before the port was back (recovering, or failed for its transmitter
        // already): the controller's restart and its bus's frames proved nothing of its
        // transmitter (a transceiver that receives but cannot send goes bus-off within a
        // millisecond of every restart, and the port flapped between failed and recovering
        // at that pace).
        let state = self.ports[p].state();
        let again = bus_off && (state == PortState::Recovering || self.ports[p].stalled());
        if state != PortState::Failed {
            self.set(now, p, PortState::Failed, reason, out);
        }
        // The latest cause decides, also for a port that had failed already.
        if let Condition::Failed { revive_on_rx, .. } = &mut self.ports[p].cond {
            *revive_on_rx = !matches!(reason, PortReason::TxStalled { .. }) && !again;
        }
        // Any bus-off is its transmitter's (see the module documentation): received frames
        // prove its receiver only, so its probation waits for a transmission confirmed (a
        // transceiver that cannot send hears the network fine between its heartbeats, and
        // was back for a moment after every first bus-off).
        self.ports[p].tx_unproven |= bus_off && self.ports[p].reports_outcomes;
    }

    fn set(&mut self, at: Instant, p: usize, to: PortState, reason: PortReason, out: &mut Outbox) {
        let port = &mut self.ports[p];
        let from = port.state();
        if from == to {
            return;
        }
        self.changes = self.changes.wrapping_add(1);
        port.since = at;
        match to {
            PortState::Failed => port.lossy = true,
            PortState::Suspect
                if !matches!(reason, PortReason::Silence { .. } | PortReason::Lag { .. }) =>
            {
                port.lossy = true
            }
            PortState::Ok if port.lossy => {
                port.lossy = false;
                port.back = at;
            }
            _ => {}
        }
        // Intact: no state since `at` in which frames on its bus may not have reached it (a
        // silence counts, a lag does not).
        match to {
            PortState::Ok => {
                port.intact.get_or_insert(at);
            }
            PortState::Suspect if matches!(reason, PortReason::Lag { .. }) => {}
            _ => port.intact = None,
        }
        port.cond = match to {
            PortState::Ok => {
                port.attempt = 0;
                port.backoff = self.cfg.reinit_first;
                Condition::Ok
            }
            // `fail` settles whether traffic may revive it.
            PortState::Failed => Condition::Failed {
                reinit_at: at + port.backoff,
                revive_on_rx: true,
            },
            PortState::Recovering => {
                // Judged afresh: only frames it misses from now on count against it (in a quiet
                // network a stale miss from before the repair would fail it again and again).
                port.silence_ref = Some(at);
                port.first_missed = None;
                port.last_missed = None;
                Condition::Recovering {
                    probation_from: None,
                }
            }
            PortState::Suspect => Condition::Suspect,
        };
        if to == PortState::Failed {
            // What this port heard no longer says anything about the other one.
            let other = &mut self.ports[1 - p];
            other.first_missed = None;
            other.last_missed = None;
            other.silence_ref = None;
        }
        out.event(LinkEvent {
            at,
            kind: LinkEventKind::Port {
                port: p as u8,
                from,
                to,
                reason,
            },
        });
    }
}

/// What became of a received frame, for the counters and the silence rule.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum RxOutcome {
    /// First copy, delivered: its twin is due on the other port.
    Delivered,
    /// Twin of a delivered frame.
    Duplicate,
    /// Dropped without a twin: older than the merger remembers, or, from a port not proven
    /// yet, at a time the other port has already passed (it delivered that time's frames).
    Stale,
    /// Delivered, although a late copy of the other port was pending: a lagging twin not yet
    /// known as such, or a repeat of a frame the other port missed, whose own copy comes after.
    /// Either way the other port has its copy: nothing missed.
    Slipped,
    /// Delivered without merging (single active channel): no twin expected.
    Direct,
    /// Not for the application (inactive channel, link-layer frame).
    Ignored,
}

#[cfg(test)]
mod tests;
