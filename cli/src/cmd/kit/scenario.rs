//! The scenario file: buses, devices, the fault timeline and the expectations, in TOML, read
//! strictly (an unknown key, a missing one, a name that names nothing: an error with its line).
//!
//! ```toml
//! name = "bus 1 cut"
//! duration_ms = 3000
//! seed = 7                      # the random faults' seed (default 0)
//!
//! [[bus]]
//! name = "bus1"
//! members = ["vm1a", "vs1a", "vs1b"]   # interfaces: the master's and each board's bus-1 port
//!
//! [[device]]
//! name = "board_a"
//! ports = ["vs1a", "vs2a"]             # the members it is on
//! run = ["{duocan}", "--bus", "vs1a,vs2a", "device", "board", "--node", "0x10"]
//! start_ms = 0                         # when the kit starts it (argv; {duocan}: this tool,
//!                                      # {out}: the run's folder)
//! restart = false                      # started again when its program ends by itself
//!
//! [[fault]]
//! at_ms = 1000
//! fault = "bus_down"                   # the simulator's names: see below
//! bus = "bus1"
//!
//! [[expect]]
//! name = "standby started on both buses"
//! kind = "within"                      # within, max_gap, no_duplicate (from or window_ms), never
//! after = { last_id = 0x710, on = "bus1", from_ms = 1000 }   # or { at_ms = 1000 }
//! id = 0x000
//! data = [0x01, 0x50]
//! on = ["vs1b", "vs2b"]                # wires: member or bus names
//! within_ms = 51
//! ```
//!
//! Faults (`fault = …`), with the keys each takes: `bus_down`/`bus_up` (bus), `disconnect`/
//! `reconnect` (member), `partition` (bus, groups: lists of members), `heal` (bus), `drop`,
//! `duplicate`, `corrupt_detected`, `corrupt_undetected` (bus or member, rate 0–1), `delay`
//! (bus or member, rate, max_ms), `drop_every` (bus or member, n), `latency` (member, ms),
//! `babble` (member, id, data, period_ms), `babble_stop` (member), `power_off`/`power_on`
//! (device). A rate set stays until set again (0 stops it).

