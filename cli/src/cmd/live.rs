//! Watching the wire for `dump` (no file) and `record`: a tap on the network's ports that hands
//! each frame over, and the end of a run (`--count N` frames, `--duration S`, or Ctrl-C).

use duocan::capture::recorder::{Tap, TapDirection, TapPoint};
use duocan::{Frame, Instant};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, SystemTime, UNIX_EPOCH};
use tokio::sync::mpsc;

/// Longest `--duration` accepted, in seconds (a week).
pub const MAX_SECONDS: f64 = 7.0 * 24.0 * 3600.0;

/// Frames waiting to be printed before the tap drops (and counts) the next ones: a terminal
/// slower than the bus loses lines, never the network's time.
pub const QUEUE: usize = 16 * 1024;

/// `--duration`: seconds, decimal (`2`, `0.5`, `1.25`), more than 0 and at most a week.
pub fn parse_seconds(s: &str) -> Result<Duration, String> {
    let (int, frac) = s.split_once('.').unwrap_or((s, ""));
    let digits = |t: &str| t.chars().all(|c| c.is_ascii_digit());
    if int.is_empty() && frac.is_empty() || !digits(int) || !digits(frac) || frac.len() > 6 {
        return Err(format!(
            "duration {s:?}: give seconds, such as 10 or 0.5 (at most 6 decimals)"
        ));
    }
    let secs: f64 = s
        .parse()
        .map_err(|_| format!("duration {s:?}: not a number of seconds"))?;
    if secs <= 0.0 || secs > MAX_SECONDS {
        return Err(format!(
            "duration {s} s: give more than 0 and at most {MAX_SECONDS} (a week)"
        ));
    }
    Ok(Duration::from_secs_f64(secs))
}

/// Microseconds since the Unix epoch, now.
pub fn wall_clock_us() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| u64::try_from(d.as_micros()).unwrap_or(u64::MAX))
}

/// A frame seen on a port.
pub struct Seen {
    /// Microseconds since the Unix epoch.
    pub timestamp_us: u64,
    /// The port (0: bus 1).
    pub port: usize,
    /// The frame.
    pub frame: Frame,
}

/// The tap that hands frames to the printing loop.
pub struct Feed {
    tx: mpsc::Sender<Seen>,
    epoch_us: u64,
    dropped: AtomicU64,
}

impl Feed {
    /// A feed and the receiving end; its instant zero is now on the wall clock.
    pub fn new() -> (Arc<Feed>, mpsc::Receiver<Seen>) {
        let (tx, rx) = mpsc::channel(QUEUE);
        let feed = Feed {
            tx,
            epoch_us: wall_clock_us(),
            dropped: AtomicU64::new(0),
        };
        (Arc::new(feed), rx)
    }
    /// Frames dropped because the printing loop fell behind.
    pub fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }
}

impl Tap for Feed {
    fn frame(&self, at: Instant, point: TapPoint, _dir: TapDirection, frame: &Frame) {
        let TapPoint::Port(port) = point else {
            return;
        };
        let seen = Seen {
            timestamp_us: self.epoch_us.saturating_add(at.as_micros()),
            port,
            frame: *frame,
        };
        if self.tx.try_send(seen).is_err() {
            self.dropped.fetch_add(1, Ordering::Relaxed);
        }
    }
}

/// Why a run ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum End {
    /// `--duration` passed.
    Duration,
    /// Ctrl-C.
    Interrupted,
    /// The network closed.
    Closed,
}

/// Waits for `f` (a frame, a count reached) until `--duration` or Ctrl-C.
pub async fn until<T>(
    deadline: Option<tokio::time::Instant>,
    f: impl std::future::Future<Output = Option<T>>,
) -> Result<T, End> {
    let sleep = async {
        match deadline {
            Some(d) => tokio::time::sleep_until(d).await,
            None => std::future::pending().await,
        }
    };
    tokio::select! {
        v = f => v.ok_or(End::Closed),
        () = sleep => Err(End::Duration),
        _ = tokio::signal::ctrl_c() => Err(End::Interrupted),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn durations_are_seconds_strictly() {
        assert_eq!(parse_seconds("2"), Ok(Duration::from_secs(2)));
        assert_eq!(parse_seconds("0.5"), Ok(Duration::from_millis(500)));
        assert_eq!(parse_seconds("1.25"), Ok(Duration::from_millis(1250)));
        for bad in [
            "", ".", "0", "0.0", "-1", "+1", "1e3", "1.2.3", "inf", "nan", " 1", "1s",
        ] {
            assert!(parse_seconds(bad).is_err(), "{bad:?}");
        }
        assert!(parse_seconds("604801").unwrap_err().contains("a week"));
    }

    proptest! {
        #[test]
        fn any_duration_text_parses_or_is_refused(s in ".{0,24}") {
            if let Ok(d) = parse_seconds(&s) {
                prop_assert!(d > Duration::ZERO && d.as_secs_f64() <= MAX_SECONDS);
            }
        }
    }
}
