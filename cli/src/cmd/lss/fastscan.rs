//! `duocan lss fastscan [--assign FROM] [--plan FILE] [--store]`: every slave without a
//! node-ID found and configured, one after another; a table of identity → node-ID and what it
//! cost (frames, time) beside what the protocol says it costs for those identities
//! ([`duocan::cia305::fastscan_cost`]).

use super::parse::parse_plan;
use crate::args::parse_node;
use crate::fail::Fail;
use crate::out::{self, node_cell, Cell, Table};
use crate::Global;
use duocan::cia305::{fastscan_cost, LssAddress, LssMasterConfig, LssPlan};
use duocan::net::{Network, LSS_PLAN};
use duocan::NodeId;
use serde_json::json;
use std::path::PathBuf;
use std::time::Duration;

/// The arguments of `duocan lss fastscan`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Slaves the plan does not name get the lowest free node-ID from this one up (to 127)
    #[arg(long, value_name = "NEXT_FREE_FROM", value_parser = parse_node)]
    assign: Option<NodeId>,
    /// A plan: lines of VENDOR PRODUCT REVISION SERIAL NODE (a part may be *: not checked)
    #[arg(long, value_name = "FILE")]
    plan: Option<PathBuf>,
    /// Each slave also stores its new node-ID (store configuration)
    #[arg(long)]
    store: bool,
    /// How long to wait for each configured slave's boot-up after the scan, in milliseconds
    #[arg(long, value_name = "MS", default_value = "1000", value_parser = crate::args::parse_timeout_ms)]
    boot_ms: u64,
}

impl Args {
    /// The usage errors found before the bus is opened.
    pub fn check(&self) -> Result<(), Fail> {
        if self.assign.is_none() && self.plan.is_none() {
            return Err(Fail::usage(
                "fastscan: which node-IDs? give --assign NEXT_FREE_FROM and/or --plan FILE",
            ));
        }
        Ok(())
    }

    fn plan(&self) -> Result<LssPlan<LSS_PLAN>, Fail> {
        let mut plan = LssPlan::new().with_store(self.store);
        if let Some(path) = &self.plan {
            let text = std::fs::read_to_string(path)
                .map_err(|e| Fail::usage(format!("{}: {e}", path.display())))?;
            let lines =
                parse_plan(&text).map_err(|e| Fail::usage(format!("{}: {e}", path.display())))?;
            if lines.len() > LSS_PLAN {
                return Err(Fail::usage(format!(
                    "{}: {} boards planned; one scan takes at most {LSS_PLAN}",
                    path.display(),
                    lines.len()
                )));
            }
            for l in lines {
                plan = if l.exact {
                    plan.with_identity(l.address, l.node)
                } else {
                    plan.with_expected(l.address, l.node)
                };
            }
        }
        if let Some(from) = self.assign {
            plan = plan.with_free((from.raw()..=127).filter_map(NodeId::new));
        }
        Ok(plan)
    }
}

/// Runs the fastscan and prints what it did.
pub async fn run(g: &Global, net: &Network, a: Args, cfg: &LssMasterConfig) -> Result<(), Fail> {
    let plan = a.plan()?;
    let begun = net.now();
    let report = net.lss().fastscan(plan).await?;
    let mut t = Table::new(&["vendor", "product", "revision", "serial", "node", "booted"]);
    for (addr, node) in &report.assigned {
        let hex = |v: u32| Cell::new(format!("{v:#010x}"), v);
        // A slave that had no node-ID boots by itself once given one and switched back.
        let boot = net
            .node(node.raw())
            .wait_for_boot_up_since(begun, Duration::from_millis(a.boot_ms))
            .await
            .is_ok();
        t.row(vec![
            hex(addr.vendor),
            hex(addr.product),
            hex(addr.revision),
            hex(addr.serial),
            node_cell(node.raw()),
            boot.into(),
        ]);
    }
    // What the protocol says a whole scan of these identities costs (not for a scan that
    // stopped on the way).
    let mut found: Vec<LssAddress> = report.assigned.iter().map(|(a, _)| *a).collect();
    let bound = report
        .stopped
        .is_none()
        .then(|| fastscan_cost(&mut found, cfg, a.store));
    let ms = |d: duocan::Duration| d.as_micros() as f64 / 1000.0;
    let took_ms = ms(report.took);
    let stopped = report
        .stopped
        .map(|e| duocan::net::NetError::Lss(e).to_string());
    if g.json {
        out::emit_json(&json!({
            "assigned": t.to_json(),
            "requests": report.requests,
            "answers": report.answers,
            "restarts": report.restarts,
            "abandoned": report.abandoned,
            "took_ms": took_ms,
            "protocol": bound.map(|b| json!({
                "requests": b.requests,
                "answers": b.answers,
                "waiting_ms": ms(b.waiting),
            })),
            "stopped": stopped,
        }));
    } else {
        if t.is_empty() {
            out::print_text("no slave without a node-ID answered\n");
        } else {
            t.print(false);
        }
        let mut line = format!(
            "{} configured: {} request frames, {} answers, {took_ms:.1} ms",
            report.assigned.len(),
            report.requests,
            report.answers,
        );
        if report.restarts > 0 {
            line.push_str(&format!(
                ", {} restarts ({} requests given up)",
                report.restarts, report.abandoned
            ));
        }
        if let Some(b) = bound {
            line.push_str(&format!(
                " (the protocol: {} requests, {} answers, {:.1} ms of waiting plus the frames)",
                b.requests,
                b.answers,
                ms(b.waiting)
            ));
        }
        out::print_text(&format!("{line}\n"));
    }
    match stopped {
        Some(why) => Err(Fail::protocol(format!(
            "{why}\nhint: the slaves listed keep their node-IDs; fix the plan or --assign and scan again for the rest"
        ))),
        None => Ok(()),
    }
}
