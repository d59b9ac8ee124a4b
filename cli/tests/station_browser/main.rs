//! The station's dashboard in a real browser: a headless Chromium (Debian's `chromium`) opens
//! the page of a station running the shipped demonstration's four racks
//! (`examples/station/demo.toml`), whose turnout rack's simulated plant fails, and the test
//! watches the page's DOM while the failover happens — the pair's running board turns from A
//! to B, bus 1 fails, the failover shows in the live events and in the timeline, the quiet
//! rack's board keeps running — then keeps a screenshot (its path is printed). Without the
//! token in its address, or with a wrong one, the page shows none of it. With the read token
//! the page offers no operator action; with the control token, the quiet rack's pair is
//! switched over from its button, confirmed on the page, and the page shows B running.
//!
//! Needs Chromium: run by `.ci/run` (`--features peers`), not by `cargo test --workspace`;
//! without Chromium it fails, saying what to install.

mod cdp;
#[path = "../common/mod.rs"]
mod common;

use serde_json::Value;
use std::io::{BufRead, BufReader};
use std::path::PathBuf;
use std::process::Child;
use std::time::{Duration, Instant};

const TOKEN: &str = "browser-test-token-0123456789";
const CONTROL: &str = "browser-control-token-0123456789";

/// The station, killed when dropped.
struct Station(Child);

impl Drop for Station {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// What the page shows of the two racks, read from its DOM by their data attributes.
const LOOK: &str = r#"(() => {
  const net = n => document.querySelector(`[data-network="${n}"]`);
  const look = n => {
    const e = net(n);
    if (!e) return null;
    const at = (s, k) => { const x = e.querySelector(s); return x ? x.getAttribute(k) : null; };
    return {
      role: e.dataset.role,
      bus1: at('[data-bus="1"]', "data-state"),
      bus2: at('[data-bus="2"]', "data-state"),
      pair: at('[data-pair="0x11"]', "data-running"),
      node: at('[data-node="0x11"]', "data-state"),
      timeline: [...e.querySelectorAll('li[data-event][data-failover="true"]')].map(l => l.textContent),
    };
  };
  return {
    turnout: look("turnout rack"),
    signal: look("signal rack"),
    live: [...document.querySelectorAll('#events li[data-event]')].map(l => `${l.dataset.network}: ${l.querySelector(".l").textContent}`),
    status: document.getElementById("status")?.textContent ?? null,
  };
})()"#;

