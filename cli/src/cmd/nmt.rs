//! `duocan nmt start|stop|preop|reset|reset-comm NODE|all [--wait[=MS]]`: one NMT command, and
//! with `--wait` the node's answer (the state it reaches, or its boot-up after a reset).

use crate::args::{parse_target, parse_timeout_ms, Target};
use crate::fail::Fail;
use crate::out;
use crate::{bus, Global};
use duocan::{NmtCommand, NmtState};
use serde_json::json;
use std::time::Duration;

/// The NMT commands.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Action {
    /// Start: operational
    Start,
    /// Stop: stopped
    Stop,
    /// Enter pre-operational
    Preop,
    /// Reset the node (application and communication)
    Reset,
    /// Reset communication
    ResetComm,
}

impl Action {
    pub(crate) fn command(self) -> NmtCommand {
        match self {
            Action::Start => NmtCommand::Start,
            Action::Stop => NmtCommand::Stop,
            Action::Preop => NmtCommand::EnterPreOperational,
            Action::Reset => NmtCommand::ResetNode,
            Action::ResetComm => NmtCommand::ResetCommunication,
        }
    }
    /// The state the node is in once it obeyed (`None`: a reset, answered by a boot-up).
    fn state(self) -> Option<NmtState> {
        match self {
            Action::Start => Some(NmtState::Operational),
            Action::Stop => Some(NmtState::Stopped),
            Action::Preop => Some(NmtState::PreOperational),
            Action::Reset | Action::ResetComm => None,
        }
    }
    fn name(self) -> &'static str {
        match self {
            Action::Start => "start",
            Action::Stop => "stop",
            Action::Preop => "preop",
            Action::Reset => "reset",
            Action::ResetComm => "reset-comm",
        }
    }
}

/// The arguments of `duocan nmt`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The command
    #[arg(value_enum)]
    action: Action,
    /// A node-ID (1-127) or `all`
    #[arg(value_parser = parse_target)]
    target: Target,
    /// Wait for the node's answer (its new state by heartbeat, or its boot-up after a reset),
    /// up to MS milliseconds (default 3000); one node only
    #[arg(long, value_name = "MS", num_args = 0..=1, default_missing_value = "3000", value_parser = parse_timeout_ms)]
    wait: Option<u64>,
}

/// Runs `duocan nmt`.
pub async fn run(g: &Global, a: Args) -> Result<(), Fail> {
    if a.wait.is_some() && a.target == Target::All {
        return Err(Fail::usage("--wait takes one node, not `all`"));
    }
    let bus = bus::open(g, false)?;
    let r = send(g, &bus, &a).await;
    bus.close().await;
    r
}

async fn send(g: &Global, bus: &bus::Bus, a: &Args) -> Result<(), Fail> {
    let cmd = a.action.command();
    let (target_text, target_json) = match a.target {
        Target::All => ("all nodes".to_string(), json!("all")),
        Target::Node(id) => (format!("node {:#04x}", id.raw()), json!(id.raw())),
    };
    let Target::Node(id) = a.target else {
        bus.net.nmt_all(cmd).await?;
        out::result(
            g.json,
            &format!("NMT {} sent to {target_text}", a.action.name()),
            json!({"command": a.action.name(), "target": target_json}),
        );
        return Ok(());
    };
    let node = bus.net.node(id.raw());
    node.send_nmt(cmd).await?;
    let Some(ms) = a.wait else {
        out::result(
            g.json,
            &format!("NMT {} sent to {target_text}", a.action.name()),
            json!({"command": a.action.name(), "target": target_json}),
        );
        return Ok(());
    };
    let timeout = Duration::from_millis(ms);
    let answer = match a.action.state() {
        Some(state) => {
            node.wait_for_state(state, timeout).await?;
            format!("{state}")
        }
        None => {
            node.wait_for_boot_up(timeout).await?;
            "boot-up".to_string()
        }
    };
    out::result(
        g.json,
        &format!("NMT {} sent to {target_text}: {answer}", a.action.name()),
        json!({"command": a.action.name(), "target": target_json, "answer": answer}),
    );
    Ok(())
}
