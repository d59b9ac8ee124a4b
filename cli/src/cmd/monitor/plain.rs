//! The monitor without a screen: one line per log line of the model (an event or an
//! observation) as it comes, and a status line every `--every` seconds; `--json` prints each as
//! one JSON object per line.

use super::model::{Logged, View};
use super::{lock, Session};
use crate::fail::Fail;
use crate::out::print_text;
use serde_json::{json, Value};
use std::collections::BTreeMap;
use std::time::Duration;

/// How often new lines are printed.
const POLL: Duration = Duration::from_millis(100);

/// Prints until the deadline or Ctrl-C.
pub async fn run(s: &Session, json: bool, every: Duration) -> Result<(), Fail> {
    let mut poll = tokio::time::interval(POLL);
    poll.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    let mut status = tokio::time::interval_at(tokio::time::Instant::now() + every, every);
    status.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    let ctrl_c = tokio::signal::ctrl_c();
    tokio::pin!(ctrl_c);
    let mut seq = 0;
    loop {
        let show_status = tokio::select! {
            _ = poll.tick() => false,
            _ = status.tick() => true,
            _ = &mut ctrl_c => break,
            () = s.until_deadline() => break,
        };
        seq = print_new(s, json, seq);
        if show_status {
            let now = s.bus.net.now();
            let view = lock(&s.model).view(now, "");
            let line = if json {
                format!("{}\n", status_json(s, now, &view))
            } else {
                format!("{}  {}\n", s.clock(now), status_text(&view))
            };
            print_text(&line);
        }
    }
    print_new(s, json, seq);
    Ok(())
}

/// Prints the log lines after `seq`; returns the last one printed.
fn print_new(s: &Session, json: bool, seq: u64) -> u64 {
    let now = s.bus.net.now();
    let (lines, missed) = {
        let mut m = lock(&s.model);
        m.tick(now);
        m.log_since(seq)
    };
    let mut text = String::new();
    if missed > 0 {
        text.push_str(&if json {
            format!("{}\n", json!({"kind": "missed", "lines": missed}))
        } else {
            format!("{}  monitor: {missed} lines missed\n", s.clock(now))
        });
    }
    for l in &lines {
        if json {
            text.push_str(&format!("{}\n", line_json(s, l)));
        } else {
            text.push_str(&format!("{}  {}\n", s.clock(l.at), l.text));
        }
    }
    if !text.is_empty() {
        print_text(&text);
    }
    lines.last().map_or(seq, |l| l.seq)
}

fn line_json(s: &Session, l: &Logged) -> Value {
    json!({
        "time": s.clock(l.at),
        "at_ms": l.at.as_micros() / 1_000,
        "kind": l.kind,
        "node": l.node,
        "text": l.text,
    })
}

/// `status: 10 nodes (7 pre-operational, 3 operational); port sim ok rx 12 tx 0 errors 0;
/// pair 0x10/0x50 active 0x10 standby 0x50; master 0x01 (priority 0), heartbeat 80 ms`
pub fn status_text(v: &View) -> String {
    let mut by_state: BTreeMap<&str, usize> = BTreeMap::new();
    for n in &v.nodes {
        *by_state.entry(n.state.as_str()).or_default() += 1;
    }
    let states: Vec<String> = by_state.iter().map(|(s, n)| format!("{n} {s}")).collect();
    let mut parts = vec![format!(
        "status: {} nodes ({})",
        v.nodes.len(),
        states.join(", ")
    )];
    for p in &v.ports {
        parts.push(format!(
            "port {} {} rx {} tx {} errors {}",
            p.name, p.state, p.rx, p.tx, p.errors
        ));
    }
    for p in &v.pairs {
        parts.push(if p.active == "not heard" {
            format!("pair {} not heard", p.pair)
        } else {
            format!("pair {} active {} standby {}", p.pair, p.active, p.standby)
        });
    }
    parts.push(format!("master {}", v.master));
    parts.join("; ")
}

fn status_json(s: &Session, now: duocan::Instant, v: &View) -> Value {
    let dash = |t: &str| (t != "-").then(|| t.to_string());
    json!({
        "time": s.clock(now),
        "at_ms": now.as_micros() / 1_000,
        "kind": "status",
        "nodes": v.nodes.iter().map(|n| json!({
            "node": n.node,
            "state": dash(&n.state),
            "heartbeat_age_ms": n.age_ms,
            "emcy": dash(&n.emcy),
            "name": dash(&n.name),
        })).collect::<Vec<_>>(),
        "ports": v.ports.iter().map(|p| json!({
            "name": p.name, "state": p.state, "rx": p.rx, "tx": p.tx, "errors": p.errors,
        })).collect::<Vec<_>>(),
        "pairs": v.pairs.iter().map(|p| json!({
            "members": p.members,
            "active": dash(&p.active),
            "standby": dash(&p.standby),
        })).collect::<Vec<_>>(),
        "master": v.master_info.map(|m| json!({"node": m.node, "priority": m.priority})),
    })
}
