//! Expectations of a failover scenario, measured on the wires the run recorded.
//!
//! A *wire* is what one interface carried (a member's candump log: what its device sent and
//! what it was sent) or what one bus carried (every frame the bridge took from that bus's
//! members); both are a list of `(µs since the run started, frame)` in the order they were
//! logged. Each [`Expect`] names the wires it looks at and gives an [`Outcome`]: the figure it
//! measured ("38.21 ms on vs1b, 38.40 ms on vs2b") and whether it passed. Nothing is sampled
//! or estimated: the figures are differences of logged timestamps.

use duocan::{Frame, Id};
use std::collections::BTreeMap;
use std::fmt::Write;

/// Which frames an expectation is about.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Match {
    /// The identifier (11- or 29-bit), if only one.
    pub id: Option<u32>,
    /// The data must start with these bytes.
    pub data: Vec<u8>,
}

impl Match {
    /// True if `f` is one of these frames.
    pub fn matches(&self, f: &Frame) -> bool {
        let id = match f.id() {
            Id::Standard(i) => u32::from(i),
            Id::Extended(i) => i,
        };
        self.id.is_none_or(|want| want == id) && f.data().starts_with(&self.data)
    }
}

/// When a reaction is measured from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Trigger {
    /// A fixed time of the run (a fault's `at`), µs.
    At(u64),
    /// The last frame matching `frames` on wire `on` at or after `from` µs.
    Last {
        /// The frames.
        frames: Match,
        /// The wire.
        on: String,
        /// Ignore frames before this (µs).
        from: u64,
    },
}

/// One expectation.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Expect {
    /// After `after`, a frame matching `then` appears on every wire of `on` within `within` µs.
    Within {
        /// The trigger.
        after: Trigger,
        /// The awaited frame.
        then: Match,
        /// The wires it must appear on.
        on: Vec<String>,
        /// The bound, µs.
        within: u64,
    },
    /// Between `from` and `to` µs, no gap between consecutive frames matching `frames` on each
    /// wire of `on` (nor from `from` to the first, nor from the last to `to`) exceeds `max` µs.
    MaxGap {
        /// The frames.
        frames: Match,
        /// The wires.
        on: Vec<String>,
        /// The bound, µs.
        max: u64,
        /// Start of the window, µs.
        from: u64,
        /// End of the window, µs (`None`: the end of the run).
        to: Option<u64>,
    },
    /// No frame matching `frames` appears twice: with `from` (the sender's own wire), no wire
    /// of `on` carries more of them than `from` does (each frame sent arrives at most once);
    /// without, no two identical ones arrive within `window` µs.
    NoDuplicate {
        /// The frames.
        frames: Match,
        /// The wires.
        on: Vec<String>,
        /// The window, µs.
        window: u64,
        /// The sender's wire, if compared with it.
        from: Option<String>,
    },
    /// No frame matching `frames` on any wire of `on` between `from` and `to` µs.
    Never {
        /// The frames.
        frames: Match,
        /// The wires.
        on: Vec<String>,
        /// Start of the window, µs.
        from: u64,
        /// End of the window, µs (`None`: the end of the run).
        to: Option<u64>,
    },
}

/// What an expectation measured.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Outcome {
    /// Passed.
    pub pass: bool,
    /// The figure(s), per wire.
    pub measured: String,
}

/// The recorded wires by name, each in log order.
pub type Wires = BTreeMap<String, Vec<(u64, Frame)>>;

fn ms(us: u64) -> String {
    format!("{}.{:02} ms", us / 1000, (us % 1000) / 10)
}

fn wire<'a>(w: &'a Wires, name: &str) -> Result<&'a [(u64, Frame)], String> {
    w.get(name)
        .map(Vec::as_slice)
        .ok_or_else(|| format!("no wire named {name:?} was recorded"))
}

