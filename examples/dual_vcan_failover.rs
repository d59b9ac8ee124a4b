//! A master and a slave, each on duocan-redundancy's dual-bus layer over two SocketCAN
//! interfaces, under the tokio runtime. Take one interface down and up while it runs:
//!
//! ```text
//! cargo run --example dual_vcan_failover --features socketcan
//! sudo ip link set vcan0 down     # bus 1 fails: frames keep flowing on bus 2, no heartbeat lost
//! sudo ip link set vcan0 up       # bus 1 recovers
//! ```
//!
//! With `--self-test` it does that itself, for bus 1 and then bus 2, checks that the master's
//! node never misses a heartbeat of the slave, that frames keep flowing on the other bus while
//! one is down and on both after the repair, and exits 0 (all held) or 1. CI runs it in the qemu
//! VM of `.ci/vcanvm` (`.ci/tier-vcan.sh`).
//!
//! Without the interfaces it exits 2, saying how to create them. Options: `--buses A,B`
//! (default `vcan0,vcan1`), `--seconds N` (run for N seconds instead of until Ctrl-C),
//! `--skew-ms N` (the merger's skew window, default 10: raise it where the two ports' frames
//! can reach the process further apart, e.g. on an emulated CPU).

use duocan::machine::{PortStatus, Station, StationEvent};
use duocan::node::NodeEventKind;
use duocan::od::{comm, DynamicDictionary, ObjectDictionary};
use duocan::port::socketcan::{link_state, LinkState, SocketCanPort};
use duocan::runtime::{Handle, Runtime, RuntimeEvent};
use duocan::{Duration, NmtCommand, NmtTarget, Node, NodeConfig, NodeEvent, NodeId};
use duocan_redundancy::{
    DualBus, DualBusConfig, DualBusNode, LinkEvent, LinkEventKind, LinkMode, PortState,
};
use std::process::{Command, ExitCode};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::Duration as StdDuration;
use tokio::sync::broadcast;

type Dev = DualBusNode<DynamicDictionary>;
type Ev = RuntimeEvent<StationEvent<LinkEvent, NodeEvent>>;

const MASTER: u8 = 1;
const SLAVE: u8 = 5;
/// Heartbeat of the slave; the master's consumer time is 12 periods, so a lost heartbeat would
/// show up while a bus is down (a failover that loses frames for longer than that would not go
/// unnoticed), and the dual-bus layer's silence limit is 3 periods.
const HB_MS: u16 = 25;
const CONSUMER_MS: u16 = 300;

struct Options {
    buses: [String; 2],
    self_test: bool,
    seconds: Option<u64>,
    skew_ms: u64,
}

fn usage(msg: &str) -> ExitCode {
    eprintln!("dual_vcan_failover: {msg}");
    eprintln!(
        "usage: dual_vcan_failover [--self-test] [--buses vcan0,vcan1] [--seconds N] [--skew-ms N]"
    );
    ExitCode::from(2)
}

fn parse_args() -> Result<Options, String> {
    let mut o = Options {
        buses: ["vcan0".into(), "vcan1".into()],
        self_test: false,
        seconds: None,
        skew_ms: 10,
    };
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--self-test" => o.self_test = true,
            "--buses" => {
                let v = args.next().ok_or("--buses needs two names: A,B")?;
                let (a, b) = v.split_once(',').ok_or("--buses needs two names: A,B")?;
                o.buses = [a.to_string(), b.to_string()];
            }
            "--seconds" => {
                let v = args.next().ok_or("--seconds needs a number")?;
                o.seconds = Some(
                    v.parse()
                        .map_err(|_| format!("--seconds {v}: not a number"))?,
                );
            }
            "--skew-ms" => {
                let v = args.next().ok_or("--skew-ms needs a number")?;
                o.skew_ms = v
                    .parse()
                    .ok()
                    .filter(|ms| (1..=1000).contains(ms))
                    .ok_or(format!(
                        "--skew-ms {v}: a number of milliseconds, 1 to 1000"
                    ))?;
            }
            other => return Err(format!("unknown argument {other:?}")),
        }
    }
    Ok(o)
}

