//! The clock contract's inputs, shared by the fuzz targets: a byte that stands for a misbehaving
//! clock becomes the next time (a step back, an hour ahead, the end of time); any other byte is
//! left to the target's own time step.

use duocan::{Duration, Instant};

/// The next time for `b` if it stands for a misbehaving clock.
pub fn misbehave(now: Instant, b: u8) -> Option<Instant> {
    match b {
        0xFF => Some(Instant::MAX),
        0xFE => Some(now + Duration::from_secs(3600)),
        0xF0..=0xFD => Some(now - Duration::from_millis(u64::from(b & 0x0F) * 100)),
        _ => None,
    }
}

/// A time well inside the clock's range, for the checks a target makes at its end ("long after
/// every timeout"): from the end of time the clock comes back.
pub fn sane(now: Instant) -> Instant {
    now.min(Instant::from_secs(1_000_000))
}
