//! The LSS requests (CiA 309-3's, with CANopenNode's `_lss_fastscan` and the optional
//! arguments of its `lss_allnodes`), carried out by the network's LSS master
//! ([`duocan::net::NetLss`]): its requests leave on every bus of `--bus`, the answers come
//! back merged.
//!
//! ```text
//! [<net>] lss_switch_glob <0|1>                   every slave to waiting (0) or configuration (1)
//! [<net>] lss_switch_sel <vendor> <product> <revision> <serial>    that slave to configuration
//! [<net>] lss_set_node <1-127|255>                node-ID of the slave in configuration
//! [<net>] lss_conf_bitrate 0 <index>              CiA 301 table index (0-4, 6-9)
//! [<net>] lss_activate_bitrate <delay_ms>
//! [<net>] lss_store
//! [<net>] lss_inquire_addr [<0-3>]                one part (0 vendor … 3 serial), or all four
//! [<net>] lss_get_node                            node-ID (0xFF: none)
//! [<net>] _lss_fastscan [<ms>]                    the first slave without a node-ID, selected
//! [<net>] lss_allnodes [<ms> [<first> <store> [<scan> <vendor> … <scan> <serial>]]]
//! ```
//!
//! Answers as CANopenNode's: `OK`; identities and values as `0x` and eight hex digits (a
//! node-ID two); `lss_allnodes` one `#` line per slave given a node-ID, one with the count,
//! then `OK`. A slave that does not answer is `ERROR:103`; one that refuses is 502 (node-ID),
//! 503 (bit rate), 504 (store) or 501 (its manufacturer's code).
//!
//! **Timing.** The answer timeout and the fastscan's settle time are the network's LSS master's
//! (`--lss-answer-ms`, `--lss-settle-ms`), the same for every request: the `<ms>` of `_lss_fastscan` and
//! `lss_allnodes` is read (0 to 65535) but does not change them. **Scan types.** Of
//! `lss_allnodes`' eight scan arguments only the fastscan of every part (scan types 0) is
//! carried out; a part to ignore or to match (1, 2) is `ERROR:100`.

use super::parse::{number_arg, Bad, Code};
use super::value::Word;
use duocan::cia305::{BitTiming, Inquiry, LssAddress, LssError, LssMode, LssPlan, LssService};
use duocan::net::{NetError, Network};
use duocan::NodeId;

/// An LSS request.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum LssRequest {
    /// `lss_switch_glob <0|1>`: every slave to waiting (false) or configuration (true) mode.
    SwitchGlobal(bool),
    /// `lss_switch_sel …`: the slave with this identity to configuration mode.
    SwitchSelective(LssAddress),
    /// `lss_set_node <node>`: 1–127, or 0xFF (none).
    SetNode(u8),
    /// `lss_conf_bitrate 0 <index>`.
    ConfBitrate(BitTiming),
    /// `lss_activate_bitrate <delay_ms>`.
    ActivateBitrate(u16),
    /// `lss_store`.
    Store,
    /// `lss_inquire_addr [<part>]`: one part, or all four (`None`).
    InquireAddr(Option<Inquiry>),
    /// `lss_get_node`.
    GetNode,
    /// `_lss_fastscan [<ms>]`: find the first slave without a node-ID and leave it selected.
    Fastscan,
    /// `lss_allnodes …`: every slave without a node-ID gets one, from `first` up.
    AllNodes {
        /// The first node-ID given.
        first: u8,
        /// Each slave stores its node-ID.
        store: bool,
    },
}