/// The interfaces exist and are up; otherwise what to type.
fn check_interfaces(buses: &[String; 2]) -> Result<(), String> {
    let mut missing = Vec::new();
    let mut down = Vec::new();
    for b in buses {
        match link_state(b) {
            LinkState::Missing => missing.push(b.as_str()),
            LinkState::Down => down.push(b.as_str()),
            LinkState::Up => {}
        }
    }
    if missing.is_empty() && down.is_empty() {
        return Ok(());
    }
    let mut msg = String::from("this example needs two CAN interfaces, up:");
    if !missing.is_empty() {
        msg += &format!("\n  missing: {}", missing.join(", "));
    }
    if !down.is_empty() {
        msg += &format!("\n  down: {}", down.join(", "));
    }
    msg += "\nCreate virtual ones (the kernel needs the vcan module) with:\n    sudo modprobe vcan";
    for b in &missing {
        msg += &format!("\n    sudo ip link add dev {b} type vcan");
    }
    for b in missing.iter().chain(&down) {
        msg += &format!("\n    sudo ip link set {b} up");
    }
    msg += "\nor name real ones with --buses can0,can1.";
    Err(msg)
}

fn station(id: u8, master: bool, skew_ms: u64) -> Dev {
    let mut od = comm::standard_dictionary(id, comm::Identity::default());
    let hb: u16 = if master { 0 } else { HB_MS };
    // The standard dictionary has these entries: the writes cannot fail.
    let _ = od.write_local(comm::HEARTBEAT_PRODUCER, 0, &hb.to_le_bytes());
    if master {
        let consume = (u32::from(SLAVE) << 16) | u32::from(CONSUMER_MS);
        let _ = od.write_local(comm::HEARTBEAT_CONSUMER, 1, &consume.to_le_bytes());
    }
    let nid = NodeId::must(id);
    let cfg = if master {
        NodeConfig::master(nid)
    } else {
        NodeConfig::slave(nid)
    };
    let mut bus = DualBusConfig::with_guard_period(
        LinkMode::ActiveActive,
        Duration::from_millis(HB_MS as u64),
    );
    bus.skew_window = Duration::from_millis(skew_ms);
    bus.health.tx_stall = bus.skew_window;
    let link = DualBus::new(bus);
    Station::new(link, Node::new(cfg, od))
}

fn start(
    name: &str,
    dev: Dev,
    buses: &[String; 2],
) -> Result<Handle<Dev>, Box<dyn std::error::Error>> {
    Ok(Runtime::new(dev)
        .name(name)
        .port(SocketCanPort::open(&buses[0])?)
        .port(SocketCanPort::open(&buses[1])?)
        .spawn()?)
}

/// One line per event worth telling.
fn describe(e: &Ev, buses: &[String; 2]) -> Option<String> {
    let bus = |p: usize| {
        format!(
            "bus {} ({})",
            p + 1,
            buses.get(p).map_or("?", |s| s.as_str())
        )
    };
    match e {
        RuntimeEvent::Port { port, status, .. } => match status {
            PortStatus::Down(c) => Some(format!("{}: port failed: {c}", bus(*port))),
            PortStatus::Up => Some(format!("{}: port recovered", bus(*port))),
            _ => None,
        },
        RuntimeEvent::Device(StationEvent::Link(l)) => match l.kind {
            LinkEventKind::Port { .. } => {
                // The event's own line starts with its instant; the runtime's clock is printed.
                let line = l.to_string();
                let what = line.split_once(": ").map_or(line.as_str(), |x| x.1);
                Some(format!("dual-bus layer: {what}"))
            }
            _ => None,
        },
        RuntimeEvent::Device(StationEvent::Machine(n)) => match n.kind {
            NodeEventKind::BootUp { node } => Some(format!("{node} booted")),
            NodeEventKind::RemoteState { node, to, .. } => Some(format!("{node} is {to:?}")),
            NodeEventKind::HeartbeatTimeout { node, .. } => {
                Some(format!("HEARTBEAT OF {node} LOST"))
            }
            NodeEventKind::HeartbeatResumed { node } => Some(format!("heartbeat of {node} back")),
            _ => None,
        },
    }
}

/// Prints what `who` reports, with the runtime's clock.
fn print_events(who: &'static str, h: &Handle<Dev>, buses: [String; 2]) {
    let mut rx = h.subscribe();
    let h = h.clone();
    tokio::spawn(async move {
        loop {
            match rx.recv().await {
                Ok(e) => {
                    if let Some(line) = describe(&e, &buses) {
                        println!(
                            "[{:>9.3} s] {who}: {line}",
                            h.now().as_micros() as f64 / 1e6
                        );
                    }
                }
                Err(broadcast::error::RecvError::Lagged(n)) => {
                    println!("{who}: {n} events not shown (printing fell behind)")
                }
                Err(broadcast::error::RecvError::Closed) => return,
            }
        }
    });
}

