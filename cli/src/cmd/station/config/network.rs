//! One `[[network]]` table, checked: its buses, its master's settings by the redundant
//! network's builder (whose errors are placed on the key that holds the value), its `on_stop`.

use super::{Buses, Network, NetworkTable, Source, SIM_BUSES};
use duocan::nmt::NmtCommand;
use duocan_redundancy::{RedundantError, RedundantNetwork, Role};
use std::ops::Range;
use toml::Spanned;

/// One network's table, checked.
pub(super) fn network(
    src: &Source<'_>,
    t: NetworkTable,
    table: Range<usize>,
) -> Result<Network, String> {
    let name = t.name.get_ref().trim().to_string();
    if name.is_empty() {
        return Err(src.span(t.name.span(), "name", "a network needs a name"));
    }
    let buses = buses(src, &t.buses)?;
    let ms = |d: &Spanned<u64>| std::time::Duration::from_millis(*d.get_ref());
    let mut b = RedundantNetwork::builder()
        .node_id(*t.node_id.get_ref())
        .priority(t.priority);
    if let Some(d) = &t.heartbeat_ms {
        b = b.heartbeat(ms(d));
    }
    if let Some(d) = &t.master_timeout_ms {
        b = b.master_timeout(ms(d));
    }
    if let Some(d) = &t.sync_ms {
        b = b.sync(ms(d));
    }
    if let Some(d) = &t.time_ms {
        b = b.time(ms(d));
    }
    if let Some(d) = &t.boot_timeout_ms {
        b = b.boot_timeout(ms(d));
    }
    if let Some(d) = &t.pair_heartbeat_ms {
        b = b.pair_heartbeat(ms(d));
    }
    if let Some(d) = &t.pair_timeout_ms {
        b = b.pair_timeout(ms(d));
    }
    for &[a, x] in t.pairs.as_ref().map_or(&[][..], |p| p.get_ref()) {
        b = b.pair(a, x);
    }
    for p in t.peers.as_ref().map_or(&[][..], |p| p.get_ref()) {
        b = b.peer_master_with_priority(p.node, p.priority);
    }
    let on_stop = match &t.on_stop {
        None => None,
        Some(s) => on_stop(s.get_ref()).map_err(|why| src.span(s.span(), "on_stop", why))?,
    };
    if let Err(e) = b.check() {
        return Err(place(src, &t, table, &name, &e));
    }
    let (link, shown) = super::link::link(src, &t)?;
    if let Some(cfg) = link {
        b = b.link(cfg);
    }
    b = b.profile(shown.net_profile());
    let pairs = t.pairs.as_ref().map_or(&[][..], |p| p.get_ref());
    let boards = super::boards::boards(src, t.boards.as_ref(), pairs)?;
    for cfg in boards.iter().filter_map(super::Board::slave_config) {
        b = b.member_config(cfg);
    }
    Ok(Network {
        name,
        buses,
        builder: b,
        on_stop,
        // Numbered once every network is read (see `gateway::net_numbers`).
        gateway_net: 0,
        boards,
        link: shown,
    })
}

/// `buses`: a simulated plant or two distinct interfaces.
fn buses(src: &Source<'_>, s: &Spanned<String>) -> Result<Buses, String> {
    let text = s.get_ref().trim();
    if SIM_BUSES.contains(&text) {
        return Ok(Buses::Sim(text.to_string()));
    }
    let bad = |why: String| src.span(s.span(), "buses", why);
    let allowed = "two interfaces as \"can0,can1\" (SocketCAN, or python-can's UDP bus: \
                   \"udp:1,udp:2\"), or \"sim-pairs\" / \"sim-pairs:quiet\" / \"sim-pairs:failover\" \
                   (simulated buses)";
    let Some((a, b)) = text.split_once(',') else {
        return Err(bad(format!("{text:?} is not two buses: give {allowed}")));
    };
    let (a, b) = (a.trim(), b.trim());
    if a.is_empty() || b.is_empty() || b.contains(',') {
        return Err(bad(format!("{text:?} is not two buses: give {allowed}")));
    }
    if a == b {
        return Err(bad(format!("{a} twice: the two buses are two interfaces")));
    }
    for x in [a, b] {
        if let Some(Err(why)) = crate::args::parse_udp(x) {
            return Err(bad(why));
        }
    }
    Ok(Buses::Ports([a.to_string(), b.to_string()]))
}

/// `on_stop`'s NMT command (`none`: nothing).
fn on_stop(s: &str) -> Result<Option<NmtCommand>, String> {
    Ok(Some(match s {
        "none" => return Ok(None),
        "stop" => NmtCommand::Stop,
        "preop" => NmtCommand::EnterPreOperational,
        "reset" => NmtCommand::ResetNode,
        "reset-comm" => NmtCommand::ResetCommunication,
        other => {
            return Err(format!(
                "{other:?} is not an NMT command: none, stop, preop, reset or reset-comm"
            ))
        }
    }))
}

/// The builder's error `e`, placed on the key that holds the value it is about (the
/// network's table when no one key does).
fn place(
    src: &Source<'_>,
    t: &NetworkTable,
    table: Range<usize>,
    name: &str,
    e: &RedundantError,
) -> String {
    let spans = |key: &str| -> Option<Range<usize>> {
        let d = |x: &Option<Spanned<u64>>| x.as_ref().map(Spanned::span);
        match key {
            "heartbeat" => d(&t.heartbeat_ms),
            "master_timeout" => d(&t.master_timeout_ms),
            "sync" => d(&t.sync_ms),
            "time" => d(&t.time_ms),
            "boot_timeout" => d(&t.boot_timeout_ms),
            "pair_heartbeat" => d(&t.pair_heartbeat_ms),
            "pair_timeout" => d(&t.pair_timeout_ms),
            "pairs" => t.pairs.as_ref().map(Spanned::span),
            "peers" => t.peers.as_ref().map(Spanned::span),
            _ => None,
        }
    };
    let role_key = |r: &Role| match r {
        Role::ThisMaster => "node_id",
        Role::PeerMaster => "peers",
        Role::PairMember => "pairs",
        _ => "",
    };
    let of_role = |r: &Role| match role_key(r) {
        "node_id" => Some(("node_id", Some(t.node_id.span()))),
        k => Some((k, spans(k))),
    };
    let key: Option<(&str, Option<Range<usize>>)> = match e {
        RedundantError::BadNodeId { role, .. } => of_role(role),
        RedundantError::NodeTwice { second, .. } => of_role(second),
        RedundantError::TooMany { what, .. } => {
            let k = if what.contains("pair") {
                "pairs"
            } else {
                "peers"
            };
            Some((k, spans(k)))
        }
        RedundantError::ZeroDuration { setting }
        | RedundantError::TooLong { setting, .. }
        | RedundantError::TimeoutTooShort { setting, .. } => Some((setting, spans(setting))),
        _ => None,
    };
    match key {
        Some((k, Some(span))) => {
            // The builder names its settings; the file's durations carry their unit.
            let key = if matches!(k, "node_id" | "pairs" | "peers") {
                k.to_string()
            } else {
                format!("{k}_ms")
            };
            src.span(span, &key, e)
        }
        // A default value is wrong with the others (a timeout left at its default below a
        // period the file sets): the network's table.
        _ => src.at(table.start, format_args!("network {name:?}: {e}")),
    }
}
