//! `duocan kit run`: the fault bridge on real interfaces, the scenario's devices as processes,
//! the fault timeline applied on time, and every wire logged.
//!
//! The bridge runs under duocan's runtime with one port per member; a tap writes, for each
//! member, what its interface carried (`<member>.log`: what its device sent and what the bridge
//! sent it) and, for each bus, every frame the bridge took from its members (`<bus>.log`, and
//! `<bus>.pcap` for Wireshark). `start_us` holds the run's time zero (µs since the Unix epoch,
//! as the logs count). Devices' output goes to `<device>.out`; when each step of the timeline
//! was applied, to `timeline` (see [`super::timeline`]).

use super::scenario::{Fault, Rate, Scenario, Target};
use super::timeline::Timeline;
use crate::fail::Fail;
use crate::ports;
use crate::Global;
use duocan::bridge::{Bridge, BridgeConfig, MemberCounters};
use duocan::capture::candump::CandumpWriter;
use duocan::capture::pcap::PcapWriter;
use duocan::capture::recorder::{Tap, TapDirection, TapPoint};
use duocan::runtime::{Handle, Runtime};
use duocan::sim::FaultRates;
use duocan::{Duration, Frame, Id, Instant};
use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use tokio::process::{Child, Command};

/// A wire's candump log.
type Log = CandumpWriter<BufWriter<File>>;
/// A bus's pcap.
type Pcap = PcapWriter<BufWriter<File>>;

/// The wires' log writers.
struct Logs {
    epoch_us: u64,
    /// Per member: its log; per bus: its log and pcap; `bus_of[member]`.
    members: Vec<Log>,
    buses: Vec<(Log, Pcap)>,
    names: Vec<String>,
    bus_of: Vec<usize>,
    errors: u64,
}

/// The tap the bridge's runtime feeds.
struct KitTap(Mutex<Logs>);

impl Tap for KitTap {
    fn frame(&self, at: Instant, point: TapPoint, dir: TapDirection, frame: &Frame) {
        let TapPoint::Port(m) = point else { return };
        let Ok(mut l) = self.0.lock() else { return };
        let l = &mut *l;
        let t = l.epoch_us + at.as_micros();
        let Some(name) = l.names.get(m).cloned() else {
            return;
        };
        let mut ok = l.members[m].write(t, &name, frame).is_ok();
        if dir == TapDirection::Rx {
            if let Some(line) = live_line(frame) {
                println!("{:>7} ms  {line} (from {name})", at.as_micros() / 1000);
            }
            let b = l.bus_of[m];
            let (log, pcap) = &mut l.buses[b];
            ok &= log.write(t, &name, frame).is_ok() && pcap.write(t, frame).is_ok();
        }
        l.errors += u64::from(!ok);
    }
}

/// The frames worth a live line while a scenario runs: NMT commands, boot-ups and the active
/// master's announcements (what a failover is made of).
fn live_line(f: &Frame) -> Option<String> {
    let Id::Standard(id) = f.id() else {
        return None;
    };
    match (id, f.data()) {
        (0x000, [cs, node]) => {
            let what = match cs {
                0x01 => "start",
                0x02 => "stop",
                0x80 => "pre-operational",
                0x81 => "reset",
                0x82 => "reset communication",
                _ => return None,
            };
            Some(if *node == 0 {
                format!("NMT {what} all nodes")
            } else {
                format!("NMT {what} node {node:#04x}")
            })
        }
        (0x701..=0x77F, [0]) => Some(format!("boot-up of node {:#04x}", id - 0x700)),
        (0x071, [prio, node]) => Some(format!("active master: node {node:#04x} (priority {prio})")),
        _ => None,
    }
}

impl KitTap {
    fn flush(&self) -> u64 {
        let Ok(mut l) = self.0.lock() else { return 1 };
        let mut errors = l.errors;
        for w in &mut l.members {
            errors += u64::from(w.flush().is_err());
        }
        for (log, pcap) in &mut l.buses {
            errors += u64::from(log.flush().is_err() || pcap.flush().is_err());
        }
        errors
    }
}

