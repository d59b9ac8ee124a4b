//! Progress of a long transfer (a domain, a firmware image): a bar with throughput on a
//! terminal, and plain lines in a log (one per tenth done), so that a CI log shows how a
//! 1 MiB transfer went. Short transfers (under [`SHOW_FROM`] bytes) show nothing.

use duocan::net::TransferProgress;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;
use std::time::Instant;

/// Transfers shorter than this show no progress.
pub const SHOW_FROM: u64 = 16 * 1024;

/// The progress of one transfer.
pub struct Progress {
    label: String,
    start: Instant,
    bar: Option<ProgressBar>,
    /// Plain lines: the last tenth printed.
    tenth: Option<u64>,
    quiet: bool,
    done: u64,
}

impl Progress {
    /// Progress of the transfer `label`; nothing is shown when `quiet`.
    pub fn new(label: impl Into<String>, quiet: bool) -> Progress {
        Progress {
            label: label.into(),
            start: Instant::now(),
            bar: None,
            tenth: None,
            quiet,
            done: 0,
        }
    }

    /// Bytes per second so far.
    fn rate(&self) -> f64 {
        let s = self.start.elapsed().as_secs_f64();
        if s > 0.0 {
            self.done as f64 / s
        } else {
            0.0
        }
    }

    /// What the transfer reported.
    pub fn update(&mut self, p: TransferProgress) {
        self.done = p.done;
        let big = p.total.unwrap_or(p.done) >= SHOW_FROM;
        if self.quiet || !big {
            return;
        }
        if std::io::stderr().is_terminal() {
            let bar = self.bar.get_or_insert_with(|| {
                let b = match p.total {
                    Some(t) => ProgressBar::new(t),
                    None => ProgressBar::new_spinner(),
                };
                b.set_draw_target(ProgressDrawTarget::stderr());
                let style = ProgressStyle::with_template(
                    "{msg} [{bar:30}] {binary_bytes}/{binary_total_bytes} {binary_bytes_per_sec} eta {eta}",
                )
                .unwrap_or_else(|_| ProgressStyle::default_bar())
                .progress_chars("=> ");
                b.set_style(style);
                b.set_message(self.label.clone());
                b
            });
            bar.set_position(p.done);
            return;
        }
        // A log: a line per tenth (or per 128 KiB when the size is unknown).
        let tenth = match p.total {
            Some(t) if t > 0 => p.done * 10 / t,
            _ => p.done / (128 * 1024),
        };
        if self.tenth != Some(tenth) {
            self.tenth = Some(tenth);
            let pct = p
                .total
                .filter(|t| *t > 0)
                .map(|t| format!(" ({}%)", p.done * 100 / t))
                .unwrap_or_default();
            let total = p.total.map(|t| format!("/{t}")).unwrap_or_default();
            eprintln!(
                "{}: {}{total} bytes{pct}, {:.1} KiB/s",
                self.label,
                p.done,
                self.rate() / 1024.0
            );
        }
    }

    /// The transfer ended: the bar is cleared; returns the summary ("1048576 bytes in 1.52 s,
    /// 673.7 KiB/s"), the throughput only for a long transfer.
    pub fn finish(self) -> String {
        if let Some(b) = &self.bar {
            b.finish_and_clear();
        }
        if self.done < SHOW_FROM {
            return format!("{} bytes", self.done);
        }
        format!(
            "{} bytes in {:.2} s, {:.1} KiB/s",
            self.done,
            self.start.elapsed().as_secs_f64(),
            self.rate() / 1024.0
        )
    }
}
