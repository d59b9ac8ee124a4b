//! One transmit PDO's timing: when it is sent, never how it is packed.
//!
//! Transmission types (CiA 301):
//! - 0: synchronous acyclic, sent at the SYNC after an event (a write to a mapped entry, an
//!   application request, an RTR);
//! - 1–240: sent at every n-th SYNC; with a SYNC start value and a SYNC counter, first sent at
//!   the SYNC whose counter equals the start value (as CANopenNode does), then every n-th;
//! - 252: sampled at SYNC, sent on RTR; 253: sampled and sent on RTR;
//! - 254/255: event-driven: sent on an event, at the latest when the event timer elapses (the
//!   timer restarts at every transmission), never sooner than the inhibit time after the
//!   previous transmission (an event during the inhibit time is sent when it ends). Times count
//!   from the instant the frame is queued for the bus, as CANopenNode counts them.
//!
//! Entering operational counts as an event for 254/255, so the current values go out at once.

use super::mapping::Mapping;
use crate::frame::instant::{earliest, shift_back, Duration, Instant};
use crate::frame::Id;
use crate::od::abort::AbortCode;

/// What a SYNC asks of a TPDO.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum OnSync {
    Nothing,
    /// Pack and send now.
    Send,
    /// Pack and keep for the next RTR (type 252).
    Sample,
}

/// What an RTR asks of a TPDO.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum OnRtr {
    Ignore,
    /// Send the payload sampled at the last SYNC (type 252).
    SendSampled,
    /// An event was recorded; the engine sends when the type and inhibit time allow.
    Event,
}

/// Parameters read from 0x18xx/0x1Axx.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct TpdoParams {
    pub id: Option<Id>,
    pub rtr_allowed: bool,
    pub ttype: u8,
    pub inhibit: Duration,
    pub event_timer: Duration,
    pub sync_start: u8,
    pub mapping: Mapping,
    /// Why the stored configuration cannot be used, if it cannot.
    pub error: Option<AbortCode>,
    /// An MPDO (mapping count 0xFE or 0xFF): sent by the application only, never by the engine.
    #[cfg(feature = "mpdo")]
    pub mpdo: Option<crate::cia301::mpdo::Mode>,
}

impl TpdoParams {
    /// Valid COB-ID, usable mapping with at least one entry.
    pub fn active(&self) -> bool {
        self.id.is_some() && self.error.is_none() && self.mapping.count() > 0
    }
    /// Writes to mapped entries and application requests mean something.
    pub fn event_capable(&self) -> bool {
        matches!(self.ttype, 0 | 254 | 255)
    }
}

/// A TPDO: parameters and run-time state.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Tpdo {
    pub p: TpdoParams,
    running: bool,
    event: bool,
    sync_left: u8,
    await_start: bool,
    last_sent: Option<Instant>,
    timer_due: Option<Instant>,
    pub sampled: Option<[u8; 8]>,
    pub sent: u32,
}

impl Tpdo {
    #[must_use]
    pub const fn new() -> Tpdo {
        Tpdo {
            p: TpdoParams {
                id: None,
                rtr_allowed: false,
                ttype: 0,
                inhibit: Duration::ZERO,
                event_timer: Duration::ZERO,
                sync_start: 0,
                mapping: Mapping::EMPTY,
                error: None,
                #[cfg(feature = "mpdo")]
                mpdo: None,
            },
            running: false,
            event: false,
            sync_left: 0,
            await_start: false,
            last_sent: None,
            timer_due: None,
            sampled: None,
            sent: 0,
        }
    }

    pub fn running(&self) -> bool {
        self.running
    }
    pub fn last_sent(&self) -> Option<Instant> {
        self.last_sent
    }

    /// (Re)starts transmission at `now` (entering operational, or the PDO became valid).
    pub fn start(&mut self, now: Instant) {
        self.running = self.p.active();
        let async_event = self.p.ttype >= 254;
        self.event = self.running && async_event;
        self.sync_left = self.p.ttype;
        self.await_start = self.p.sync_start > 0;
        self.sampled = None;
        self.timer_due = if self.running && async_event && !self.p.event_timer.is_zero() {
            Some(now + self.p.event_timer)
        } else {
            None
        };
    }