/// The LSS request `name` (lower case) with its arguments.
pub fn parse_lss(name: &str, args: &[Word]) -> Result<LssRequest, Bad> {
    let usage = |u: &str| Bad::syntax(format!("{name} {u}"));
    let u32_arg = |w: &Word| number_arg::<u32>(w, "a number (0 to 0xFFFFFFFF)");
    Ok(match (name, args) {
        ("lss_switch_glob", [m]) => match number_arg::<u8>(m, "0 or 1")? {
            0 => LssRequest::SwitchGlobal(false),
            1 => LssRequest::SwitchGlobal(true),
            _ => return Err(usage("<0|1>")),
        },
        ("lss_switch_glob", _) => return Err(usage("<0|1>")),
        ("lss_switch_sel", [v, p, r, s]) => LssRequest::SwitchSelective(LssAddress {
            vendor: u32_arg(v)?,
            product: u32_arg(p)?,
            revision: u32_arg(r)?,
            serial: u32_arg(s)?,
        }),
        ("lss_switch_sel", _) => return Err(usage("<vendor> <product> <revision> <serial>")),
        // 0 is read, as CANopenNode reads it, and refused by the LSS master (`ERROR:102`).
        ("lss_set_node", [n]) => match number_arg::<u8>(n, "a node-ID (1 to 127, 255: none)")? {
            n @ (0..=127 | 0xFF) => LssRequest::SetNode(n),
            n => {
                return Err(Bad::syntax(format!(
                    "{n}: a node-ID is 1 to 127 (255: none)"
                )))
            }
        },
        ("lss_set_node", _) => return Err(usage("<node>")),
        ("lss_conf_bitrate", [t, i]) => {
            if number_arg::<u8>(t, "table 0")? != 0 {
                return Err(Bad::syntax("only table 0, CiA 301's, is known"));
            }
            match number_arg::<u8>(i, "a table index (0-4, 6-9)")? {
                i @ (0..=4 | 6..=9) => LssRequest::ConfBitrate(BitTiming::standard(i)),
                i => {
                    return Err(Bad::syntax(format!(
                        "{i}: the table's indices are 0-4 and 6-9"
                    )))
                }
            }
        }
        ("lss_conf_bitrate", _) => return Err(usage("0 <table index>")),
        ("lss_activate_bitrate", [d]) => {
            LssRequest::ActivateBitrate(number_arg(d, "a delay (0 to 65535 ms)")?)
        }
        ("lss_activate_bitrate", _) => return Err(usage("<delay_ms>")),
        ("lss_store", []) => LssRequest::Store,
        ("lss_store", _) => return Err(usage("takes no argument")),
        ("lss_inquire_addr", []) => LssRequest::InquireAddr(None),
        ("lss_inquire_addr", [p]) => {
            LssRequest::InquireAddr(Some(match number_arg::<u8>(p, "a part (0 to 3)")? {
                0 => Inquiry::Vendor,
                1 => Inquiry::Product,
                2 => Inquiry::Revision,
                3 => Inquiry::Serial,
                _ => return Err(usage("[<0 vendor|1 product|2 revision|3 serial>]")),
            }))
        }
        ("lss_inquire_addr", _) => return Err(usage("[<0-3>]")),
        ("lss_get_node", []) => LssRequest::GetNode,
        ("lss_get_node", _) => return Err(usage("takes no argument")),
        ("_lss_fastscan", []) => LssRequest::Fastscan,
        ("_lss_fastscan", [ms]) => {
            number_arg::<u16>(ms, "a time-out (0 to 65535 ms)")?;
            LssRequest::Fastscan
        }
        ("_lss_fastscan", _) => return Err(usage("[<timeout_ms>]")),
        ("lss_allnodes", _) => all_nodes(args)?,
        _ => {
            let why = format!("{name}: not an LSS request (help lss lists them)");
            return Err(Bad::because(Code::NotSupported, why));
        }
    })
}

/// `lss_allnodes [<ms> [<first> <store> [<scan> <value>]×4]]`; without a first node-ID, 2 and
/// stored, as CANopenNode's.
fn all_nodes(args: &[Word]) -> Result<LssRequest, Bad> {
    if let Some(ms) = args.first() {
        number_arg::<u16>(ms, "a time-out (0 to 65535 ms)")?;
    }
    let (first, store) = match args.get(1..3) {
        None if args.len() <= 1 => (2, true),
        Some([first, store]) => {
            let first = match number_arg::<u8>(first, "a node-ID (1 to 127)")? {
                n @ 1..=127 => n,
                n => return Err(Bad::syntax(format!("{n}: a node-ID is 1 to 127"))),
            };
            let store = match number_arg::<u8>(store, "0 or 1")? {
                0 => false,
                1 => true,
                n => return Err(Bad::syntax(format!("{n}: store is 0 or 1"))),
            };
            (first, store)
        }
        _ => {
            return Err(Bad::syntax(
                "lss_allnodes [<ms> [<first> <store> [<scans>]]]",
            ))
        }
    };
    match &args[args.len().min(3)..] {
        [] => {}
        scans @ [_, _, _, _, _, _, _, _] => {
            for pair in scans.chunks(2) {
                number_arg::<u32>(&pair[1], "a number (0 to 0xFFFFFFFF)")?;
                match number_arg::<u8>(&pair[0], "a scan type (0 to 2)")? {
                    0 => {}
                    1 | 2 => {
                        let why = "only scan type 0 (fastscan of every part) is carried out";
                        return Err(Bad::because(Code::NotSupported, why));
                    }
                    n => return Err(Bad::syntax(format!("{n}: a scan type is 0 to 2"))),
                }
            }
        }
        _ => return Err(Bad::syntax("lss_allnodes: four <scan type> <value> pairs")),
    }
    Ok(LssRequest::AllNodes { first, store })
}

