//! The timeline as a real run applied it, and the scenario's times read on it.
//!
//! **The rule.** A scenario's times are the schedule; on real interfaces the bridge applies each
//! step a little late when the machine is loaded (a fault scheduled at 2,500 ms took effect at
//! 2,546 in the emulated VM), and what an expectation watches follows the step as applied. So
//! in a real run a moment `t` of the scenario is read as the same distance after the last step
//! scheduled at or before it, *as that step was applied*; and the end of a window as the same
//! distance before the next step as applied too, if that comes sooner. A window between two
//! steps thus keeps its margins to both ("from 10 ms after the partition to 10 ms before the
//! heal"), and a reaction timed from a step is timed from when it happened. In the simulator
//! every step is applied on time and nothing moves.
//!
//! The run writes its timeline next to its logs (`timeline`: a line per step, the scheduled
//! and the applied time in µs), so that `kit check` reads the logs the same way later.

use super::expect::{Expect, Trigger};
use std::path::Path;

/// Each step's scheduled and applied time (µs since the run started), in schedule order.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Timeline(Vec<(u64, u64)>);

/// The file a run writes its timeline to, in its log directory.
pub const FILE: &str = "timeline";

impl Timeline {
    /// A step scheduled at `scheduled` was applied at `applied` (steps in schedule order).
    pub fn push(&mut self, scheduled: u64, applied: u64) {
        self.0.push((scheduled, applied));
    }

    /// How late the step scheduled last at or before `t` was applied (0 if none).
    fn delay_at(&self, t: u64) -> u64 {
        self.0
            .iter()
            .rev()
            .find(|(s, _)| *s <= t)
            .map_or(0, |(s, a)| a.saturating_sub(*s))
    }

    /// How late the first step scheduled after `t` was applied, if there is one.
    fn delay_after(&self, t: u64) -> Option<u64> {
        self.0
            .iter()
            .find(|(s, _)| *s > t)
            .map(|(s, a)| a.saturating_sub(*s))
    }

    /// The moment `t` of the scenario as the run applied it (a window's start, a trigger).
    pub fn start(&self, t: u64) -> u64 {
        t + self.delay_at(t)
    }

    /// The end `t` of a window as the run applied it: never closer to the next step than the
    /// schedule had it.
    pub fn end(&self, t: u64) -> u64 {
        let d = self.delay_at(t);
        t + self.delay_after(t).map_or(d, |next| d.min(next))
    }

    /// `e` with its times read on this timeline.
    pub fn read(&self, e: &Expect) -> Expect {
        let mut e = e.clone();
        match &mut e {
            Expect::Within { after, .. } => match after {
                Trigger::At(t) => *t = self.start(*t),
                Trigger::Last { from, .. } => *from = self.start(*from),
            },
            Expect::MaxGap { from, to, .. } | Expect::Never { from, to, .. } => {
                *from = self.start(*from);
                *to = to.map(|t| self.end(t));
            }
            Expect::NoDuplicate { .. } => {}
        }
        e
    }

    /// The timeline as a run writes it.
    pub fn write(&self, dir: &Path) -> std::io::Result<()> {
        let text: String = self.0.iter().map(|(s, a)| format!("{s} {a}\n")).collect();
        std::fs::write(dir.join(FILE), text)
    }

    /// The timeline a run wrote in `dir`; none (the schedule as it is) if it wrote none.
    pub fn read_from(dir: &Path) -> Result<Timeline, String> {
        let path = dir.join(FILE);
        let Ok(text) = std::fs::read_to_string(&path) else {
            return Ok(Timeline::default());
        };
        let mut t = Timeline::default();
        for (i, line) in text.lines().enumerate() {
            let mut w = line.split_whitespace().map(str::parse::<u64>);
            match (w.next(), w.next(), w.next()) {
                (Some(Ok(s)), Some(Ok(a)), None) => t.push(s, a),
                _ => {
                    return Err(format!(
                        "{} line {}: not two numbers of µs (scheduled, applied): {line:?}",
                        path.display(),
                        i + 1
                    ))
                }
            }
        }
        Ok(t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cmd::kit::expect::Match;

    /// The partition scenario as the VM ran it: split scheduled at 2,500 ms and applied 46 ms
    /// late, healed at 3,500 and applied 2 ms late.
    fn vm() -> Timeline {
        let mut t = Timeline::default();
        t.push(1_000_000, 1_020_000);
        t.push(2_500_000, 2_546_000);
        t.push(3_500_000, 3_502_000);
        t
    }

    #[test]
    fn a_window_between_two_steps_keeps_its_margins_to_both_as_applied() {
        let t = vm();
        // "From 10 ms after the split": 10 ms after it took effect.
        assert_eq!(t.start(2_510_000), 2_556_000);
        // "To 10 ms before the heal": the heal came only 2 ms late, so 10 ms before it still.
        assert_eq!(t.end(3_490_000), 3_492_000);
        // Before any step, and after the last: as scheduled, then as late as the last one.
        assert_eq!(t.start(500_000), 500_000);
        assert_eq!(t.end(4_000_000), 4_002_000);
        let never = Expect::Never {
            frames: Match::default(),
            on: vec!["vm1a".into()],
            from: 2_510_000,
            to: Some(3_490_000),
        };
        let Expect::Never { from, to, .. } = t.read(&never) else {
            unreachable!()
        };
        assert_eq!((from, to), (2_556_000, Some(3_492_000)));
        let at = Expect::Within {
            after: Trigger::At(2_500_000),
            then: Match::default(),
            on: vec![],
            within: 1,
        };
        assert!(matches!(
            t.read(&at),
            Expect::Within {
                after: Trigger::At(2_546_000),
                ..
            }
        ));
    }

    #[test]
    fn on_time_nothing_moves_and_the_file_reads_back() {
        let mut on_time = Timeline::default();
        on_time.push(2_500_000, 2_500_000);
        assert_eq!(on_time.start(2_510_000), 2_510_000);
        assert_eq!(Timeline::default().end(7), 7);
        let dir = std::env::temp_dir().join(format!("duocan-timeline-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        vm().write(&dir).unwrap();
        assert_eq!(Timeline::read_from(&dir).unwrap(), vm());
        std::fs::write(dir.join(FILE), "2500000 x\n").unwrap();
        let e = Timeline::read_from(&dir).unwrap_err();
        assert!(e.contains("line 1") && e.contains("2500000 x"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
        let none = std::env::temp_dir().join("duocan-no-such-run");
        assert_eq!(Timeline::read_from(&none).unwrap(), Timeline::default());
    }
}
