//! A Mosquitto of the test's own, and subscribers to it.

use rumqttc::{AsyncClient, Event, MqttOptions, Packet, QoS};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// The Mosquitto binary: on PATH, or where Debian puts it.
fn mosquitto() -> String {
    if let Ok(o) = Command::new("sh")
        .args(["-c", "command -v mosquitto"])
        .output()
    {
        let p = String::from_utf8_lossy(&o.stdout).trim().to_string();
        if !p.is_empty() {
            return p;
        }
    }
    let sbin = "/usr/sbin/mosquitto";
    assert!(
        std::path::Path::new(sbin).exists(),
        "mosquitto not found: apt-get install mosquitto (.ci/run does)"
    );
    sbin.into()
}

/// A Mosquitto of the test's own, on loopback, killed when dropped.
pub struct Broker {
    pub port: u16,
    conf: std::path::PathBuf,
    child: Option<Child>,
}

impl Broker {
    pub fn new(dir: &std::path::Path) -> Broker {
        let port = std::net::TcpListener::bind("127.0.0.1:0")
            .and_then(|l| l.local_addr())
            .expect("a free port")
            .port();
        let conf = dir.join("mosquitto.conf");
        std::fs::write(
            &conf,
            format!("listener {port} 127.0.0.1\nallow_anonymous true\npersistence false\n"),
        )
        .unwrap();
        Broker {
            port,
            conf,
            child: None,
        }
    }

    /// Starts it and waits until it accepts connections (10 s at most).
    pub fn start(&mut self) {
        let child = Command::new(mosquitto())
            .arg("-c")
            .arg(&self.conf)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("start mosquitto");
        self.child = Some(child);
        let end = Instant::now() + Duration::from_secs(10);
        while std::net::TcpStream::connect(("127.0.0.1", self.port)).is_err() {
            assert!(Instant::now() < end, "mosquitto not listening in 10 s");
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// Sends it `sig` (`STOP`: it hangs, its connections open; `CONT`: it goes on).
    pub fn signal(&self, sig: &str) {
        let pid = self
            .child
            .as_ref()
            .expect("a running broker")
            .id()
            .to_string();
        let sent = Command::new("kill")
            .args([&format!("-{sig}"), &pid])
            .status()
            .expect("kill");
        assert!(sent.success(), "kill -{sig} {pid}");
    }

    /// Kills it (SIGKILL: no goodbye to its clients).
    pub fn kill(&mut self) {
        if let Some(mut c) = self.child.take() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

impl Drop for Broker {
    fn drop(&mut self) {
        self.kill();
    }
}

/// One message a subscriber got.
#[derive(Clone, Debug)]
pub struct Got {
    pub topic: String,
    pub text: String,
    pub qos: QoS,
    pub retain: bool,
}

/// A subscriber to `filter`, its messages in order.
pub struct Sub {
    rx: tokio::sync::mpsc::UnboundedReceiver<Got>,
    pub seen: Vec<Got>,
}

impl Sub {
    /// Connects and subscribes with QoS 1, waiting for the broker's acknowledgement.
    pub async fn new(port: u16, id: &str, filter: &str) -> Sub {
        let mut o = MqttOptions::new(id, "127.0.0.1", port);
        o.set_max_packet_size(1 << 20, 1 << 20);
        let (client, mut el) = AsyncClient::new(o, 16);
        client.subscribe(filter, QoS::AtLeastOnce).await.unwrap();
        let (tx, rx) = tokio::sync::mpsc::unbounded_channel();
        let (acked, ack) = tokio::sync::oneshot::channel();
        tokio::spawn(async move {
            let _client = client;
            let mut acked = Some(acked);
            while let Ok(e) = el.poll().await {
                match e {
                    Event::Incoming(Packet::SubAck(_)) => {
                        if let Some(a) = acked.take() {
                            let _ = a.send(());
                        }
                    }
                    Event::Incoming(Packet::Publish(p)) => {
                        let got = Got {
                            topic: p.topic.clone(),
                            text: String::from_utf8_lossy(&p.payload).into_owned(),
                            qos: p.qos,
                            retain: p.retain,
                        };
                        if tx.send(got).is_err() {
                            return;
                        }
                    }
                    _ => {}
                }
            }
        });
        tokio::time::timeout(Duration::from_secs(10), ack)
            .await
            .expect("no SUBACK in 10 s")
            .expect("subscriber gone");
        Sub { rx, seen: vec![] }
    }

    /// The first message (seen before, or to come within `secs`) that `want` accepts.
    pub async fn until(&mut self, secs: u64, what: &str, want: impl Fn(&Got) -> bool) -> Got {
        if let Some(g) = self.seen.iter().find(|g| want(g)) {
            return g.clone();
        }
        let end = tokio::time::Instant::now() + Duration::from_secs(secs);
        loop {
            match tokio::time::timeout_at(end, self.rx.recv()).await {
                Ok(Some(g)) => {
                    self.seen.push(g.clone());
                    if want(&g) {
                        return g;
                    }
                }
                _ => panic!("{what}: not in {secs} s; got:\n{}", self.dump()),
            }
        }
    }

    pub fn dump(&self) -> String {
        let line = |g: &Got| format!("{} q{:?} r{} {}", g.topic, g.qos, g.retain, g.text);
        self.seen.iter().map(line).collect::<Vec<_>>().join("\n")
    }
}
