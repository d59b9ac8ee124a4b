//! In a real terminal: tmux runs the monitor in a 160×50 pane, the test reads the screen
//! (`capture-pane`), presses keys (`send-keys`) and asserts on what is shown. Without tmux the
//! test fails (CI installs it): a terminal test that skips proves nothing.

use super::STATION;
use std::process::{Command, Output};
use std::time::{Duration, Instant};

/// How long to wait for the screen to show something.
const WAIT: Duration = Duration::from_secs(10);

/// A tmux server of its own (its own socket, no user configuration), killed when dropped.
struct Tmux {
    socket: String,
}

impl Tmux {
    /// Starts `cmd` in a detached 160×50 session named `mon`.
    fn start(name: &str, cmd: &str) -> Tmux {
        let t = Tmux {
            socket: format!("duocan-test-{}-{name}", std::process::id()),
        };
        let o = t.run(&[
            "new-session",
            "-d",
            "-s",
            "mon",
            "-x",
            "160",
            "-y",
            "50",
            cmd,
        ]);
        assert!(
            o.status.success(),
            "tmux new-session failed: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        t
    }

    fn run(&self, args: &[&str]) -> Output {
        match Command::new("tmux")
            .args(["-L", &self.socket, "-f", "/dev/null"])
            .args(args)
            .env_remove("TMUX")
            .output()
        {
            Ok(o) => o,
            Err(e) => panic!(
                "cannot run tmux ({e}): this test needs tmux (apt-get install tmux); \
                 .ci/run installs it"
            ),
        }
    }

    /// The pane's text now.
    fn screen(&self) -> String {
        let o = self.run(&["capture-pane", "-p", "-t", "mon"]);
        String::from_utf8_lossy(&o.stdout).into_owned()
    }

    /// Presses keys (tmux key names, or text).
    fn keys(&self, keys: &[&str]) {
        let mut args = vec!["send-keys", "-t", "mon"];
        args.extend_from_slice(keys);
        let o = self.run(&args);
        assert!(o.status.success(), "tmux send-keys {keys:?} failed");
    }

    /// Types `text` as it is (`0x05` would otherwise be read as a key code: Ctrl-E).
    fn type_text(&self, text: &str) {
        let o = self.run(&["send-keys", "-t", "mon", "-l", text]);
        assert!(o.status.success(), "tmux send-keys -l {text:?} failed");
    }

    /// Waits until the screen satisfies `ok`; fails with the screen if it does not in time.
    fn wait_for(&self, what: &str, ok: impl Fn(&str) -> bool) -> String {
        let start = Instant::now();
        loop {
            let s = self.screen();
            if ok(&s) {
                return s;
            }
            if start.elapsed() > WAIT {
                panic!("the screen did not show {what} within {WAIT:?}; it shows:\n{s}");
            }
            std::thread::sleep(Duration::from_millis(100));
        }
    }
}

impl Drop for Tmux {
    fn drop(&mut self) {
        // Not through `run`: a missing tmux has already failed the test, once is enough.
        let _ = Command::new("tmux")
            .args(["-L", &self.socket, "kill-server"])
            .output();
    }
}

/// The command the pane runs: the monitor, then its exit status, kept on screen.
fn monitor_cmd(bus: &str) -> String {
    format!(
        "env -u DUOCAN_BUS {} --bus {bus} monitor --duration 60; echo EXIT=$?; sleep 60",
        env!("CARGO_BIN_EXE_duocan")
    )
}

/// The lines of the nodes panel that show a node row (`│0x05  pre-operational …`).
fn node_rows(screen: &str) -> Vec<String> {
    screen
        .lines()
        .filter_map(|l| l.strip_prefix('│'))
        .filter(|l| l.starts_with("0x") && l.as_bytes().get(4) == Some(&b' '))
        .map(|l| l.chars().take(40).collect())
        .collect()
}

/// The header's time of day (`08:21:03.120`).
fn clock(screen: &str) -> String {
    let head = screen.lines().next().unwrap_or_default();
    head.split_whitespace()
        .find(|w| w.len() == 12 && w.as_bytes()[2] == b':')
        .unwrap_or_default()
        .to_string()
}

/// The cells of port `name`'s row in the ports panel (name, state, rx, tx, errors).
fn port_row(screen: &str, name: &str) -> Vec<String> {
    let line = screen
        .lines()
        .find(|l| l.contains(&format!("│{name} ")))
        .unwrap_or_else(|| panic!("no row of port {name}:\n{screen}"));
    let cell = line.rsplit('│').nth(1).unwrap_or_default();
    cell.split_whitespace().map(String::from).collect()
}

#[test]
fn the_monitor_in_a_real_terminal_shows_the_panels_and_obeys_the_keys() {
    let t = Tmux::start("keys", &monitor_cmd("sim-station"));
    // Settled: every node in its state, the B members (powered at 1 s) standby.
    let s = t.wait_for("the station's nodes in their states", |s| {
        STATION
            .iter()
            .all(|(id, state)| s.contains(&format!("│{id:#04x}  {state} ")))
            && node_rows(s).len() == STATION.len()
    });
    assert!(
        s.contains("duocan monitor") && s.contains("bus sim-station"),
        "{s}"
    );
    assert!(s.contains("Nodes (9)") && s.contains("Heard on"), "{s}");
    assert!(s.contains("duocan simulated node"), "the device name:\n{s}");
    // The ports panel: both buses, ok, counting (listen-only: nothing sent).
    assert!(
        s.contains("Ports") && s.contains("Rx") && s.contains("Errors"),
        "{s}"
    );
    for name in ["sim-bus1", "sim-bus2"] {
        let cells = port_row(&s, name);
        assert_eq!(cells[1], "ok", "{cells:?}");
        assert!(
            cells[2].parse::<u64>().unwrap() > 0,
            "rx counted: {cells:?}"
        );
        assert_eq!(cells[3], "0", "nothing sent: {cells:?}");
    }
    // The redundancy panel: the master of the 0x71 frame, the pairs' roles.
    let s = t.wait_for("the master and both pairs' roles", |s| {
        s.contains("Master: 0x01 (priority 0), heartbeat ")
            && s.contains("│0x10/0x50   0x10        0x50")
            && s.contains("│0x11/0x51   0x11        0x51")
    });
    assert!(s.contains("Redundancy") && s.contains("Events ("), "{s}");
    assert!(
        s.contains("q quit") && s.contains("p pause"),
        "the footer:\n{s}"
    );

    // p: PAUSED, and the view stands still (its clock too) while paused.
    t.keys(&["p"]);
    let paused = t.wait_for("PAUSED", |s| {
        s.lines().next().unwrap_or("").contains("PAUSED")
    });
    std::thread::sleep(Duration::from_millis(600));
    let later = t.screen();
    assert_eq!(
        clock(&paused),
        clock(&later),
        "paused, yet the clock moved:\n{later}"
    );
    assert!(!clock(&later).is_empty(), "{later}");
    t.keys(&["p"]);
    t.wait_for("the view running again", |s| {
        !s.contains("PAUSED") && clock(s) != clock(&later)
    });

    // /0x05 Enter: only the matching node row and events.
    t.keys(&["/"]);
    t.type_text("0x05");
    t.keys(&["Enter"]);
    let s = t.wait_for("only node 0x05", |s| node_rows(s).len() == 1);
    assert!(node_rows(&s)[0].starts_with("0x05  pre-operational"), "{s}");
    assert!(
        s.contains("Nodes (1 of 9)") && s.contains("filter: 0x05"),
        "{s}"
    );
    let events: Vec<&str> = s
        .lines()
        .filter(|l| l.starts_with('│') && l.contains("  node 0x"))
        .collect();
    assert!(!events.is_empty(), "the matching event:\n{s}");
    assert!(
        events.iter().all(|l| l.contains("node 0x05")),
        "only matching events:\n{s}"
    );
    // c: the events are cleared.
    t.keys(&["c"]);
    t.wait_for("no events", |s| s.contains("Events (0)"));

    // q: the monitor exits with 0.
    t.keys(&["q"]);
    t.wait_for("EXIT=0", |s| s.contains("EXIT=0"));
}

#[test]
fn the_fault_script_s_port_failure_pair_failover_and_master_failover_show_on_screen() {
    let t = Tmux::start("faults", &monitor_cmd("sim-station:faults"));
    // 2 s into the script bus 1 is cut: its port fails, the nodes are heard on bus 2 only.
    let s = t.wait_for("bus 1 failed", |s| {
        s.contains("│sim-bus1 ") && port_row(s, "sim-bus1")[1] == "failed"
    });
    assert_eq!(port_row(&s, "sim-bus2")[1], "ok", "{s}");
    assert!(s.contains("bus 1: failed (port down"), "the event:\n{s}");
    // 4 s: plugged back in, ok again.
    t.wait_for("bus 1 ok again", |s| port_row(s, "sim-bus1")[1] == "ok");
    // 5 s: pair 0x10/0x50's active member stops; 0x50 takes over.
    let s = t.wait_for("the pair's failover", |s| {
        s.contains("│0x10/0x50   0x50 ")
            && s.contains("monitor: pair 0x10/0x50: failover: 0x50 active (was 0x10)")
    });
    assert!(s.contains("│0x50  operational"), "{s}");
    // 8 s: the active master stops; 0x02 takes over.
    t.wait_for("the master's failover", |s| {
        s.contains("Master: 0x02") && s.contains("monitor: active master now 0x02 (was 0x01)")
    });
    t.keys(&["q"]);
    t.wait_for("EXIT=0", |s| s.contains("EXIT=0"));
}