/// Looks at the page until `done` holds, every 100 ms, for at most `limit`; panics with
/// what the page showed last if it never does.
fn until(
    b: &mut cdp::Browser,
    page: &str,
    what: &str,
    limit: Duration,
    done: impl Fn(&Value) -> bool,
) -> Value {
    let end = Instant::now() + limit;
    loop {
        let v = b.eval(page, LOOK);
        if done(&v) {
            return v;
        }
        assert!(
            Instant::now() < end,
            "the page never showed {what} in {limit:?}; it showed:\n{v:#}"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// Evaluates `js` on `page` every 100 ms until it gives `want`, for at most `limit`.
fn until_js(b: &mut cdp::Browser, page: &str, js: &str, want: &Value, limit: Duration) {
    let end = Instant::now() + limit;
    loop {
        let v = b.eval(page, js);
        if &v == want {
            return;
        }
        assert!(
            Instant::now() < end,
            "{js} never gave {want} in {limit:?}; it gave {v}"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// With the control token, the signal rack's pair is switched over from the page: the button
/// asks first, and once confirmed the pair's running board turns from A to B.
fn operate(b: &mut cdp::Browser, addr: &str, dir: &std::path::Path) {
    let page = b.open(&format!("http://{addr}/#token={CONTROL}"), 1280, 900);
    let button = r#"document.querySelector('[data-network="signal rack"] [data-pair="0x11"] button[data-action="switch"]')"#;
    until_js(
        b,
        &page,
        &format!("!!{button}"),
        &Value::Bool(true),
        Duration::from_secs(20),
    );
    let nmt = b.eval(
        &page,
        r#"document.querySelectorAll('[data-network="signal rack"] [data-node="0x11"] button[data-action="nmt"]').length"#,
    );
    assert_eq!(nmt, 4, "start, stop, preop and reset for each node");
    let asked = b.eval(
        &page,
        &format!("{button}.click(); [document.getElementById('confirm').hidden, document.getElementById('ask').textContent]"),
    );
    assert_eq!(
        asked,
        serde_json::json!([false, "switch pair 0x11 of signal rack over?"]),
        "no confirmation asked"
    );
    let running = |b: &mut cdp::Browser| b.eval(&page, LOOK)["signal"]["pair"].clone();
    assert_eq!(running(b), "A", "switched before the confirmation");
    b.eval(
        &page,
        r#"document.querySelector('#confirm [data-confirm="yes"]').click(); true"#,
    );
    let after = until(
        b,
        &page,
        "the signal rack's pair switched over",
        Duration::from_secs(20),
        |v| v["signal"]["pair"] == "B",
    );
    let said = b.eval(&page, "document.getElementById('result').textContent");
    eprintln!("switched over from the page: {} ({said})", after["signal"]);
    until_js(
        b,
        &page,
        "document.getElementById('result').textContent",
        &Value::from("switch pair 0x11 of signal rack over: done"),
        Duration::from_secs(20),
    );
    let shot = dir.join("dashboard-control.png");
    std::fs::write(&shot, b.screenshot(&page)).unwrap();
    eprintln!("screenshot with control: {}", shot.display());
}

#[test]
fn the_dashboard_shows_a_failover_as_it_happens() {
    let _one = common::one_station();
    let t0 = Instant::now();
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("station-browser");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    // The browser first, warm before the plant's script starts its clock.
    let mut b = cdp::Browser::start(&dir);
    // The shipped demonstration file's racks, under a station section of the test's own (an
    // address the system picks, the tokens) and with the boards' device files found from here.
    let examples = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../examples");
    let demo = std::fs::read_to_string(examples.join("station/demo.toml")).unwrap();
    let racks = &demo[demo.find("[[network]]").expect("the demo's networks")..];
    let racks = racks.replace(
        "\"../demo/devices/",
        &format!("\"{}/", examples.join("demo/devices").display()),
    );
    assert!(
        racks.contains("name = \"turnout rack\"\nbuses = \"sim-pairs:failover\""),
        "the demo's turnout rack no longer fails: {racks}"
    );
    let file = dir.join("demo.toml");
    std::fs::write(
        &file,
        format!(
            "[station]\nname = \"browser\"\nhttp = \"127.0.0.1:0\"\nhttp_token = \"{TOKEN}\"\n\
             http_control_token = \"{CONTROL}\"\n\n{racks}"
        ),
    )
    .unwrap();
    let mut child = crate::common::station_run(file.to_str().unwrap())
        .spawn()
        .expect("run duocan");
    let started = Instant::now();
    let (tx, rx) = std::sync::mpsc::channel();
    let stderr = child.stderr.take().expect("stderr");
    let station = Station(child);
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            if tx.send(line).is_err() {
                return;
            }
        }
    });
    let addr = loop {
        let line = rx
            .recv_timeout(Duration::from_secs(60))
            .expect("no http address from the station in 60 s");
        if let Some(a) = line.split("http listening on ").nth(1) {
            break a.trim().to_string();
        }
    };
    let page = b.open(&format!("http://{addr}/#token={TOKEN}"), 1280, 900);

    // Before the failover: both racks, this master active, each pair's A board running
    // (the running boards stop at 4 s: the page, open from the start, must see them before).
    let before = until(
        &mut b,
        &page,
        "both racks with A running",
        Duration::from_secs(20),
        |v| {
            ["turnout", "signal"].iter().all(|n| {
                v[n]["role"] == "active" && v[n]["pair"] == "A" && v[n]["node"] == "operational"
            })
        },
    );
    eprintln!(
        "A running on the page {:?} after the start: turnout rack {}, signal rack {}",
        started.elapsed(),
        before["turnout"],
        before["signal"]
    );

    // The plant cuts bus 1 at 2 s and stops the running boards at 4 s.
    let after = until(
        &mut b,
        &page,
        "the failover",
        Duration::from_secs(30),
        |v| {
            let t = &v["turnout"];
            let live = |s: &str| {
                v["live"]
                    .as_array()
                    .is_some_and(|l| l.iter().any(|e| e.as_str().is_some_and(|e| e.contains(s))))
            };
            let timeline = |s: &str| {
                t["timeline"]
                    .as_array()
                    .is_some_and(|l| l.iter().any(|e| e.as_str().is_some_and(|e| e.contains(s))))
            };
            t["pair"] == "B"
                && t["bus1"] != "ok"
                && live("turnout rack: bus 1: failed")
                && live("turnout rack: pair 0x11/0x21: B active")
                && timeline("pair 0x11/0x21: B active")
        },
    );
    eprintln!(
        "failover on the page {:?} after the start: turnout rack {}, signal rack {}, {} live events",
        started.elapsed(),
        after["turnout"],
        after["signal"],
        after["live"].as_array().map_or(0, Vec::len)
    );
    // The quiet rack's boards kept running. (Its buses are not looked at: on a machine short
    // of CPU a simulated bus may go quiet for longer than its timeout, which the page shows as
    // it should.)
    assert_eq!(after["signal"]["pair"], "A", "{after:#}");
    assert_eq!(after["signal"]["role"], "active", "{after:#}");

    // The read token's page offers no action, and only a button sends one, after its
    // confirmation on the page.
    let buttons = b.eval(
        &page,
        "document.querySelectorAll('button[data-action]').length",
    );
    assert_eq!(buttons, 0, "the read token's page offers actions");
    operate(&mut b, &addr, &dir);

    let png = b.screenshot(&page);
    assert!(png.starts_with(b"\x89PNG\r\n\x1a\n"), "not a PNG");
    let shot = dir.join("dashboard.png");
    std::fs::write(&shot, &png).unwrap();
    eprintln!("screenshot: {} ({} bytes)", shot.display(), png.len());

    // The same page without the token, or with a wrong one: it shows nothing of the station.
    for (url, says) in [
        (format!("http://{addr}/"), "needs a token"),
        (
            format!("http://{addr}/#token=not-{TOKEN}"),
            "token was refused",
        ),
    ] {
        let bare = b.open(&url, 800, 600);
        let end = Instant::now() + Duration::from_secs(20);
        let text = loop {
            let text = b.eval(&bare, "document.body ? document.body.innerText : ''");
            if text.as_str().is_some_and(|t| t.contains(says)) || Instant::now() > end {
                break text;
            }
            std::thread::sleep(Duration::from_millis(100));
        };
        assert!(
            text.as_str().is_some_and(|t| t.contains(says)),
            "{url}: {text}"
        );
        let nets = b.eval(&bare, "document.querySelectorAll('[data-network]').length");
        assert_eq!(nets, 0, "{url} shows networks");
    }
    drop(station);
    drop(b);
    eprintln!("browser test: {:?}", t0.elapsed());
}
