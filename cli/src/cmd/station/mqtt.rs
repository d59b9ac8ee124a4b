//! The station's reports to the plant: every network's state and events, published to an MQTT
//! broker (MQTT 3.1.1 over TCP) named by the station file's `mqtt` key.
//!
//! # Topics
//!
//! `PREFIX` is `mqtt_prefix` (default `duocan/STATION`); `NETWORK` is the network's name made a
//! topic level: ASCII letters, digits, `-` and `_` are kept, every other character (a space,
//! `/`, `+`, `#`, …) becomes `_` — `turnout rack` is `turnout_rack` — the same rule as the
//! audit files' names. `station check` refuses two networks that would share a level.
//!
//! | topic | payload | QoS | retained |
//! |---|---|---|---|
//! | `PREFIX/status` | `online`, or `offline` (on a clean stop, and as the connection's last will when the station dies) | 1 | yes |
//! | `PREFIX/NETWORK/state` | JSON: the network now (below) | 1 | yes |
//! | `PREFIX/NETWORK/pair/0xAA` | the running board of the pair whose A node is 0xAA: `A`, `B` or `none` | 1 | yes |
//! | `PREFIX/NETWORK/events` | JSON: one event (below) | 1 | no |
//!
//! A state:
//!
//! ```json
//! {"network": "turnout rack", "buses": "can0,can1", "open": true, "role": "active",
//!  "ports": [{"bus": 1, "name": "can0", "state": "ok"}, {"bus": 2, "name": "can1", "state": "ok"}],
//!  "pairs": [{"pair": "0x11/0x21", "active": "A"}]}
//! ```
//!
//! (`open` false, with nothing else known, once the network has closed; while `status` is
//! `offline`, the state is the last one the station gave). An event, as the log
//! line says it, with the wall-clock time in Unix milliseconds:
//!
//! ```json
//! {"wall_ms": 1765090000125, "failover": true, "event": "bus 1: failed (port down: interface down)"}
//! ```
//!
//! and `{"wall_ms": …, "missed": N}` when the station's reader fell behind the network's
//! bounded event queue. A state is republished, coalesced, after the events that may change it
//! ([`STATE_EVERY`] at most).
//!
//! # A broker that goes away never holds the CAN side up
//!
//! The networks never see the publisher: a watcher per network reads its bounded event stream
//! (as the log and the HTTP stream do; one that falls behind is told how many it missed, the
//! network never waits for it) and hands messages to a bounded outbox without waiting; one task
//! of its own sends them to the broker. While the broker is away, the outbox keeps at most
//! `mqtt_outbox` events: each one more drops the oldest, counted
//! (`duocan_mqtt_dropped_total` in `/metrics`, and a warning in the log). Retained state is
//! not queued but kept, latest per topic: it is sent once the broker is back, whatever was
//! dropped. Messages a broken connection leaves unacknowledged are counted as dropped too and
//! not resent (the session is clean: the broker forgets it as well).
//!
//! The connection is retried with a back-off from [`BACKOFF_FIRST`] doubling up to
//! [`BACKOFF_MAX`]; on each connection the whole retained state is republished (a restarted
//! broker may have lost it) and `status` says `online`.

mod network;

use super::config::Mqtt;
use super::http::Watched;
use rumqttc::{AsyncClient, Event, LastWill, MqttOptions, Packet, QoS, Request};
use std::collections::{BTreeMap, BTreeSet, VecDeque};
use std::fmt::Write as _;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, OnceLock};
use std::time::Duration;
use tokio::sync::{watch, Notify};

/// The first wait before connecting again.
pub const BACKOFF_FIRST: Duration = Duration::from_millis(200);
/// The longest wait before connecting again.
pub const BACKOFF_MAX: Duration = Duration::from_secs(5);
/// A network's state is published at most this often.
pub const STATE_EVERY: Duration = Duration::from_millis(100);
/// How long a stopping station tries to say `offline` before it closes the connection.
const STOP_WAIT: Duration = Duration::from_secs(2);

/// The counters `/metrics` shows.
#[derive(Default)]
pub struct Stats {
    /// Whether the broker is connected.
    pub connected: AtomicBool,
    /// Messages dropped: the outbox full, or unacknowledged on a broken connection.
    pub dropped: AtomicU64,
    /// Messages handed to the connection.
    pub sent: AtomicU64,
    /// Connections made.
    pub connections: AtomicU64,
}

/// The running publisher's counters, once one runs (one station per process).
static STATS: OnceLock<Arc<Stats>> = OnceLock::new();