fn create(dir: &Path, name: &str) -> Result<BufWriter<File>, Fail> {
    let p = dir.join(name);
    File::create(&p)
        .map(BufWriter::new)
        .map_err(|e| Fail::usage(format!("{}: {e}", p.display())))
}

/// A frame for identifier `id` (11 bits if it fits, else 29) and `data`.
fn frame(id: u32, data: &[u8]) -> Option<Frame> {
    let id = match u16::try_from(id) {
        Ok(i) if i <= 0x7FF => Id::Standard(i),
        _ => Id::Extended(id),
    };
    Frame::new(id, data).ok()
}

/// Applies one fault of the timeline to the bridge; names were checked with the scenario.
pub fn apply(b: &mut Bridge, s: &Scenario, f: &Fault) {
    let bus = |name: &str| {
        s.buses
            .iter()
            .position(|(n, _)| n == name)
            .unwrap_or(usize::MAX)
    };
    let member = |name: &str| b.member(name).unwrap_or(usize::MAX);
    match f {
        Fault::BusDown(x) => b.bus_down(bus(x)),
        Fault::BusUp(x) => b.bus_up(bus(x)),
        Fault::Disconnect(m) => b.disconnect(member(m)),
        Fault::Reconnect(m) => b.reconnect(member(m)),
        Fault::Partition(x, groups) => {
            let g: Vec<Vec<usize>> = groups
                .iter()
                .map(|g| g.iter().map(|m| member(m)).collect())
                .collect();
            let g: Vec<&[usize]> = g.iter().map(Vec::as_slice).collect();
            b.partition(bus(x), &g);
        }
        Fault::Heal(x) => b.heal(bus(x)),
        Fault::Rate(t, r) => {
            let old = match t {
                Target::Bus(x) => b.bus_faults(bus(x)),
                Target::Member(m) => b.port_faults(member(m)),
            }
            .unwrap_or(FaultRates::NONE);
            let new = match *r {
                Rate::Drop(p) => old.with_drop(p),
                Rate::Duplicate(p) => old.with_duplicate(p),
                Rate::Delay(p, max) => old.with_delay(p, Duration::from_millis(max)),
                Rate::CorruptDetected(p) => old.with_corrupt_detected(p),
                Rate::CorruptUndetected(p) => old.with_corrupt_undetected(p),
            };
            match t {
                Target::Bus(x) => b.set_bus_faults(bus(x), new),
                Target::Member(m) => b.set_port_faults(member(m), new),
            }
        }
        Fault::DropEvery(Target::Bus(x), n) => b.drop_every_on_bus(bus(x), *n),
        Fault::DropEvery(Target::Member(m), n) => b.drop_every(member(m), *n),
        Fault::Latency(m, ms) => b.set_port_latency(member(m), Duration::from_millis(*ms)),
        Fault::Babble(m, id, data, period) => {
            let f = frame(*id, data);
            b.babble(member(m), f, Duration::from_millis(*period));
        }
        Fault::BabbleStop(m) => b.babble(member(m), None, Duration::ZERO),
        // Devices are the runner's business.
        Fault::PowerOff(_) | Fault::PowerOn(_) => {}
    }
}

/// A device's command line with `{duocan}` replaced by this program and `{out}` by the run's
/// folder (a device that keeps files, such as a stack's stored parameters, keeps them with the
/// run's logs rather than wherever the kit was started).
fn command(run: &[String], dir: &Path) -> Command {
    let me = std::env::current_exe()
        .map(|p| p.display().to_string())
        .unwrap_or_else(|_| "duocan".into());
    let out = dir.display().to_string();
    let argv: Vec<String> = run
        .iter()
        .map(|a| a.replace("{duocan}", &me).replace("{out}", &out))
        .collect();
    let mut c = Command::new(&argv[0]);
    c.args(&argv[1..]).kill_on_drop(true);
    c
}

