//! What `duocan station check` prints: what a checked station runs, and who may reach it.

use super::config;

/// The warnings of a board's description shown, at most.
const SHOWN_WARNINGS: usize = 5;

/// What a checked station runs, one line per network.
pub(super) fn summary(st: &config::Station) -> String {
    let mut out = format!("station {}: {} networks\n", st.name, st.networks.len());
    for n in &st.networks {
        let b = &n.builder;
        let pairs: Vec<String> = b
            .pairs()
            .iter()
            .map(|(a, x)| format!("{a:#04x}/{x:#04x}"))
            .collect();
        let peers: Vec<String> = b.peers().iter().map(|(p, _)| format!("{p:#04x}")).collect();
        out += &format!(
            "  {} on {}: master {:#04x}, pairs [{}], peer masters [{}]\n",
            n.name,
            n.buses,
            b.this_node(),
            pairs.join(" "),
            peers.join(" ")
        );
        out += &format!("    {}\n", n.link);
        for d in &n.boards {
            let kind = match d.kind {
                duocan::eds::FileKind::Eds => "eds",
                duocan::eds::FileKind::Dcf => "dcf",
            };
            let mut notes = Vec::new();
            if d.kind == duocan::eds::FileKind::Dcf {
                notes.push(format!("{} writes at boot", d.writes()));
            }
            if d.warnings() > 0 {
                notes.push(format!("{} warnings", d.warnings()));
            }
            let notes = if notes.is_empty() {
                String::new()
            } else {
                format!(" ({})", notes.join(", "))
            };
            out += &format!(
                "    board {:#04x}: {kind} {}{notes}\n",
                d.node,
                d.path.display()
            );
            // What a lenient reading took: the operator sees what the file gets wrong.
            for w in d.desc.warnings.iter().take(SHOWN_WARNINGS) {
                out += &format!("      warning: {w}\n");
            }
            if d.warnings() > SHOWN_WARNINGS {
                out += &format!("      … and {} more\n", d.warnings() - SHOWN_WARNINGS);
            }
        }
    }
    if let Some(h) = &st.http {
        // Who may do what, said plainly: an operator checks that control is as meant.
        let reads = if h.token.is_some() {
            "with http_token"
        } else {
            "open"
        };
        let control = match &h.control {
            config::Control::Off => "off",
            config::Control::Loopback => "open to loopback clients",
            config::Control::Token(_) => "with http_control_token",
        };
        let scheme = if h.tls.is_some() { "https" } else { "http" };
        out += &format!("  {scheme}: {}, reads {reads}, control {control}\n", h.addr);
    }
    if let Some(m) = &st.mqtt {
        out += &format!("  mqtt: {}:{} under {}/\n", m.host, m.port, m.prefix);
    }
    if let Some(gw) = &st.gateway {
        let mut on = Vec::new();
        if let Some(a) = gw.tcp {
            on.push(format!("tcp {a}"));
        }
        if let Some(p) = &gw.socket {
            on.push(format!(
                "socket {} (mode {:#o})",
                p.display(),
                gw.socket_mode
            ));
        }
        let nets: Vec<String> = st
            .networks
            .iter()
            .map(|n| format!("{} {}", n.gateway_net, n.name))
            .collect();
        out += &format!(
            "  309-3 gateway: {}, at most {} clients, nets: {}\n",
            on.join(", "),
            gw.max_clients,
            nets.join(", ")
        );
    }
    out
}