/// The MQTT lines of `/metrics` (none when the station has no broker).
pub fn metrics(out: &mut String) {
    let Some(s) = STATS.get() else { return };
    let n = |a: &AtomicU64| a.load(Ordering::Relaxed);
    let connected = u64::from(s.connected.load(Ordering::Relaxed));
    let lines = [
        (
            "connected",
            "gauge",
            "Whether the MQTT broker is connected",
            connected,
        ),
        (
            "dropped_total",
            "counter",
            "MQTT messages dropped: outbox full, or unacknowledged on a broken connection",
            n(&s.dropped),
        ),
        (
            "sent_total",
            "counter",
            "MQTT messages handed to the broker's connection",
            n(&s.sent),
        ),
        (
            "connections_total",
            "counter",
            "Connections made to the MQTT broker",
            n(&s.connections),
        ),
    ];
    for (name, kind, help, v) in lines {
        let name = format!("duocan_mqtt_{name}");
        let _ = writeln!(
            out,
            "# HELP {name} {help}.\n# TYPE {name} {kind}\n{name} {v}"
        );
    }
}

/// One message to send.
struct Msg {
    topic: String,
    payload: Vec<u8>,
    retain: bool,
}

/// What waits to be sent: events in order (bounded), and the latest retained payload of each
/// topic with those not sent since they changed or since the last connection.
struct Outbox {
    events: VecDeque<Msg>,
    cap: usize,
    retained: BTreeMap<String, Vec<u8>>,
    dirty: BTreeSet<String>,
}

/// The networks' side of the publisher: never waits for the broker.
#[derive(Clone)]
pub struct Publisher {
    prefix: String,
    outbox: Arc<Mutex<Outbox>>,
    ready: Arc<Notify>,
    stats: Arc<Stats>,
}

impl Publisher {
    fn lock(&self) -> std::sync::MutexGuard<'_, Outbox> {
        self.outbox
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    /// Queues an event message; a full outbox drops its oldest.
    fn event(&self, topic: String, payload: Vec<u8>) {
        let dropped = {
            let mut o = self.lock();
            let full = o.events.len() >= o.cap;
            if full {
                o.events.pop_front();
            }
            o.events.push_back(Msg {
                topic,
                payload,
                retain: false,
            });
            full
        };
        if dropped && self.stats.dropped.fetch_add(1, Ordering::Relaxed) == 0 {
            tracing::warn!(target: "duocan::station", "mqtt: the outbox is full (the broker \
                is away): the oldest events are dropped and counted (duocan_mqtt_dropped_total)");
        }
        self.ready.notify_one();
    }

    /// Sets a retained topic's payload (sent if it changed).
    fn retain(&self, topic: String, payload: Vec<u8>) {
        {
            let mut o = self.lock();
            if o.retained.get(&topic) == Some(&payload) {
                return;
            }
            o.dirty.insert(topic.clone());
            o.retained.insert(topic, payload);
        }
        self.ready.notify_one();
    }

    /// The next message to send: changed retained state first, then the oldest event.
    fn next(&self) -> Option<Msg> {
        let mut o = self.lock();
        if let Some(topic) = o.dirty.pop_first() {
            let payload = o.retained.get(&topic).cloned().unwrap_or_default();
            return Some(Msg {
                topic,
                payload,
                retain: true,
            });
        }
        o.events.pop_front()
    }

    /// Marks the whole retained state to be sent again (a new connection).
    fn resend_retained(&self) {
        let mut o = self.lock();
        let all: BTreeSet<String> = o.retained.keys().cloned().collect();
        o.dirty = all;
        drop(o);
        self.ready.notify_one();
    }
}

/// The running publisher: its networks' side and the tasks that send.
pub struct Running {
    prefix: String,
    client: AsyncClient,
    connected: watch::Receiver<bool>,
    conn: tokio::task::JoinHandle<()>,
    tasks: tokio::task::JoinSet<()>,
}

/// Starts publishing `networks` of station `station` to the broker of `m`: the connection
/// (retried with back-off), its sender, and a watcher per network.
pub fn start(m: &Mqtt, networks: &[Arc<Watched>]) -> Running {
    let stats = STATS.get_or_init(|| Arc::new(Stats::default())).clone();
    let status = format!("{}/status", m.prefix);
    let mut opts = MqttOptions::new(m.client_id.clone(), m.host.clone(), m.port);
    opts.set_keep_alive(Duration::from_secs(5))
        .set_clean_session(true)
        // A state of a network of 110 pairs is some 4 KiB; room to spare.
        .set_max_packet_size(256 * 1024, 256 * 1024)
        .set_last_will(LastWill::new(&status, "offline", QoS::AtLeastOnce, true));
    if let Some((u, p)) = &m.login {
        opts.set_credentials(u.clone(), p.clone());
    }
    // The connection's own queue is small: the outbox is where messages wait.
    let (client, eventloop) = AsyncClient::new(opts, 16);
    let publisher = Publisher {
        prefix: m.prefix.clone(),
        outbox: Arc::new(Mutex::new(Outbox {
            events: VecDeque::new(),
            cap: m.outbox,
            retained: BTreeMap::new(),
            dirty: BTreeSet::new(),
        })),
        ready: Arc::new(Notify::new()),
        stats,
    };
    publisher.retain(status, b"online".to_vec());
    let (tx, connected) = watch::channel(false);
    let mut tasks = tokio::task::JoinSet::new();
    let broker = format!("{}:{}", m.host, m.port);
    tracing::info!(target: "duocan::station", "mqtt: publishing to {broker} under {}/", m.prefix);
    let conn = tokio::spawn(connection(eventloop, publisher.clone(), tx, broker));
    tasks.spawn(sender(client.clone(), publisher.clone(), connected.clone()));
    for w in networks {
        tasks.spawn(network::watch(w.clone(), publisher.clone()));
    }
    Running {
        prefix: m.prefix.clone(),
        client,
        connected,
        conn,
        tasks,
    }
}

