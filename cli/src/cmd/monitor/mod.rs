//! `duocan monitor`: a live view of the network, full screen on a terminal, plain lines
//! otherwise.
//!
//! **Panels.** Nodes (node-ID, NMT state, heartbeat age, last EMCY with its text, device name
//! from the description attached), ports (name, state, rx/tx/error counters), redundancy (each
//! `--pair`'s active and standby member, the active master of the latest CiA 302-2 active-master
//! response 0x71 and its heartbeat age) and the recent events (the network's, and the monitor's
//! own observations, lines starting with `monitor:`). What the panels show is
//! [`model::Model`]'s rule; this module feeds it and draws it.
//!
//! **Where the data comes from.** The network's events (states, boot-ups, EMCY, port status)
//! are read by a task of their own, so drawing never holds them up; a tap on the ports
//! (`NetOptions::with_tap`) hands the model what events do not carry: each heartbeat's arrival
//! and the 0x71 frames. The monitor is listen-only: it sends no frame at all.
//!
//! **Memory.** The model's bounds: 127 nodes, 2 ports, [`model::EVENTS_KEPT`] log lines.
//!
//! **Keys** (full screen): `q`, Esc or Ctrl-C quit; `p` pauses the view (the data is still
//! collected, `PAUSED` is shown); `/` then text filters the nodes and events (Enter keeps it,
//! Esc drops it); `c` clears the events; arrows and PgUp/PgDn scroll the events.
//!
//! **Plain** (standard output not a terminal, or `--plain`): one line per event with the time
//! of day, and a status line every `--every` seconds; `--json`: the same as one JSON object per
//! line. `--duration S` stops after S seconds in either mode.

mod model;
mod plain;
mod screen;

use crate::args::parse_node;
use crate::fail::Fail;
use crate::{bus, Global};
use duocan::capture::recorder::{Tap, TapDirection, TapPoint};
use duocan::net::{Network, PortView};
use duocan::{Frame, Instant};
use duocan_redundancy::net::SIM_PAIRS;
use model::{Model, Names, PortInfo};
use std::io::IsTerminal;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

/// How often the ports' states and counters are read.
const PORTS_POLL: Duration = Duration::from_millis(250);
/// The longest `--duration` or `--every`: a day.
const MAX_SECONDS: f64 = 86_400.0;

/// The arguments of `duocan monitor`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// A redundant pair of slaves, A,B (node-IDs): shows which member is active (operational)
    /// and which standby (pre-operational); repeatable. Default on `--bus sim-station`: the simulated
    /// station's pairs
    #[arg(long = "pair", value_name = "A,B", value_parser = parse_pair)]
    pairs: Vec<(u8, u8)>,
    /// Plain lines even on a terminal
    #[arg(long)]
    plain: bool,
    /// Plain mode: seconds between status lines
    #[arg(long, value_name = "S", default_value = "5", value_parser = parse_seconds)]
    every: Duration,
    /// Stop after S seconds (exit 0)
    #[arg(long, value_name = "S", value_parser = parse_seconds)]
    duration: Option<Duration>,
}

/// `A,B`: two different node-IDs.
fn parse_pair(s: &str) -> Result<(u8, u8), String> {
    let (a, b) = s
        .split_once(',')
        .ok_or_else(|| format!("pair {s:?}: give two node-IDs as A,B (e.g. 0x10,0x50)"))?;
    let (a, b) = (parse_node(a.trim())?.raw(), parse_node(b.trim())?.raw());
    if a == b {
        return Err(format!(
            "pair {s:?}: the two members must be different nodes"
        ));
    }
    Ok((a, b))
}

/// Seconds: a decimal number (`2`, `0.5`) above zero, at most a day.
fn parse_seconds(s: &str) -> Result<Duration, String> {
    let digits = s.bytes().filter(u8::is_ascii_digit).count();
    let points = s.bytes().filter(|b| *b == b'.').count();
    let v = (digits > 0 && digits + points == s.len() && points <= 1)
        .then(|| s.parse::<f64>().ok())
        .flatten()
        .ok_or_else(|| format!("{s:?} seconds: give a number such as 5 or 0.5"))?;
    if v > 0.0 && v <= MAX_SECONDS {
        Ok(Duration::from_secs_f64(v))
    } else {
        Err(format!(
            "{s} seconds: give more than 0 and at most {MAX_SECONDS} (a day)"
        ))
    }
}

