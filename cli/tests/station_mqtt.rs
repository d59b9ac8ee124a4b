//! The station's reports to the plant, against a real MQTT broker (Mosquitto, started by each
//! test on a free port of its own): a subscriber sees a failover as it happens and the
//! retained state after it; a broker that dies and comes back holds nothing up, gets the
//! state again, and the events the outbox could not hold are counted; a broker that hangs
//! holds nothing up either.
//!
//! Needs `mosquitto` (Debian's package of that name: `.ci/run` installs it); feature `peers`.

#[path = "station_mqtt/broker.rs"]
mod broker;
mod common;
use broker::{Broker, Sub};
#[path = "station_mqtt/station.rs"]
mod station;
use rumqttc::QoS;
use station::{log_until, metrics, metrics_until, station};
use std::process::Command;
use std::time::{Duration, Instant};

/// The subscribers' runtime (the test's own thread waits on the station's log).
fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap()
}

fn dir(name: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("duocan-mqtt-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A network on the simulated plant: `faulty` (bus 1 cut at 2 s, the running board of the pair
/// stopped at 4 s, the network closed at 6 s) or quiet (until stopped).
fn network(name: &str, faulty: bool) -> String {
    let buses = if faulty {
        "sim-pairs"
    } else {
        "sim-pairs:quiet"
    };
    format!(
        "[[network]]\nname = \"{name}\"\nbuses = \"{buses}\"\nnode_id = 1\nheartbeat_ms = 50\n\
         master_timeout_ms = 200\npairs = [[0x10, 0x50]]\npair_heartbeat_ms = 50\n\
         pair_timeout_ms = 200\n\n"
    )
}

fn json(text: &str) -> serde_json::Value {
    serde_json::from_str(text).unwrap_or_else(|e| panic!("{e}: {text}"))
}

/// A subscriber from before the start sees the station come online, the bus and the board
/// failovers as QoS 1 events, the running board go from A to B; one subscribing after sees
/// the retained state; a stop says offline.
#[test]
fn a_subscriber_sees_a_failover_and_the_retained_state_after_it() {
    let _one = common::one_station();
    runtime().block_on(failover());
}

async fn failover() {
    let d = dir("failover");
    let mut broker = Broker::new(&d);
    broker.start();
    let port = broker.port;
    let file = d.join("plant.toml");
    std::fs::write(
        &file,
        format!(
            "[station]\nname = \"plant\"\nmqtt = \"127.0.0.1:{port}\"\n\
             mqtt_prefix = \"t/ixl\"\n\n{}",
            network("east rack/1", true)
        ),
    )
    .unwrap();
    let mut early = Sub::new(port, "early", "t/ixl/#").await;
    let started = Instant::now();
    let (mut child, rx) = station(&file);
    let on = early
        .until(20, "status online", |g| g.topic == "t/ixl/status")
        .await;
    assert_eq!(on.text, "online");
    let net = "t/ixl/east_rack_1";
    early
        .until(30, "pair A running", |g| {
            g.topic == format!("{net}/pair/0x10") && g.text == "A"
        })
        .await;
    for (what, line) in [
        ("bus failover", "bus 1: failed (port down: interface down)"),
        ("board failover", "pair 0x10/0x50: B active"),
    ] {
        let e = early
            .until(30, what, |g| {
                g.topic == format!("{net}/events") && json(&g.text)["event"] == line
            })
            .await;
        assert_eq!(e.qos, QoS::AtLeastOnce, "{what}");
        assert_eq!(json(&e.text)["failover"], true, "{what}");
        assert!(!e.retain, "{what}: events are not retained");
    }
    let b = early
        .until(30, "pair B running", |g| {
            g.topic == format!("{net}/pair/0x10") && g.text == "B"
        })
        .await;
    assert_eq!(b.qos, QoS::AtLeastOnce);
    early
        .until(10, "a state with B running", |g| {
            g.topic == format!("{net}/state") && json(&g.text)["pairs"][0]["active"] == "B"
        })
        .await;
    // The running board as published, in order: A, then B (after none while booting).
    let mut boards: Vec<&str> = early
        .seen
        .iter()
        .filter(|g| g.topic == format!("{net}/pair/0x10"))
        .map(|g| g.text.as_str())
        .collect();
    boards.dedup();
    assert!(boards.ends_with(&["A", "B"]), "{boards:?}");
    // A latecomer gets the retained topics at once.
    let mut late = Sub::new(port, "late", "t/ixl/#").await;
    for topic in [
        "t/ixl/status".to_string(),
        format!("{net}/pair/0x10"),
        format!("{net}/state"),
    ] {
        let g = late.until(10, &topic, |g| g.topic == topic).await;
        assert!(g.retain, "{topic} not retained");
        match topic.rsplit('/').next() {
            Some("status") => assert_eq!(g.text, "online"),
            Some("0x10") => assert_eq!(g.text, "B"),
            _ => {
                // Open and B running, or (the plant's script over) closed.
                let s = json(&g.text);
                assert_eq!(s["network"], "east rack/1");
                assert!(s["open"] == false || s["pairs"][0]["active"] == "B", "{s}");
            }
        }
    }
    let pid = child.id().to_string();
    assert!(Command::new("kill")
        .args(["-TERM", &pid])
        .status()
        .unwrap()
        .success());
    let off = late
        .until(20, "status offline", |g| {
            g.topic == "t/ixl/status" && g.text == "offline"
        })
        .await;
    assert!(!off.retain);
    let status = child.wait().unwrap();
    let log: Vec<String> = rx.try_iter().collect();
    assert_eq!(status.code(), Some(0), "{}", log.join("\n"));
    eprintln!("failover test: {:.1} s", started.elapsed().as_secs_f64());
    let _ = std::fs::remove_dir_all(&d);
}

const STEADY_RX: &str =
    "duocan_port_rx_frames_total{network=\"steady\",bus=\"2\",port=\"sim-bus2\"}";

/// The broker away at the start (a failing plant's events overflow the outbox of 2, counted),
/// then there (the state arrives), then killed (the station goes on: its buses' frames keep
/// being counted) and started again, empty: the station connects again and republishes the
/// retained state. A station killed outright is said offline by its last will.
#[test]
fn a_broker_that_goes_away_holds_nothing_up_and_gets_the_state_again() {
    let _one = common::one_station();
    runtime().block_on(away());
}

async fn away() {
    let d = dir("away");
    let mut broker = Broker::new(&d);
    let port = broker.port;
    let file = d.join("away.toml");
    std::fs::write(
        &file,
        format!(
            "[station]\nname = \"away\"\nhttp = \"127.0.0.1:0\"\nmqtt = \"127.0.0.1:{port}\"\n\
             mqtt_outbox = 2\n\n{}{}",
            network("steady", false),
            network("faulty", true)
        ),
    )
    .unwrap();
    let started = Instant::now();
    let (mut child, rx) = station(&file);
    let mut log = vec![];
    let addr = log_until(&rx, &mut log, 60, "http listening on ")
        .rsplit(' ')
        .next()
        .unwrap()
        .to_string();
    // No broker yet: the failing plant's events (some tens) overflow the outbox.
    log_until(&rx, &mut log, 60, "pair 0x10/0x50: B active network=faulty");
    log_until(&rx, &mut log, 10, "mqtt: the outbox is full");
    let before = metrics_until(&addr, 10, "drops counted", |m| {
        m.get("duocan_mqtt_dropped_total").is_some_and(|&n| n > 0)
    });
    assert_eq!(before["duocan_mqtt_connected"], 0);
    assert_eq!(before["duocan_mqtt_connections_total"], 0);

    // The broker comes: the state is sent (the latest, whatever was dropped).
    broker.start();
    let mut sub = Sub::new(port, "first", "duocan/away/#").await;
    sub.until(20, "online", |g| {
        g.topic == "duocan/away/status" && g.text == "online"
    })
    .await;
    sub.until(20, "faulty's board B", |g| {
        g.topic == "duocan/away/faulty/pair/0x10" && g.text == "B"
    })
    .await;
    sub.until(20, "steady's state", |g| {
        g.topic == "duocan/away/steady/state" && json(&g.text)["pairs"][0]["active"] == "A"
    })
    .await;

    // Killed: the station notices, and its buses go on.
    broker.kill();
    let down = metrics_until(&addr, 20, "broker lost", |m| {
        m["duocan_mqtt_connected"] == 0
    });
    metrics_until(&addr, 20, "frames counted while the broker is away", |m| {
        m[STEADY_RX] > down[STEADY_RX]
    });
    assert_eq!(down["duocan_mqtt_connections_total"], 1);

    // Back, without its retained messages (no persistence): the station gives them again.
    broker.start();
    metrics_until(&addr, 20, "connected again", |m| {
        m["duocan_mqtt_connections_total"] == 2 && m["duocan_mqtt_connected"] == 1
    });
    let want = [
        ("duocan/away/status", "online"),
        ("duocan/away/faulty/pair/0x10", "B"),
        ("duocan/away/steady/pair/0x10", "A"),
    ];
    let mut again = Sub::new(port, "again", "duocan/away/#").await;
    for (topic, text) in want {
        again
            .until(20, topic, |g| g.topic == topic && g.text == text)
            .await;
    }
    // The broker holds them now: one more subscriber gets them as retained messages.
    let mut last = Sub::new(port, "last", "duocan/away/#").await;
    for (topic, text) in want {
        let g = last.until(10, topic, |g| g.topic == topic).await;
        assert_eq!((g.text.as_str(), g.retain), (text, true), "{topic}");
    }
    let state = last
        .until(10, "steady's state", |g| {
            g.topic == "duocan/away/steady/state"
        })
        .await;
    assert!(state.retain);
    assert_eq!(json(&state.text)["role"], "active");

    // Killed outright: the broker says offline for it (the last will).
    let _ = child.kill();
    let _ = child.wait();
    let will = last
        .until(20, "the last will", |g| {
            g.topic == "duocan/away/status" && g.text == "offline"
        })
        .await;
    assert_eq!(will.qos, QoS::AtLeastOnce);
    // Both connections logged (every line is read before the stream ends with the station).
    let connected = |log: &Vec<String>| {
        log.iter()
            .filter(|l| l.contains("mqtt: connected to"))
            .count()
    };
    while connected(&log) < 2 {
        match rx.recv_timeout(Duration::from_secs(10)) {
            Ok(l) => log.push(l),
            Err(_) => panic!("two connections not logged:\n{}", log.join("\n")),
        }
    }
    eprintln!("broker-away test: {:.1} s", started.elapsed().as_secs_f64());
    let _ = std::fs::remove_dir_all(&d);
}

/// A broker that hangs (SIGSTOP: its connections stay open, nothing is read) holds nothing up:
/// the failing plant's board failover happens and is logged, the HTTP status answers, and the
/// station stops at once on SIGTERM; the broker, going on, says it offline.
#[test]
fn a_hung_broker_holds_nothing_up() {
    let _one = common::one_station();
    runtime().block_on(hung());
}

async fn hung() {
    let d = dir("hung");
    let mut broker = Broker::new(&d);
    broker.start();
    let port = broker.port;
    let file = d.join("hung.toml");
    std::fs::write(
        &file,
        format!(
            "[station]\nname = \"hung\"\nhttp = \"127.0.0.1:0\"\nmqtt = \"127.0.0.1:{port}\"\n\n{}",
            network("faulty", true)
        ),
    )
    .unwrap();
    let mut sub = Sub::new(port, "watcher", "duocan/hung/#").await;
    let started = Instant::now();
    let (mut child, rx) = station(&file);
    let mut log = vec![];
    let addr = log_until(&rx, &mut log, 60, "http listening on ")
        .rsplit(' ')
        .next()
        .unwrap()
        .to_string();
    log_until(&rx, &mut log, 20, "mqtt: connected to");
    // Hung before the plant's failures (from 2 s on).
    broker.signal("STOP");
    log_until(&rx, &mut log, 30, "pair 0x10/0x50: B active network=faulty");
    let m = metrics(&addr);
    assert!(m.contains_key("duocan_mqtt_connected"), "{m:#?}");
    let pid = child.id().to_string();
    let asked = Instant::now();
    assert!(Command::new("kill")
        .args(["-TERM", &pid])
        .status()
        .unwrap()
        .success());
    let end = asked + Duration::from_secs(10);
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        assert!(
            Instant::now() < end,
            "the station did not stop in 10 s with its broker hung"
        );
        std::thread::sleep(Duration::from_millis(20));
    };
    let stop_took = asked.elapsed();
    assert_eq!(status.code(), Some(0));
    // Going on, the broker tells its subscribers the station is gone (its own goodbye, or the
    // last will of a connection it finds broken).
    broker.signal("CONT");
    sub.until(20, "offline, once the broker goes on", |g| {
        g.topic == "duocan/hung/status" && g.text == "offline"
    })
    .await;
    eprintln!(
        "hung-broker test: {:.1} s (stopped in {:.1} s)",
        started.elapsed().as_secs_f64(),
        stop_took.as_secs_f64()
    );
    let _ = std::fs::remove_dir_all(&d);
}