use super::expect::{Expect, Match, Trigger};
use serde::Deserialize;
use std::collections::BTreeSet;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileScenario {
    name: String,
    duration_ms: u64,
    #[serde(default)]
    seed: u64,
    bus: Vec<FileBus>,
    #[serde(default)]
    device: Vec<FileDevice>,
    #[serde(default)]
    fault: Vec<FileFault>,
    #[serde(default)]
    expect: Vec<FileExpect>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileBus {
    name: String,
    members: Vec<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileDevice {
    name: String,
    ports: Vec<String>,
    run: Vec<String>,
    #[serde(default)]
    start_ms: u64,
    /// What stands in for the device in the simulator.
    sim: Option<String>,
    #[serde(default)]
    restart: bool,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileFault {
    at_ms: u64,
    fault: String,
    bus: Option<String>,
    member: Option<String>,
    device: Option<String>,
    rate: Option<f64>,
    max_ms: Option<u64>,
    n: Option<u32>,
    ms: Option<u64>,
    groups: Option<Vec<Vec<String>>>,
    id: Option<u32>,
    data: Option<Vec<u8>>,
    period_ms: Option<u64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileAfter {
    at_ms: Option<u64>,
    last_id: Option<u32>,
    last_data: Option<Vec<u8>>,
    on: Option<String>,
    from_ms: Option<u64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileExpect {
    name: String,
    kind: String,
    on: Vec<String>,
    id: Option<u32>,
    data: Option<Vec<u8>>,
    after: Option<FileAfter>,
    within_ms: Option<u64>,
    max_ms: Option<u64>,
    window_ms: Option<u64>,
    from: Option<String>,
    from_ms: Option<u64>,
    to_ms: Option<u64>,
}

/// Where a rate or drop-every fault applies.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Target {
    /// Every frame on the bus.
    Bus(String),
    /// What one member receives.
    Member(String),
}

/// A random fault kind, as the simulator's `FaultRates` fields name them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Rate {
    /// `drop`.
    Drop(f64),
    /// `duplicate`.
    Duplicate(f64),
    /// `delay`, by up to `max` ms.
    Delay(f64, u64),
    /// `corrupt_detected`.
    CorruptDetected(f64),
    /// `corrupt_undetected`.
    CorruptUndetected(f64),
}

/// One fault of the timeline.
#[derive(Clone, Debug, PartialEq)]
pub enum Fault {
    /// `bus_down`.
    BusDown(String),
    /// `bus_up`.
    BusUp(String),
    /// `disconnect`.
    Disconnect(String),
    /// `reconnect`.
    Reconnect(String),
    /// `partition`.
    Partition(String, Vec<Vec<String>>),
    /// `heal`.
    Heal(String),
    /// A rate.
    Rate(Target, Rate),
    /// `drop_every`.
    DropEvery(Target, u32),
    /// `latency` (ms).
    Latency(String, u64),
    /// `babble`: identifier, data, period (ms).
    Babble(String, u32, Vec<u8>, u64),
    /// `babble_stop`.
    BabbleStop(String),
    /// `power_off`.
    PowerOff(String),
    /// `power_on`.
    PowerOn(String),
}

/// A device the kit starts (or the simulator stands in for).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Device {
    /// Its name.
    pub name: String,
    /// The members it is on.
    pub ports: Vec<String>,
    /// Its command line.
    pub run: Vec<String>,
    /// When it is started, ms.
    pub start_ms: u64,
    /// What stands in for it in the simulator.
    pub sim: Option<String>,
    /// Started again at once when its program ends by itself (not by `power_off`): a device
    /// whose reset ends its program, as CANopenNode's `canopend` does on NMT reset node, comes
    /// back with a boot-up as a board does.
    pub restart: bool,
}

/// A checked scenario.
#[derive(Clone, Debug, PartialEq)]
pub struct Scenario {
    /// Its name.
    pub name: String,
    /// How long it runs, ms.
    pub duration_ms: u64,
    /// The random faults' seed.
    pub seed: u64,
    /// The buses: name and members, in file order.
    pub buses: Vec<(String, Vec<String>)>,
    /// The devices.
    pub devices: Vec<Device>,
    /// The faults, by time (file order among equal times).
    pub timeline: Vec<(u64, Fault)>,
    /// The expectations, by name.
    pub expects: Vec<(String, Expect)>,
}

impl Scenario {
    /// Reads a scenario from TOML text; `source` names it in errors.
    pub fn parse(text: &str, source: &str) -> Result<Scenario, String> {
        let f: FileScenario = toml::from_str(text).map_err(|e| format!("{source}: {e}"))?;
        check(f).map_err(|e| format!("{source}: {e}"))
    }
    /// Every member, in port order.
    pub fn members(&self) -> impl Iterator<Item = &str> {
        self.buses
            .iter()
            .flat_map(|(_, m)| m.iter().map(String::as_str))
    }
}

fn check(f: FileScenario) -> Result<Scenario, String> {
    let mut names = BTreeSet::new();
    let mut members = BTreeSet::new();
    let mut buses = Vec::new();
    for b in f.bus {
        if !names.insert(b.name.clone()) {
            return Err(format!("bus {:?} is named twice", b.name));
        }
        if b.members.len() < 2 {
            return Err(format!(
                "bus {:?}: a bus joins at least two members",
                b.name
            ));
        }
        for m in &b.members {
            if !members.insert(m.clone()) || names.contains(m) {
                return Err(format!("member {m:?} is named twice"));
            }
        }
        buses.push((b.name, b.members));
    }
    let bus_names: BTreeSet<String> = buses.iter().map(|(n, _)| n.clone()).collect();
    let is_bus = |s: &str| bus_names.contains(s);
    let is_member = |s: &str| members.contains(s);
    let mut devices = Vec::new();
    for d in f.device {
        if d.run.is_empty() {
            return Err(format!("device {:?}: `run` is empty", d.name));
        }
        if let Some(p) = d.ports.iter().find(|p| !is_member(p)) {
            return Err(format!(
                "device {:?}: {p:?} is not a member of any bus",
                d.name
            ));
        }
        if devices.iter().any(|x: &Device| x.name == d.name) {
            return Err(format!("device {:?} is named twice", d.name));
        }
        if d.start_ms > f.duration_ms {
            return Err(format!("device {:?} starts after the end", d.name));
        }
        devices.push(Device {
            name: d.name,
            ports: d.ports,
            run: d.run,
            start_ms: d.start_ms,
            sim: d.sim,
            restart: d.restart,
        });
    }
    let is_device = |s: &str| devices.iter().any(|d| d.name == s);
    let mut timeline = Vec::new();
    for (i, x) in f.fault.into_iter().enumerate() {
        let at = x.at_ms;
        let fault = fault(x, &is_bus, &is_member, &is_device)
            .map_err(|e| format!("fault {} (at {at} ms): {e}", i + 1))?;
        if at > f.duration_ms {
            return Err(format!(
                "fault {} is at {at} ms, after the end ({} ms)",
                i + 1,
                f.duration_ms
            ));
        }
        timeline.push((at, fault));
    }
    timeline.sort_by_key(|(t, _)| *t);
    let mut expects = Vec::new();
    for x in f.expect {
        let name = x.name.clone();
        let e = expect(x, &|w| is_bus(w) || is_member(w))
            .map_err(|e| format!("expectation {name:?}: {e}"))?;
        expects.push((name, e));
    }
    Ok(Scenario {
        name: f.name,
        duration_ms: f.duration_ms,
        seed: f.seed,
        buses,
        devices,
        timeline,
        expects,
    })
}

fn need<T>(v: Option<T>, key: &str) -> Result<T, String> {
    v.ok_or_else(|| format!("needs `{key}`"))
}

fn fault(
    x: FileFault,
    is_bus: &dyn Fn(&str) -> bool,
    is_member: &dyn Fn(&str) -> bool,
    is_device: &dyn Fn(&str) -> bool,
) -> Result<Fault, String> {
    let bus = |b: Option<String>| -> Result<String, String> {
        let b = need(b, "bus")?;
        if is_bus(&b) {
            Ok(b)
        } else {
            Err(format!("{b:?} is not a bus"))
        }
    };
    let member = |m: Option<String>| -> Result<String, String> {
        let m = need(m, "member")?;
        if is_member(&m) {
            Ok(m)
        } else {
            Err(format!("{m:?} is not a member"))
        }
    };
    let device = |d: Option<String>| -> Result<String, String> {
        let d = need(d, "device")?;
        if is_device(&d) {
            Ok(d)
        } else {
            Err(format!("{d:?} is not a device"))
        }
    };
    let target = |b: Option<String>, m: Option<String>| match (b, m) {
        (Some(_), Some(_)) => Err("give `bus` or `member`, not both".to_string()),
        (b @ Some(_), None) => bus(b).map(Target::Bus),
        (None, m) => member(m).map(Target::Member),
    };
    let rate = |r: Option<f64>| -> Result<f64, String> {
        let r = need(r, "rate")?;
        if (0.0..=1.0).contains(&r) {
            Ok(r)
        } else {
            Err(format!("rate {r}: give 0 to 1"))
        }
    };
    Ok(match x.fault.as_str() {
        "bus_down" => Fault::BusDown(bus(x.bus)?),
        "bus_up" => Fault::BusUp(bus(x.bus)?),
        "disconnect" => Fault::Disconnect(member(x.member)?),
        "reconnect" => Fault::Reconnect(member(x.member)?),
        "heal" => Fault::Heal(bus(x.bus)?),
        "partition" => {
            let b = bus(x.bus)?;
            let groups = need(x.groups, "groups")?;
            for m in groups.iter().flatten() {
                member(Some(m.clone()))?;
            }
            Fault::Partition(b, groups)
        }
        "drop" => Fault::Rate(target(x.bus, x.member)?, Rate::Drop(rate(x.rate)?)),
        "duplicate" => Fault::Rate(target(x.bus, x.member)?, Rate::Duplicate(rate(x.rate)?)),
        "corrupt_detected" => Fault::Rate(
            target(x.bus, x.member)?,
            Rate::CorruptDetected(rate(x.rate)?),
        ),
        "corrupt_undetected" => Fault::Rate(
            target(x.bus, x.member)?,
            Rate::CorruptUndetected(rate(x.rate)?),
        ),
        "delay" => Fault::Rate(
            target(x.bus, x.member)?,
            Rate::Delay(rate(x.rate)?, need(x.max_ms, "max_ms")?),
        ),
        "drop_every" => Fault::DropEvery(target(x.bus, x.member)?, need(x.n, "n")?),
        "latency" => Fault::Latency(member(x.member)?, need(x.ms, "ms")?),
        "babble" => {
            let id = need(x.id, "id")?;
            let data = x.data.unwrap_or_default();
            if id > 0x1FFF_FFFF || data.len() > 8 {
                return Err("babble: an identifier up to 29 bits and at most 8 data bytes".into());
            }
            Fault::Babble(member(x.member)?, id, data, need(x.period_ms, "period_ms")?)
        }
        "babble_stop" => Fault::BabbleStop(member(x.member)?),
        "power_off" => Fault::PowerOff(device(x.device)?),
        "power_on" => Fault::PowerOn(device(x.device)?),
        other => {
            return Err(format!(
                "unknown fault {other:?}: bus_down, bus_up, disconnect, reconnect, partition, \
                 heal, drop, duplicate, delay, corrupt_detected, corrupt_undetected, drop_every, \
                 latency, babble, babble_stop, power_off, power_on"
            ))
        }
    })
}

fn expect(x: FileExpect, is_wire: &dyn Fn(&str) -> bool) -> Result<Expect, String> {
    if x.on.is_empty() {
        return Err("`on` names no wire".into());
    }
    if let Some(w) = x.on.iter().find(|w| !is_wire(w)) {
        return Err(format!("{w:?} is neither a bus nor a member"));
    }
    let frames = Match {
        id: x.id,
        data: x.data.unwrap_or_default(),
    };
    let us = |ms: u64| ms.saturating_mul(1000);
    Ok(match x.kind.as_str() {
        "within" => {
            let a = need(x.after, "after")?;
            let after = match (a.at_ms, a.last_id) {
                (Some(t), None) => Trigger::At(us(t)),
                (None, Some(id)) => {
                    let on = need(a.on, "after.on")?;
                    if !is_wire(&on) {
                        return Err(format!("after.on: {on:?} is neither a bus nor a member"));
                    }
                    Trigger::Last {
                        frames: Match {
                            id: Some(id),
                            data: a.last_data.unwrap_or_default(),
                        },
                        on,
                        from: us(a.from_ms.unwrap_or(0)),
                    }
                }
                _ => return Err("`after` takes at_ms, or last_id with on".into()),
            };
            Expect::Within {
                after,
                then: frames,
                on: x.on,
                within: us(need(x.within_ms, "within_ms")?),
            }
        }
        "max_gap" => Expect::MaxGap {
            frames,
            on: x.on,
            max: us(need(x.max_ms, "max_ms")?),
            from: us(x.from_ms.unwrap_or(0)),
            to: x.to_ms.map(us),
        },
        "no_duplicate" => match x.from {
            Some(from) if is_wire(&from) => Expect::NoDuplicate {
                frames,
                on: x.on,
                window: 0,
                from: Some(from),
            },
            Some(from) => return Err(format!("from: {from:?} is neither a bus nor a member")),
            None => Expect::NoDuplicate {
                frames,
                on: x.on,
                window: us(need(x.window_ms, "window_ms")?),
                from: None,
            },
        },
        "never" => Expect::Never {
            frames,
            on: x.on,
            from: us(x.from_ms.unwrap_or(0)),
            to: x.to_ms.map(us),
        },
        other => {
            return Err(format!(
                "unknown kind {other:?}: within, max_gap, no_duplicate, never"
            ))
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = r#"
name = "bus 1 cut"
duration_ms = 3000
[[bus]]
name = "bus1"
members = ["vm1a", "vs1a", "vs1b"]
[[bus]]
name = "bus2"
members = ["vm2a", "vs2a", "vs2b"]
[[device]]
name = "board_a"
ports = ["vs1a", "vs2a"]
run = ["board", "--node", "0x10"]
sim = "board 0x10"
[[fault]]
at_ms = 1500
fault = "power_off"
device = "board_a"
[[fault]]
at_ms = 1000
fault = "bus_down"
bus = "bus1"
[[fault]]
at_ms = 0
fault = "drop"
member = "vs1b"
rate = 0.25
[[expect]]
name = "standby started"
kind = "within"
after = { last_id = 0x710, on = "bus2", from_ms = 1500 }
id = 0
data = [1, 0x50]
on = ["vs2b"]
within_ms = 51
"#;

    #[test]
    fn a_scenario_reads_into_its_timeline_and_expectations() {
        let s = Scenario::parse(GOOD, "good.toml").unwrap();
        assert_eq!(s.members().count(), 6);
        assert_eq!(
            s.timeline,
            [
                (
                    0,
                    Fault::Rate(Target::Member("vs1b".into()), Rate::Drop(0.25))
                ),
                (1000, Fault::BusDown("bus1".into())),
                (1500, Fault::PowerOff("board_a".into())),
            ]
        );
        assert_eq!(
            s.expects[0].1,
            Expect::Within {
                after: Trigger::Last {
                    frames: Match {
                        id: Some(0x710),
                        data: vec![]
                    },
                    on: "bus2".into(),
                    from: 1_500_000
                },
                then: Match {
                    id: Some(0),
                    data: vec![1, 0x50]
                },
                on: vec!["vs2b".into()],
                within: 51_000
            }
        );
    }

    #[test]
    fn mistakes_are_errors_that_say_where() {
        let cases = [
            (
                "duration_ms = 3000",
                "duration_ms = \"x\"",
                "good.toml: TOML parse error at line 3",
            ),
            (
                "bus = \"bus1\"",
                "bus = \"bus9\"",
                "fault 2 (at 1000 ms): \"bus9\" is not a bus",
            ),
            (
                "rate = 0.25",
                "rate = 1.5",
                "fault 3 (at 0 ms): rate 1.5: give 0 to 1",
            ),
            (
                "fault = \"drop\"",
                "fault = \"explode\"",
                "unknown fault \"explode\"",
            ),
            (
                "on = [\"vs2b\"]",
                "on = [\"vs9\"]",
                "\"vs9\" is neither a bus nor a member",
            ),
            (
                "within_ms = 51",
                "within_ms = 51\nbogus = 1",
                "unknown field `bogus`",
            ),
            (
                "members = [\"vm2a\", \"vs2a\", \"vs2b\"]",
                "members = [\"vm2a\", \"vs1a\"]",
                "member \"vs1a\" is named twice",
            ),
            ("at_ms = 1500", "at_ms = 9000", "after the end (3000 ms)"),
        ];
        for (from, to, says) in cases {
            let bad = GOOD.replacen(from, to, 1);
            let e = Scenario::parse(&bad, "good.toml").unwrap_err();
            assert!(e.contains(says), "{to}: {e}");
        }
    }
}