    /// Stops transmission (left operational, or the PDO became invalid).
    pub fn stop(&mut self) {
        self.running = false;
        self.event = false;
        self.timer_due = None;
        self.sampled = None;
    }

    /// Applies new timing parameters to a running PDO without restarting it (inhibit time,
    /// event timer): the event timer restarts from `now`.
    pub fn retime(&mut self, now: Instant, p: TpdoParams) {
        self.p = p;
        if self.running && p.ttype >= 254 {
            self.timer_due = (!p.event_timer.is_zero()).then(|| now + p.event_timer);
        }
    }

    /// An application event (mapped entry written, request). True if the engine should try to
    /// send now (asynchronous types); synchronous acyclic waits for SYNC.
    pub fn trigger(&mut self) -> bool {
        if !self.running {
            return false;
        }
        match self.p.ttype {
            0 => {
                self.event = true;
                false
            }
            254 | 255 => {
                self.event = true;
                true
            }
            _ => false,
        }
    }

    /// A remote request for this PDO arrived.
    pub fn rtr(&mut self) -> OnRtr {
        if !self.running || !self.p.rtr_allowed {
            return OnRtr::Ignore;
        }
        match self.p.ttype {
            252 => OnRtr::SendSampled,
            0 | 253..=255 => {
                self.event = true;
                OnRtr::Event
            }
            _ => OnRtr::Ignore,
        }
    }

    /// A SYNC with `counter` (when SYNC carries one).
    pub fn on_sync(&mut self, counter: Option<u8>) -> OnSync {
        if !self.running {
            return OnSync::Nothing;
        }
        match self.p.ttype {
            0 if self.event => {
                self.event = false;
                OnSync::Send
            }
            n @ 1..=240 => {
                if self.await_start {
                    match counter {
                        Some(c) if c == self.p.sync_start => {
                            self.await_start = false;
                            self.sync_left = n;
                            return OnSync::Send;
                        }
                        Some(_) => return OnSync::Nothing,
                        // No counter on this network: the start value does not apply.
                        None => self.await_start = false,
                    }
                }
                self.sync_left = self.sync_left.saturating_sub(1);
                if self.sync_left == 0 {
                    self.sync_left = n;
                    OnSync::Send
                } else {
                    OnSync::Nothing
                }
            }
            252 => OnSync::Sample,
            _ => OnSync::Nothing,
        }
    }

    /// Asynchronous types: should it be sent at `now`? Fires the event timer when due.
    pub fn due(&mut self, now: Instant) -> bool {
        if !self.running || self.p.ttype < 253 {
            return false;
        }
        if self.timer_due.is_some_and(|t| t <= now) {
            self.timer_due = None;
            self.event = true;
        }
        self.event && self.inhibit_over(now)
    }

    fn inhibit_over(&self, now: Instant) -> bool {
        self.last_sent.is_none_or(|l| now >= l + self.p.inhibit)
    }

    /// The caller's clock stepped back `by` (the clock contract, [`crate::frame::instant`]).
    pub fn step_back(&mut self, by: Duration) {
        shift_back(&mut self.last_sent, by);
        shift_back(&mut self.timer_due, by);
    }

    /// It was sent at `now`.
    pub fn sent(&mut self, now: Instant) {
        self.last_sent = Some(now);
        self.event = false;
        self.sent = self.sent.wrapping_add(1);
        if self.running && self.p.ttype >= 254 && !self.p.event_timer.is_zero() {
            self.timer_due = Some(now + self.p.event_timer);
        }
    }