/// Starts a device, its output into `<name>.out`: a new file at its first start, added to at
/// each start after (a power cycle, a restart), so that its whole life is there.
fn start(dir: &Path, name: &str, run: &[String], first: bool) -> Result<Child, Fail> {
    let p = dir.join(format!("{name}.out"));
    let out = std::fs::OpenOptions::new()
        .create(true)
        .write(true)
        .truncate(first)
        .append(!first)
        .open(&p)
        .map_err(|e| Fail::usage(format!("{}: {e}", p.display())))?;
    let err = out.try_clone()?;
    command(run, dir)
        .stdout(out)
        .stderr(err)
        .spawn()
        .map_err(|e| Fail::usage(format!("device {name}: cannot start {:?}: {e}", run[0])))
}

/// Waits until `until`; meanwhile a device with `restart` whose program ended by itself is
/// started again at once (looked at every 5 ms: a board's reboot takes longer than that).
async fn wait_restarting(
    until: tokio::time::Instant,
    t0: tokio::time::Instant,
    s: &Scenario,
    dir: &Path,
    devices: &mut BTreeMap<String, Child>,
) -> Result<(), Fail> {
    if !s.devices.iter().any(|d| d.restart) {
        tokio::time::sleep_until(until).await;
        return Ok(());
    }
    loop {
        for d in s.devices.iter().filter(|d| d.restart) {
            let Some(c) = devices.get_mut(&d.name) else {
                continue;
            };
            if let Ok(Some(status)) = c.try_wait() {
                let child = start(dir, &d.name, &d.run, false)?;
                devices.insert(d.name.clone(), child);
                println!(
                    "{:>7} ms  restart {} (its program ended: {status})",
                    t0.elapsed().as_millis(),
                    d.name
                );
            }
        }
        let now = tokio::time::Instant::now();
        if now >= until {
            return Ok(());
        }
        tokio::time::sleep_until(until.min(now + std::time::Duration::from_millis(5))).await;
    }
}

/// What a run left: where its logs are, and the bridge's counters per member and bus.
pub struct RunResult {
    /// The log directory.
    pub dir: PathBuf,
    /// Per member: name and counters.
    pub members: Vec<(String, MemberCounters)>,
    /// Per bus: name and counters of its own faults.
    pub buses: Vec<(String, MemberCounters)>,
    /// Log writes that failed.
    pub log_errors: u64,
    /// When each step of the timeline was applied.
    pub timeline: Timeline,
}