fn ip(args: &[&str]) -> Result<(), String> {
    let st = Command::new("ip")
        .args(args)
        .status()
        .map_err(|e| format!("cannot run ip: {e}"))?;
    if st.success() {
        Ok(())
    } else {
        Err(format!("ip {} failed ({st}): run as root", args.join(" ")))
    }
}

/// Brings the interface back up when dropped, whatever happened.
struct Restore(String);
impl Drop for Restore {
    fn drop(&mut self) {
        let _ = ip(&["link", "set", &self.0, "up"]);
    }
}

async fn wait_for<T>(
    rx: &mut broadcast::Receiver<Ev>,
    secs: u64,
    what: &str,
    mut pick: impl FnMut(&Ev) -> Option<T>,
) -> Result<T, String> {
    let r = tokio::time::timeout(StdDuration::from_secs(secs), async {
        loop {
            match rx.recv().await {
                Ok(e) => {
                    if let Some(t) = pick(&e) {
                        return Ok(t);
                    }
                }
                Err(broadcast::error::RecvError::Lagged(_)) => {}
                Err(broadcast::error::RecvError::Closed) => return Err("runtime closed".into()),
            }
        }
    })
    .await;
    r.unwrap_or_else(|_| Err(format!("no {what} within {secs} s")))
}

fn link_port(e: &Ev) -> Option<(usize, PortState)> {
    match e {
        RuntimeEvent::Device(StationEvent::Link(LinkEvent {
            kind: LinkEventKind::Port { port, to, .. },
            ..
        })) => Some((*port as usize, *to)),
        _ => None,
    }
}

fn rx(h: &Handle<Dev>, port: usize) -> u64 {
    h.port_counters(port).map_or(0, |c| c.rx_frames)
}

/// Takes bus `p` down and up, checking what must hold meanwhile.
async fn toggle(
    master: &Handle<Dev>,
    buses: &[String; 2],
    p: usize,
    ev: &mut broadcast::Receiver<Ev>,
) -> Result<(), String> {
    let other = 1 - p;
    let name = &buses[p];
    println!("== self-test: ip link set {name} down");
    ip(&["link", "set", name, "down"])?;
    let restore = Restore(name.clone());
    wait_for(ev, 5, &format!("port failure of {name}"), |e| match e {
        RuntimeEvent::Port {
            port,
            status: PortStatus::Down(_),
            ..
        } if *port == p => Some(()),
        _ => None,
    })
    .await?;
    wait_for(ev, 5, "the dual-bus layer failing the bus", |e| {
        (link_port(e) == Some((p, PortState::Failed))).then_some(())
    })
    .await?;
    // Behaviour, not speed (an emulated CPU may be slow): 15 frames must flow on the other bus.
    let flowed = frames_flow(master, other, 15).await.map_err(|n| {
        format!(
            "only {n} frames on {} in 20 s while {name} was down",
            buses[other]
        )
    })?;
    println!(
        "== self-test: {flowed} frames on {} while {name} was down",
        buses[other]
    );
    println!("== self-test: ip link set {name} up");
    drop(restore);
    wait_for(ev, 5, &format!("recovery of {name}"), |e| match e {
        RuntimeEvent::Port {
            port,
            status: PortStatus::Up,
            ..
        } if *port == p => Some(()),
        _ => None,
    })
    .await?;
    wait_for(ev, 10, "the dual-bus layer trusting the bus again", |e| {
        (link_port(e) == Some((p, PortState::Ok))).then_some(())
    })
    .await?;
    let flowed = frames_flow(master, p, 5)
        .await
        .map_err(|n| format!("only {n} frames on {name} in 20 s after its repair"))?;
    println!("== self-test: {name} carries frames again ({flowed})");
    Ok(())
}

/// Waits until `n` more frames arrived on `port` (at most 20 s); the count, or what came.
async fn frames_flow(master: &Handle<Dev>, port: usize, n: u64) -> Result<u64, u64> {
    let before = rx(master, port);
    let until = tokio::time::Instant::now() + StdDuration::from_secs(20);
    loop {
        let flowed = rx(master, port) - before;
        if flowed >= n {
            return Ok(flowed);
        }
        if tokio::time::Instant::now() >= until {
            return Err(flowed);
        }
        tokio::time::sleep(StdDuration::from_millis(20)).await;
    }
}