/// Carries out `r`; the answer's body (lines before the last are `#` comments).
pub async fn execute(net: &Network, r: LssRequest) -> Result<String, Bad> {
    let lss = net.lss();
    let ok = |()| "OK".to_string();
    match r {
        LssRequest::SwitchGlobal(config) => {
            let mode = if config {
                LssMode::Configuration
            } else {
                LssMode::Waiting
            };
            lss.switch_global(mode).await.map(ok)
        }
        LssRequest::SwitchSelective(a) => lss.switch_selective(a).await.map(ok),
        LssRequest::SetNode(n) => lss.configure_node_id(n).await.map(ok),
        LssRequest::ConfBitrate(t) => lss.configure_bit_timing(t).await.map(ok),
        LssRequest::ActivateBitrate(d) => lss.activate_bit_timing(d).await.map(ok),
        LssRequest::Store => lss.store().await.map(ok),
        LssRequest::InquireAddr(Some(q)) => lss.inquire(q).await.map(|v| format!("0x{v:08X}")),
        LssRequest::InquireAddr(None) => {
            let mut parts = Vec::with_capacity(4);
            for q in [
                Inquiry::Vendor,
                Inquiry::Product,
                Inquiry::Revision,
                Inquiry::Serial,
            ] {
                parts.push(lss.inquire(q).await.map_err(|e| lss_error(&e))?);
            }
            Ok(address(&LssAddress {
                vendor: parts[0],
                product: parts[1],
                revision: parts[2],
                serial: parts[3],
            }))
        }
        LssRequest::GetNode => lss
            .inquire(Inquiry::NodeId)
            .await
            .map(|v| format!("0x{:02X}", v & 0xFF)),
        LssRequest::Fastscan => return fastscan_one(net).await,
        LssRequest::AllNodes { first, store } => return all_nodes_run(net, first, store).await,
    }
    .map_err(|e| lss_error(&e))
}

/// `_lss_fastscan`: a scan with an empty plan stops at the first slave found (it has no
/// node-ID for it) and switches it back to waiting; selecting it again leaves it in
/// configuration mode, where CANopenNode's fastscan leaves the slave it found.
async fn fastscan_one(net: &Network) -> Result<String, Bad> {
    let lss = net.lss();
    let report = lss
        .fastscan(LssPlan::new())
        .await
        .map_err(|e| lss_error(&e))?;
    match report.stopped {
        Some(LssError::NoNodeId(found)) => {
            lss.switch_selective(found)
                .await
                .map_err(|e| lss_error(&e))?;
            Ok(address(&found))
        }
        Some(e) => Err(lss_error(&NetError::Lss(e))),
        None => Err(Bad::because(
            Code::Timeout,
            "no slave without a node-ID answered",
        )),
    }
}

/// `lss_allnodes`: a fastscan giving node-IDs from `first` up.
async fn all_nodes_run(net: &Network, first: u8, store: bool) -> Result<String, Bad> {
    let plan = LssPlan::new()
        .with_free((first..=127).filter_map(NodeId::new))
        .with_store(store);
    let report = net.lss().fastscan(plan).await.map_err(|e| lss_error(&e))?;
    let mut lines: Vec<String> = report
        .assigned
        .iter()
        .map(|(a, n)| format!("# node-ID {} given to {}", n.raw(), address(a)))
        .collect();
    match report.stopped {
        None => lines.push(format!(
            "# {} given a node-ID; no slave is left without one",
            report.assigned.len()
        )),
        // Node-IDs ran out (CANopenNode stops at 127 too): the rest wait for another scan.
        Some(LssError::NoNodeId(_)) => lines.push(format!(
            "# {} given a node-ID; none is left for the others",
            report.assigned.len()
        )),
        Some(e) => return Err(lss_error(&NetError::Lss(e))),
    }
    lines.push("OK".to_string());
    Ok(lines.join("\n"))
}

/// An identity as four `0x` words, CANopenNode's way.
fn address(a: &LssAddress) -> String {
    format!(
        "0x{:08X} 0x{:08X} 0x{:08X} 0x{:08X}",
        a.vendor, a.product, a.revision, a.serial
    )
}

/// The 309-3 code of an LSS failure, and what happened.
fn lss_error(e: &NetError) -> Bad {
    let code = match e {
        NetError::Lss(LssError::Timeout(_)) => Code::Timeout,
        NetError::Lss(LssError::Refused { error: 0xFF, .. }) => Code::LssManufacturer,
        NetError::Lss(LssError::Refused { service, .. }) => match service {
            LssService::ConfigureNodeId => Code::LssNodeId,
            LssService::ConfigureBitTiming => Code::LssBitRate,
            LssService::Store => Code::LssStore,
            _ => Code::InternalState,
        },
        _ => Code::InternalState,
    };
    Bad::because(code, e.to_string())
}