/// The model, shared by the tap, the event task and the view.
pub(crate) type Shared = Arc<Mutex<Model>>;

/// The model behind `m`'s lock (a panic elsewhere leaves it whole: every update is one call).
pub(crate) fn lock(m: &Mutex<Model>) -> std::sync::MutexGuard<'_, Model> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// Hands every frame a port sees to the model.
struct ModelTap(Shared);

impl Tap for ModelTap {
    fn frame(&self, at: Instant, point: TapPoint, dir: TapDirection, frame: &Frame) {
        let port = match point {
            TapPoint::Port(n) => Some(n),
            TapPoint::Logical => None,
        };
        lock(&self.0).on_frame(at, port, dir == TapDirection::Rx, frame);
    }
}

/// What the two modes share: the network, the model, and the wall-clock time of the network's
/// zero.
pub(crate) struct Session {
    pub bus: bus::Bus,
    pub model: Shared,
    /// Milliseconds since 1970 at the network's `Instant::ZERO`.
    pub zero_unix_ms: u64,
    /// When to stop, if `--duration` says.
    pub deadline: Option<tokio::time::Instant>,
}

impl Session {
    /// The time of day of `at`, UTC.
    pub fn clock(&self, at: Instant) -> String {
        model::clock_text(self.zero_unix_ms + at.as_micros() / 1_000)
    }
    /// Waits until the deadline (forever without one).
    pub async fn until_deadline(&self) {
        match self.deadline {
            Some(d) => tokio::time::sleep_until(d).await,
            None => std::future::pending().await,
        }
    }
}

/// Runs `duocan monitor`.
pub async fn run(g: &Global, a: Args) -> Result<(), Fail> {
    let sim = g
        .bus
        .as_ref()
        .is_some_and(|b| crate::bus::is_sim_station(&b.0));
    let pairs = if a.pairs.is_empty() && sim {
        SIM_PAIRS.to_vec()
    } else {
        a.pairs.clone()
    };
    if pairs.len() > model::MAX_PAIRS {
        return Err(Fail::usage(format!(
            "--pair given {} times: at most {}",
            pairs.len(),
            model::MAX_PAIRS
        )));
    }
    let shared: Shared = Arc::new(Mutex::new(Model::new(Names::new(), pairs)));
    let tap: Arc<dyn Tap> = Arc::new(ModelTap(shared.clone()));
    let bus = bus::open_tapped(g, true, Some(tap))?;
    let names: Names = bus
        .descs
        .iter()
        .filter(|(_, d)| !d.device_info.product_name.is_empty())
        .map(|(id, d)| (*id, d.device_info.product_name.clone()))
        .collect();
    lock(&shared).set_names(names);
    let mut events = bus.net.events();
    let m = shared.clone();
    let collector = tokio::spawn(async move {
        while let Some(e) = events.next().await {
            lock(&m).on_event(&e);
        }
    });
    let poller = tokio::spawn(poll_ports(bus.net.clone(), shared.clone()));
    let since_zero =
        u64::try_from(std::time::Duration::from_micros(bus.net.now().as_micros()).as_millis())
            .unwrap_or(0);
    let unix_now = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| u64::try_from(d.as_millis()).unwrap_or(0));
    let session = Session {
        bus,
        model: shared,
        zero_unix_ms: unix_now.saturating_sub(since_zero),
        deadline: a.duration.map(|d| tokio::time::Instant::now() + d),
    };
    let r = if a.plain || g.json || !std::io::stdout().is_terminal() {
        plain::run(&session, g.json, a.every).await
    } else {
        screen::run(&session).await
    };
    poller.abort();
    session.bus.close().await;
    collector.abort();
    r
}

/// Reads the ports' states and counters into the model until the network closes.
async fn poll_ports(net: Network, model: Shared) {
    let mut every = tokio::time::interval(PORTS_POLL);
    loop {
        every.tick().await;
        let Ok(ports) = net.ports().await else {
            return;
        };
        lock(&model).set_ports(ports.into_iter().map(port_info).collect());
    }
}

/// A port's row: errors are the error frames received and the sends that failed.
fn port_info(p: PortView) -> PortInfo {
    let c = p.counters;
    PortInfo {
        name: p.name,
        state: p.state.into(),
        rx: c.rx_frames,
        tx: c.tx_frames,
        errors: c.rx_error_frames + c.tx_failed,
    }
}