    /// When [`Tpdo::due`] next has something to do.
    pub fn deadline(&self) -> Option<Instant> {
        if !self.running || self.p.ttype < 253 {
            return None;
        }
        let inhibit_end = if self.event {
            Some(self.last_sent.map_or(Instant::ZERO, |l| l + self.p.inhibit))
        } else {
            None
        };
        earliest(self.timer_due, inhibit_end)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cia301::pdo::mapping::MapEntry;

    fn tpdo(ttype: u8, inhibit_us: u64, timer_ms: u64, start: u8) -> Tpdo {
        let mut t = Tpdo::new();
        t.p = TpdoParams {
            id: Some(Id::Standard(0x181)),
            rtr_allowed: true,
            ttype,
            inhibit: Duration::from_micros(inhibit_us),
            event_timer: Duration::from_millis(timer_ms),
            sync_start: start,
            mapping: Mapping::with(&[MapEntry::new(0x2000, 0, 8)]),
            error: None,
            #[cfg(feature = "mpdo")]
            mpdo: None,
        };
        t
    }

    fn sends(t: &mut Tpdo, counters: impl IntoIterator<Item = Option<u8>>) -> Vec<usize> {
        counters
            .into_iter()
            .enumerate()
            .filter(|(_, c)| t.on_sync(*c) == OnSync::Send)
            .map(|(i, _)| i + 1)
            .collect()
    }

    #[test]
    fn every_nth_sync_counts_from_start() {
        let mut t = tpdo(3, 0, 0, 0);
        t.start(Instant::ZERO);
        assert_eq!(sends(&mut t, [None; 10]), [3, 6, 9]);
    }

    #[test]
    fn sync_start_value_waits_for_the_counter() {
        let mut t = tpdo(2, 0, 0, 4);
        t.start(Instant::ZERO);
        let counters = (1..=10u8).map(Some);
        assert_eq!(sends(&mut t, counters), [4, 6, 8, 10]);
        // Without a counter on the bus the start value is ignored.
        let mut t = tpdo(2, 0, 0, 4);
        t.start(Instant::ZERO);
        assert_eq!(sends(&mut t, [None; 5]), [2, 4]);
    }

    #[test]
    fn acyclic_sends_only_after_an_event() {
        let mut t = tpdo(0, 0, 0, 0);
        t.start(Instant::ZERO);
        assert_eq!(t.on_sync(None), OnSync::Nothing);
        assert!(!t.trigger(), "type 0 waits for SYNC");
        assert_eq!(t.on_sync(None), OnSync::Send);
        assert_eq!(t.on_sync(None), OnSync::Nothing);
    }

    #[test]
    fn inhibit_delays_and_event_timer_restarts_at_each_send() {
        let ms = Instant::from_millis;
        let mut t = tpdo(255, 10_000, 50, 0);
        t.start(ms(0));
        assert!(t.due(ms(0)), "entering operational is an event");
        t.sent(ms(0));
        assert!(t.trigger());
        assert!(!t.due(ms(4)));
        assert_eq!(t.deadline(), Some(ms(10)));
        assert!(t.due(ms(10)));
        t.sent(ms(10));
        assert_eq!(t.deadline(), Some(ms(60)));
        assert!(!t.due(ms(59)));
        assert!(t.due(ms(60)));
    }

    #[test]
    fn rtr_rules() {
        let mut t = tpdo(252, 0, 0, 0);
        t.start(Instant::ZERO);
        assert_eq!(t.on_sync(None), OnSync::Sample);
        assert_eq!(t.rtr(), OnRtr::SendSampled);
        let mut t = tpdo(253, 0, 0, 0);
        t.start(Instant::ZERO);
        assert!(!t.due(Instant::ZERO), "253 waits for RTR");
        assert_eq!(t.rtr(), OnRtr::Event);
        assert!(t.due(Instant::ZERO));
        t.p.rtr_allowed = false;
        assert_eq!(t.rtr(), OnRtr::Ignore);
        let mut t = tpdo(5, 0, 0, 0);
        t.start(Instant::ZERO);
        assert_eq!(t.rtr(), OnRtr::Ignore);
    }
}