impl Running {
    /// Says `offline` and disconnects, if the broker is there within [`STOP_WAIT`].
    pub async fn stop(mut self) {
        self.tasks.abort_all();
        let status = format!("{}/status", self.prefix);
        let (client, conn) = (&self.client, &mut self.conn);
        let bye = async {
            if *self.connected.borrow() {
                // After what the sender handed over; the connection ends once the disconnect
                // has gone out.
                let _ = client
                    .publish(status, QoS::AtLeastOnce, true, "offline")
                    .await;
                let _ = client.disconnect().await;
                let _ = conn.await;
            }
        };
        let _ = tokio::time::timeout(STOP_WAIT, bye).await;
        self.conn.abort();
    }
}

/// Drives the connection: reconnects with back-off, republishes the retained state on each
/// connection, counts what a broken one leaves unacknowledged.
async fn connection(
    mut el: rumqttc::EventLoop,
    p: Publisher,
    connected: watch::Sender<bool>,
    broker: String,
) {
    let mut backoff = BACKOFF_FIRST;
    let mut told = false;
    loop {
        match el.poll().await {
            Ok(Event::Incoming(Packet::ConnAck(_))) => {
                backoff = BACKOFF_FIRST;
                told = false;
                p.stats.connections.fetch_add(1, Ordering::Relaxed);
                p.stats.connected.store(true, Ordering::Relaxed);
                tracing::info!(target: "duocan::station", "mqtt: connected to {broker}");
                p.resend_retained();
                connected.send_replace(true);
            }
            Ok(Event::Outgoing(rumqttc::Outgoing::Disconnect)) => return,
            Ok(_) => {}
            Err(e) => {
                let was = connected.send_replace(false);
                p.stats.connected.store(false, Ordering::Relaxed);
                // Not resent: the next session is a clean one.
                let lost = el
                    .pending
                    .drain(..)
                    .filter(|r| matches!(r, Request::Publish(_)))
                    .count() as u64;
                p.stats.dropped.fetch_add(lost, Ordering::Relaxed);
                if was || !told {
                    tracing::warn!(target: "duocan::station",
                        "mqtt: {broker}: {e}; trying again (every {} s at most)",
                        BACKOFF_MAX.as_secs());
                    told = true;
                }
                tokio::time::sleep(backoff).await;
                backoff = (backoff * 2).min(BACKOFF_MAX);
            }
        }
    }
}

/// Hands the outbox's messages to the connection while it is up.
async fn sender(client: AsyncClient, p: Publisher, mut connected: watch::Receiver<bool>) {
    loop {
        if connected.wait_for(|c| *c).await.is_err() {
            return;
        }
        let ready = p.ready.notified();
        let Some(m) = p.next() else {
            tokio::select! {
                () = ready => {}
                _ = connected.changed() => {}
            }
            continue;
        };
        if client
            .publish(m.topic, QoS::AtLeastOnce, m.retain, m.payload)
            .await
            .is_err()
        {
            return;
        }
        p.stats.sent.fetch_add(1, Ordering::Relaxed);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn publisher(cap: usize) -> Publisher {
        Publisher {
            prefix: "p".into(),
            outbox: Arc::new(Mutex::new(Outbox {
                events: VecDeque::new(),
                cap,
                retained: BTreeMap::new(),
                dirty: BTreeSet::new(),
            })),
            ready: Arc::new(Notify::new()),
            stats: Arc::new(Stats::default()),
        }
    }

    #[test]
    fn a_full_outbox_drops_its_oldest_and_counts_and_state_is_kept_latest() {
        let p = publisher(2);
        for i in 0..5u8 {
            p.event("p/n/events".into(), vec![i]);
            p.retain("p/n/state".into(), vec![i]);
        }
        assert_eq!(p.stats.dropped.load(Ordering::Relaxed), 3);
        let got: Vec<(String, Vec<u8>, bool)> = std::iter::from_fn(|| p.next())
            .map(|m| (m.topic, m.payload, m.retain))
            .collect();
        assert_eq!(
            got,
            [
                ("p/n/state".into(), vec![4], true),
                ("p/n/events".into(), vec![3], false),
                ("p/n/events".into(), vec![4], false),
            ]
        );
        // A new connection sends the retained state again; an unchanged one is not resent.
        p.retain("p/n/state".into(), vec![4]);
        assert!(p.next().is_none());
        p.resend_retained();
        assert_eq!(p.next().map(|m| m.payload), Some(vec![4]));
    }
}