/// `ev` and `watch` were subscribed before the slave was started: its change to operational
/// may come before this function runs, and an event sent before a subscription is not seen.
async fn self_test(
    master: &Handle<Dev>,
    buses: &[String; 2],
    mut ev: broadcast::Receiver<Ev>,
    mut watch: broadcast::Receiver<Ev>,
) -> Result<(), String> {
    // Counts lost heartbeats for the whole run (a lagging watcher counts as a failure too).
    let lost = Arc::new(AtomicUsize::new(0));
    let l = lost.clone();
    tokio::spawn(async move {
        loop {
            match watch.recv().await {
                Ok(RuntimeEvent::Device(StationEvent::Machine(n))) => {
                    if matches!(n.kind, NodeEventKind::HeartbeatTimeout { .. }) {
                        l.fetch_add(1, Ordering::Relaxed);
                    }
                }
                Ok(_) => {}
                Err(broadcast::error::RecvError::Lagged(_)) => {
                    l.fetch_add(1000, Ordering::Relaxed);
                }
                Err(broadcast::error::RecvError::Closed) => return,
            }
        }
    });
    wait_for(&mut ev, 5, "the slave's heartbeat", |e| match e {
        RuntimeEvent::Device(StationEvent::Machine(n)) => match n.kind {
            NodeEventKind::RemoteState { node, .. } if node.raw() == SLAVE => Some(()),
            _ => None,
        },
        _ => None,
    })
    .await?;
    for (p, bus) in buses.iter().enumerate() {
        frames_flow(master, p, 5)
            .await
            .map_err(|n| format!("heartbeats on both buses expected, got {n} on {bus}"))?;
    }
    for p in 0..2 {
        toggle(master, buses, p, &mut ev).await?;
    }
    tokio::time::sleep(StdDuration::from_millis(100)).await;
    match lost.load(Ordering::Relaxed) {
        0 => Ok(()),
        n if n >= 1000 => {
            Err("the event watcher fell behind: cannot tell whether a heartbeat was lost".into())
        }
        n => Err(format!("the master lost the slave's heartbeat {n} time(s)")),
    }
}

async fn run(o: Options) -> ExitCode {
    let handles = start("master", station(MASTER, true, o.skew_ms), &o.buses).and_then(|m| {
        Ok((
            m,
            start("slave", station(SLAVE, false, o.skew_ms), &o.buses)?,
        ))
    });
    let (master, slave) = match handles {
        Ok(h) => h,
        Err(e) => {
            eprintln!("dual_vcan_failover: {e}");
            return ExitCode::from(2);
        }
    };
    print_events("master", &master, o.buses.clone());
    print_events("slave ", &slave, o.buses.clone());
    let (ev, watch) = (master.subscribe(), master.subscribe());
    let _ = slave.boot().await;
    let _ = master.boot().await;
    let _ = master
        .nmt(NmtCommand::Start, NmtTarget::Node(NodeId::must(SLAVE)))
        .await;
    let code = if o.self_test {
        match self_test(&master, &o.buses, ev, watch).await {
            Ok(()) => {
                println!("dual_vcan_failover: self-test OK: both buses failed and recovered, no heartbeat lost");
                ExitCode::SUCCESS
            }
            Err(e) => {
                eprintln!("dual_vcan_failover: self-test FAILED: {e}");
                ExitCode::from(1)
            }
        }
    } else {
        println!(
            "running: try `sudo ip link set {} down` and `… up` (Ctrl-C to stop)",
            o.buses[0]
        );
        let mut tick = tokio::time::interval(StdDuration::from_secs(1));
        let mut left = o.seconds;
        loop {
            tick.tick().await;
            if left == Some(0) {
                break;
            }
            left = left.map(|s| s - 1);
            println!(
                "[{:>9.3} s] master received: bus 1 {} frames, bus 2 {} frames",
                master.now().as_micros() as f64 / 1e6,
                rx(&master, 0),
                rx(&master, 1)
            );
        }
        ExitCode::SUCCESS
    };
    master.shutdown().await;
    slave.shutdown().await;
    code
}

fn main() -> ExitCode {
    let o = match parse_args() {
        Ok(o) => o,
        Err(e) => return usage(&e),
    };
    if let Err(msg) = check_interfaces(&o.buses) {
        eprintln!("dual_vcan_failover: {msg}");
        return ExitCode::from(2);
    }
    match tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
    {
        Ok(rt) => rt.block_on(run(o)),
        Err(e) => {
            eprintln!("dual_vcan_failover: cannot start the async runtime: {e}");
            ExitCode::from(2)
        }
    }
}