/// Measures `e` on `wires`, the run having lasted `end` µs.
pub fn measure(e: &Expect, wires: &Wires, end: u64) -> Result<Outcome, String> {
    let mut text = String::new();
    let mut pass = true;
    match e {
        Expect::Within {
            after,
            then,
            on,
            within,
        } => {
            let t0 = match after {
                Trigger::At(t) => *t,
                Trigger::Last { frames, on, from } => {
                    match wire(wires, on)?
                        .iter()
                        .rev()
                        .find(|(t, f)| *t >= *from && frames.matches(f))
                    {
                        Some((t, _)) => *t,
                        None => {
                            return Ok(Outcome {
                                pass: false,
                                measured: format!("the trigger frame never appeared on {on}"),
                            })
                        }
                    }
                }
            };
            let _ = write!(text, "from {}: ", ms(t0));
            for (i, name) in on.iter().enumerate() {
                let sep = if i == 0 { "" } else { ", " };
                match wire(wires, name)?
                    .iter()
                    .find(|(t, f)| *t >= t0 && then.matches(f))
                {
                    Some((t, _)) => {
                        let d = t - t0;
                        pass &= d <= *within;
                        let _ = write!(text, "{sep}{} on {name}", ms(d));
                    }
                    None => {
                        pass = false;
                        let _ = write!(text, "{sep}never on {name}");
                    }
                }
            }
        }
        Expect::MaxGap {
            frames,
            on,
            max,
            from,
            to,
        } => {
            let to = to.unwrap_or(end);
            for (i, name) in on.iter().enumerate() {
                let mut last = *from;
                let mut worst = (0u64, *from);
                for (t, _) in wire(wires, name)?
                    .iter()
                    .filter(|(t, f)| (*from..=to).contains(t) && frames.matches(f))
                {
                    if t - last > worst.0 {
                        worst = (t - last, last);
                    }
                    last = *t;
                }
                if to - last > worst.0 {
                    worst = (to - last, last);
                }
                pass &= worst.0 <= *max;
                let sep = if i == 0 { "" } else { ", " };
                let _ = write!(
                    text,
                    "{sep}longest gap {} on {name} (from {})",
                    ms(worst.0),
                    ms(worst.1)
                );
            }
        }
        Expect::NoDuplicate {
            frames,
            on,
            from: Some(from),
            ..
        } => {
            let sent = wire(wires, from)?
                .iter()
                .filter(|(_, f)| frames.matches(f))
                .count();
            let _ = write!(text, "{sent} sent on {from}: ");
            for (i, name) in on.iter().enumerate() {
                let got = wire(wires, name)?
                    .iter()
                    .filter(|(_, f)| frames.matches(f))
                    .count();
                pass &= got <= sent;
                let sep = if i == 0 { "" } else { ", " };
                let _ = write!(text, "{sep}{got} on {name}");
            }
        }
        Expect::NoDuplicate {
            frames,
            on,
            window,
            from: None,
        } => {
            for (i, name) in on.iter().enumerate() {
                let w: Vec<&(u64, Frame)> = wire(wires, name)?
                    .iter()
                    .filter(|(_, f)| frames.matches(f))
                    .collect();
                let mut twins = 0u64;
                let mut first = None;
                for (k, (t, f)) in w.iter().enumerate() {
                    let twin = w[..k]
                        .iter()
                        .rev()
                        .take_while(|(u, _)| t - u <= *window)
                        .any(|(_, g)| g == f);
                    if twin {
                        twins += 1;
                        first.get_or_insert(*t);
                    }
                }
                pass &= twins == 0;
                let sep = if i == 0 { "" } else { ", " };
                match first {
                    None => {
                        let _ = write!(text, "{sep}no twin on {name}");
                    }
                    Some(t) => {
                        let _ = write!(text, "{sep}{twins} twin(s) on {name}, first at {}", ms(t));
                    }
                }
            }
        }
        Expect::Never {
            frames,
            on,
            from,
            to,
        } => {
            let to = to.unwrap_or(end);
            for (i, name) in on.iter().enumerate() {
                let seen: Vec<u64> = wire(wires, name)?
                    .iter()
                    .filter(|(t, f)| (*from..=to).contains(t) && frames.matches(f))
                    .map(|(t, _)| *t)
                    .collect();
                pass &= seen.is_empty();
                let sep = if i == 0 { "" } else { ", " };
                match seen.first() {
                    None => {
                        let _ = write!(text, "{sep}none on {name}");
                    }
                    Some(t) => {
                        let _ = write!(text, "{sep}{} on {name}, first at {}", seen.len(), ms(*t));
                    }
                }
            }
        }
    }
    Ok(Outcome {
        pass,
        measured: text,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fr(id: u16, data: &[u8]) -> Frame {
        Frame::new(Id::Standard(id), data).unwrap()
    }
    fn wires(list: &[(&str, &[(u64, Frame)])]) -> Wires {
        list.iter()
            .map(|(n, w)| (n.to_string(), w.to_vec()))
            .collect()
    }
    fn hb(id: u16) -> Match {
        Match {
            id: Some(u32::from(id)),
            data: vec![],
        }
    }

    #[test]
    fn a_reaction_is_measured_from_the_last_trigger_frame_on_every_wire() {
        let start = Match {
            id: Some(0),
            data: vec![0x01, 0x50],
        };
        let w = wires(&[
            (
                "bus1",
                &[(1_000, fr(0x710, &[5])), (51_000, fr(0x710, &[5]))],
            ),
            ("vs1b", &[(80_000, fr(0, &[1, 0x50]))]),
            (
                "vs2b",
                &[(90_000, fr(0, &[1, 0x10])), (101_500, fr(0, &[1, 0x50]))],
            ),
        ]);
        let e = Expect::Within {
            after: Trigger::Last {
                frames: hb(0x710),
                on: "bus1".into(),
                from: 0,
            },
            then: start,
            on: vec!["vs1b".into(), "vs2b".into()],
            within: 51_000,
        };
        let o = measure(&e, &w, 200_000).unwrap();
        assert_eq!(
            o.measured,
            "from 51.00 ms: 29.00 ms on vs1b, 50.50 ms on vs2b"
        );
        assert!(o.pass);
        let Expect::Within {
            after, then, on, ..
        } = e
        else {
            unreachable!()
        };
        let tight = Expect::Within {
            after,
            then,
            on,
            within: 50_000,
        };
        assert!(!measure(&tight, &w, 200_000).unwrap().pass);
    }

    #[test]
    fn the_longest_gap_counts_the_window_edges() {
        let w = wires(&[(
            "vs1a",
            &[
                (10_000, fr(0x701, &[5])),
                (60_000, fr(0x701, &[5])),
                (100_000, fr(0x702, &[5])),
            ],
        )]);
        let e = |max| Expect::MaxGap {
            frames: hb(0x701),
            on: vec!["vs1a".into()],
            max,
            from: 0,
            to: Some(120_000),
        };
        let o = measure(&e(70_000), &w, 120_000).unwrap();
        assert_eq!(o.measured, "longest gap 60.00 ms on vs1a (from 60.00 ms)");
        assert!(o.pass);
        assert!(!measure(&e(59_000), &w, 120_000).unwrap().pass);
    }

    #[test]
    fn twins_within_the_window_are_duplicates_and_periodic_repeats_are_not() {
        let w = wires(&[(
            "bus2",
            &[
                (0, fr(0x190, &[1])),
                (50_000, fr(0x190, &[1])),
                (50_300, fr(0x190, &[1])),
            ],
        )]);
        let e = Expect::NoDuplicate {
            frames: hb(0x190),
            on: vec!["bus2".into()],
            window: 1_000,
            from: None,
        };
        let o = measure(&e, &w, 60_000).unwrap();
        assert_eq!(o.measured, "1 twin(s) on bus2, first at 50.30 ms");
        assert!(!o.pass);
        // Against the sender's wire: three sent, three arrived; a fourth is one too many.
        let mut w2 = w.clone();
        w2.insert("vs".into(), w["bus2"].clone());
        let e = Expect::NoDuplicate {
            frames: hb(0x190),
            on: vec!["bus2".into()],
            window: 0,
            from: Some("vs".into()),
        };
        let o = measure(&e, &w2, 60_000).unwrap();
        assert_eq!(
            (o.pass, o.measured.as_str()),
            (true, "3 sent on vs: 3 on bus2")
        );
        w2.get_mut("bus2").unwrap().push((55_000, fr(0x190, &[1])));
        assert!(!measure(&e, &w2, 60_000).unwrap().pass);
    }

    #[test]
    fn never_and_a_missing_wire() {
        let w = wires(&[("bus1", &[(5_000, fr(0x80, &[]))])]);
        let e = Expect::Never {
            frames: hb(0x80),
            on: vec!["bus1".into()],
            from: 6_000,
            to: None,
        };
        assert!(measure(&e, &w, 9_000).unwrap().pass);
        let e = Expect::Never {
            frames: hb(0x80),
            on: vec!["bus9".into()],
            from: 0,
            to: None,
        };
        assert_eq!(
            measure(&e, &w, 9_000).unwrap_err(),
            "no wire named \"bus9\" was recorded"
        );
    }
}