/// Runs `s` on the real interfaces its members name, logging into `dir`.
pub async fn run(g: &Global, s: &Scenario, dir: &Path) -> Result<RunResult, Fail> {
    std::fs::create_dir_all(dir).map_err(|e| Fail::usage(format!("{}: {e}", dir.display())))?;
    let buses: Vec<Vec<&str>> = s
        .buses
        .iter()
        .map(|(_, m)| m.iter().map(String::as_str).collect())
        .collect();
    let buses_ref: Vec<&[&str]> = buses.iter().map(Vec::as_slice).collect();
    let bridge = Bridge::new(BridgeConfig::new(&buses_ref).with_seed(s.seed))
        .map_err(|e| Fail::usage(e.to_string()))?;
    let names: Vec<String> = s.members().map(String::from).collect();
    let mut logs = Logs {
        epoch_us: 0,
        members: Vec::new(),
        buses: Vec::new(),
        names: names.clone(),
        bus_of: Vec::new(),
        errors: 0,
    };
    for (i, (bus, members)) in s.buses.iter().enumerate() {
        for m in members {
            logs.members
                .push(CandumpWriter::new(create(dir, &format!("{m}.log"))?));
            logs.bus_of.push(i);
        }
        let pcap = PcapWriter::new(create(dir, &format!("{bus}.pcap"))?)?;
        logs.buses.push((
            CandumpWriter::new(create(dir, &format!("{bus}.log"))?),
            pcap,
        ));
    }
    let mut rt = Runtime::new(bridge).name("bridge");
    for m in &names {
        rt = rt.port(ports::open(m, g.udp_interface)?);
    }
    let epoch = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| u64::try_from(d.as_micros()).unwrap_or(u64::MAX));
    logs.epoch_us = epoch;
    let tap = Arc::new(KitTap(Mutex::new(logs)));
    let t0 = tokio::time::Instant::now();
    let handle: Handle<Bridge> = rt
        .tap(tap.clone())
        .spawn()
        .map_err(|e| Fail::usage(e.to_string()))?;
    std::fs::write(dir.join("start_us"), format!("{epoch}\n"))?;
    println!("{:>7} ms  bridge up: {}", 0, names.join(", "));

    let mut devices: BTreeMap<String, Child> = BTreeMap::new();
    // Device starts join the timeline as power-ons, in start order.
    let mut timeline: Vec<(u64, Fault)> = s
        .devices
        .iter()
        .map(|d| (d.start_ms, Fault::PowerOn(d.name.clone())))
        .collect();
    timeline.sort_by_key(|(t, _)| *t);
    timeline.extend(s.timeline.iter().cloned());
    timeline.sort_by_key(|(t, _)| *t);
    let mut applied = Timeline::default();
    let mut started = std::collections::BTreeSet::new();
    for (at, f) in &timeline {
        let until = t0 + std::time::Duration::from_millis(*at);
        wait_restarting(until, t0, s, dir, &mut devices).await?;
        let elapsed = || u64::try_from(t0.elapsed().as_micros()).unwrap_or(u64::MAX);
        let mut when = elapsed();
        match f {
            Fault::PowerOff(d) => {
                if let Some(mut c) = devices.remove(d) {
                    let _ = c.start_kill();
                    let _ = c.wait().await;
                }
            }
            Fault::PowerOn(d) => {
                if let Some(dev) = s.devices.iter().find(|x| &x.name == d) {
                    if let Some(mut old) = devices.remove(d) {
                        let _ = old.start_kill();
                        let _ = old.wait().await;
                    }
                    when = elapsed();
                    let first = started.insert(d.clone());
                    devices.insert(d.clone(), start(dir, d, &dev.run, first)?);
                }
            }
            _ => {
                let (s2, f2) = (s.clone(), f.clone());
                // When the bridge applied it, on its clock (the logs' too).
                when = handle
                    .call(move |b, now| {
                        apply(b, &s2, &f2);
                        now.as_micros()
                    })
                    .await
                    .map_err(|_| Fail::protocol("the bridge stopped"))?;
            }
        }
        applied.push(at.saturating_mul(1000), when);
        println!("{:>7} ms  {}", when / 1000, describe(f));
    }
    applied.write(dir)?;
    let end = t0 + std::time::Duration::from_millis(s.duration_ms);
    wait_restarting(end, t0, s, dir, &mut devices).await?;
    for (name, mut c) in devices {
        if let Ok(Some(status)) = c.try_wait() {
            println!("          {name} had exited: {status}");
        }
        let _ = c.start_kill();
        let _ = c.wait().await;
    }
    let n = names.len();
    let nb = s.buses.len();
    let (members, bus_counters) = handle
        .call(move |b, _| {
            let m: Vec<MemberCounters> = (0..n).filter_map(|i| b.counters(i).copied()).collect();
            let bc: Vec<MemberCounters> =
                (0..nb).filter_map(|i| b.bus_counters(i).copied()).collect();
            (m, bc)
        })
        .await
        .map_err(|_| Fail::protocol("the bridge stopped"))?;
    handle.shutdown().await;
    let log_errors = tap.flush();
    println!("{:>7} ms  end", t0.elapsed().as_millis());
    Ok(RunResult {
        dir: dir.to_path_buf(),
        members: names.into_iter().zip(members).collect(),
        buses: s
            .buses
            .iter()
            .map(|(b, _)| b.clone())
            .zip(bus_counters)
            .collect(),
        log_errors,
        timeline: applied,
    })
}

