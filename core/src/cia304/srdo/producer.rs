//! The SRDO producer: the same data twice, plain on the normal identifier and bitwise inverted on
//! the next one, every refresh time.
//!
//! **The rule.** Entering operational starts the producer; its first pair leaves after a delay
//! the caller gives (CANopenNode staggers producers by node-ID × 0.5 ms so that a whole network
//! entering operational at once does not collide), then one pair per refresh time on a fixed
//! grid. A [`request`](SrdoProducer::request) sends the next pair at once and restarts the grid
//! from there. Both frames of a pair leave in the same call, normal first, so the inverted one
//! follows within the bus time of one frame, well inside any SRVT.
//!
//! **What it checks.** The producer never sends what its consumers would reject: the inverted
//! data comes from the objects the mapping names for it, and a pair whose inverted half is not
//! the exact inverse of the normal one is not sent at all ([`SrdoProducer::frames`] says
//! `None`). The consumers then reach their safe state within their SCT: a producer that cannot
//! vouch for its data falls silent rather than send it.
//!
//! **Memory.** Two identifiers, two times and a length: no buffer, nothing grows.

use crate::frame::instant::{next_on_grid, shift_back, Duration, Instant};
use crate::frame::{Frame, Id};

/// One SRDO producer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SrdoProducer {
    normal: u16,
    inverted: u16,
    refresh: Duration,
    len: u8,
    next: Option<Instant>,
    sent: u32,
}

impl SrdoProducer {
    /// A stopped producer of `len` bytes (at most 8) on the 11-bit identifiers `normal` and
    /// `inverted`, every `refresh`.
    #[must_use]
    pub const fn new(normal: u16, inverted: u16, refresh: Duration, len: u8) -> Self {
        SrdoProducer {
            normal,
            inverted,
            refresh,
            len: if len > 8 { 8 } else { len },
            next: None,
            sent: 0,
        }
    }
    /// Starts producing: the first pair is due at `now + delay`.
    pub fn start(&mut self, now: Instant, delay: Duration) {
        self.next = Some(now.saturating_add(delay));
    }
    /// Stops producing (leaving operational).
    pub fn stop(&mut self) {
        self.next = None;
    }
    /// True while producing.
    #[must_use]
    pub const fn is_running(&self) -> bool {
        self.next.is_some()
    }
    /// The next pair is due at once (a changed value the application wants out before the
    /// refresh time). Ignored while stopped.
    pub fn request(&mut self, now: Instant) {
        if self.next.is_some() {
            self.next = Some(now);
        }
    }
    /// When the next pair is due.
    #[must_use]
    pub const fn poll_timeout(&self) -> Option<Instant> {
        self.next
    }
    /// True if a pair is due at `now`.
    #[must_use]
    pub fn is_due(&self, now: Instant) -> bool {
        self.next.is_some_and(|t| now >= t)
    }
    /// Pairs sent since creation.
    #[must_use]
    pub const fn sent(&self) -> u32 {
        self.sent
    }
    /// The two frames of one pair from the normal and inverted data, or `None` if the inverted
    /// data is not the exact bitwise inverse of the normal data over the SRDO's length.
    #[must_use]
    pub fn frames(&self, normal: &[u8; 8], inverted: &[u8; 8]) -> Option<(Frame, Frame)> {
        let n = self.len as usize;
        if normal[..n]
            .iter()
            .zip(&inverted[..n])
            .any(|(a, b)| !a != *b)
        {
            return None;
        }
        let a = Frame::new(Id::Standard(self.normal), &normal[..n]).ok()?;
        let b = Frame::new(Id::Standard(self.inverted), &inverted[..n]).ok()?;
        Some((a, b))
    }
    /// The pair due at `now` went out (or was withheld): the next one is due a refresh time
    /// after the grid point, skipping points already past.
    pub fn sent_at(&mut self, now: Instant, went_out: bool) {
        if let Some(due) = self.next {
            self.next = Some(next_on_grid(due, self.refresh, now));
            if went_out {
                self.sent = self.sent.wrapping_add(1);
            }
        }
    }
    /// The caller's clock stepped back `by`.
    pub fn step_back(&mut self, by: Duration) {
        shift_back(&mut self.next, by);
    }
}