/// A fault as a live line says it.
pub fn describe(f: &Fault) -> String {
    match f {
        Fault::BusDown(b) => format!("bus_down {b}"),
        Fault::BusUp(b) => format!("bus_up {b}"),
        Fault::Disconnect(m) => format!("disconnect {m}"),
        Fault::Reconnect(m) => format!("reconnect {m}"),
        Fault::Partition(b, g) => format!("partition {b} {g:?}"),
        Fault::Heal(b) => format!("heal {b}"),
        Fault::Rate(t, r) => format!("{r:?} on {t:?}"),
        Fault::DropEvery(t, n) => format!("drop_every {n} on {t:?}"),
        Fault::Latency(m, ms) => format!("latency {ms} ms on {m}"),
        Fault::Babble(m, id, data, p) => {
            format!("babble {m}: {id:#x} {data:02x?} every {p} ms")
        }
        Fault::BabbleStop(m) => format!("babble_stop {m}"),
        Fault::PowerOff(d) => format!("power_off {d}"),
        Fault::PowerOn(d) => format!("power_on {d}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A scenario of one device running `script` (sh), restarted or not.
    fn one_device(script: &str, restart: bool) -> Scenario {
        let text = format!(
            r#"
name = "restart"
duration_ms = 1000
[[bus]]
name = "bus1"
members = ["x0", "x1"]
[[device]]
name = "dev"
ports = ["x0"]
run = ["sh", "-c", {script:?}, "sh", "{{out}}"]
restart = {restart}
"#
        );
        Scenario::parse(&text, "test").unwrap()
    }

    fn folder(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("duocan-kit-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    /// Runs the device from its start for 300 ms as a run does; its output.
    async fn run_for_300ms(s: &Scenario, dir: &Path) -> String {
        let d = &s.devices[0];
        let mut devices = BTreeMap::new();
        devices.insert(d.name.clone(), start(dir, &d.name, &d.run, true).unwrap());
        let t0 = tokio::time::Instant::now();
        let end = t0 + std::time::Duration::from_millis(300);
        wait_restarting(end, t0, s, dir, &mut devices)
            .await
            .unwrap();
        for (_, mut c) in devices {
            let _ = c.start_kill();
            let _ = c.wait().await;
        }
        std::fs::read_to_string(dir.join("dev.out")).unwrap()
    }

    #[tokio::test]
    async fn a_device_whose_program_ends_is_started_again_only_with_restart() {
        // Each start writes a line to its output and a file into the run's folder ({out}),
        // then ends at once: restarted, it has started many times in 300 ms (each start's
        // output kept); not restarted, once.
        let script = "echo started; echo x >> \"$1/starts\"";
        let dir = folder("restart");
        let out = run_for_300ms(&one_device(script, true), &dir).await;
        let starts = std::fs::read_to_string(dir.join("starts")).unwrap();
        let (said, wrote) = (out.lines().count(), starts.lines().count());
        assert!(wrote >= 3, "{out:?} {starts:?}");
        // Every start's output kept: one line per start that got as far as its file, and the
        // last start, killed at the end of the run, may have said its line but not yet written
        // its file (the kill lands between its two commands).
        assert!(said == wrote || said == wrote + 1, "{out:?} {starts:?}");

        let dir = folder("no-restart");
        let out = run_for_300ms(&one_device(script, false), &dir).await;
        assert_eq!(out, "started\n");
        assert_eq!(std::fs::read_to_string(dir.join("starts")).unwrap(), "x\n");
    }

    #[test]
    fn a_command_names_this_tool_and_the_runs_folder() {
        let c = command(
            &["{duocan}".into(), "-s".into(), "{out}/a_".into()],
            Path::new("/tmp/run"),
        );
        let args: Vec<_> = c.as_std().get_args().collect();
        assert_eq!(args, ["-s", "/tmp/run/a_"]);
        assert_ne!(c.as_std().get_program(), "{duocan}");
    }
}
