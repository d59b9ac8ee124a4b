//! `duocan gateway [--listen ADDR:PORT [--allow-remote] | --socket PATH]`: the CiA 309-3 ASCII
//! command interface, answering as CANopenNode's gateway does, so that scripts written for it
//! (with its client `cocomm`) or for other 309-3 gateways drive a duocan network unchanged.
//!
//! **What it speaks.** One request per line, on standard input (the default; until end of
//! input), on a TCP port (`--listen`) or on a local socket (`--socket`, where `cocomm -s PATH`
//! connects), several clients at once on either:
//!
//! ```text
//! "[" <sequence> "]" [[<net>] <node>] <command>      # a comment
//! [1] 5 read 0x1018 1 u32          SDO upload            -> [1] 13683200
//! [2] 5 w 0x1017 0 u16 250         SDO download          -> [2] OK
//! [3] set node 5                   default node          -> [3] OK
//! [4] r 0x1008 0 vs                (node 5)              -> [4] "duocan simulated node"
//! [5] start                        NMT (node 0: all)     -> [5] OK
//! [6] r 0x1234 0 u8                the node aborts       -> [6] ERROR:0x06020000 #object does not exist…
//! [7] lss_switch_glob 1            LSS                   -> [7] OK
//! ```
//!
//! Commands: `r[ead]`, `w[rite]`, `start`, `stop`, `preop[erational]`, `reset node`,
//! `reset comm[unication]`, `set network`, `set node`, `set sdo_timeout <ms>`,
//! `set sdo_block <0|1>`, the LSS requests (`lss_switch_glob`, `lss_switch_sel`,
//! `lss_set_node`, `lss_conf_bitrate`, `lss_activate_bitrate`, `lss_store`,
//! `lss_inquire_addr`, `lss_get_node`, `_lss_fastscan`, `lss_allnodes`: see `lss`),
//! `info version`, `help [datatype|lss]`; the data types are those of 309-3 (`b`, `i8`…`i64`,
//! `u8`…`u64`, `r32`, `r64`, `vs`, `os`, `us`, `d`, `t`, `td`) with CANopenNode's `x8`…`x64`
//! and `hex` (see `value`). Commands and types are case-insensitive; `#` starts a comment.
//!
//! **What it answers.** One answer per line, in order: `OK`, the value, or
//! `ERROR:<code> #<meaning>`, behind the request's `[<sequence>]`. The codes are 309-3's
//! internal ones (100 request not supported, 101 syntax error, 102 not processed as things
//! are, 103 time-out, 105 no default node, 106 unsupported net, 107 unsupported node, 501–504
//! LSS refusals) or the SDO abort code in hex (`ERROR:0x06020000`; a node that does not answer
//! in time is the client's abort `0x05040000`); the `#` comment 309-3 allows behind it says
//! what the code means and, for the gateway's own, what in the request was wrong. A request
//! without its `[<sequence>]` is not carried out: `[0] ERROR:101`. A blank line or a comment
//! is answered with an empty line (a client that waits for an answer to each line it sends,
//! as `cocomm` does, would otherwise wait for ever). A value read whose size is not its type's
//! shows as its bytes in hex (`r 0x1017 0 u32` of a 16-bit object: `E8 03`); `r32` and `r64`
//! show as C's `%g`. A `b` write takes a number (`1`, `0x1`) as one byte, and the node judges
//! its value, as with CANopenNode's gateway. `help` answers with `#` comment lines, then `OK`. Answers end with LF on
//! standard output and CR LF on a socket, and the lines of a longer answer are parted by LF
//! alone: `cocomm` reads an answer up to its first CR LF. A request may end with either.
//!
//! **Its state.** Each client (standard input, or one connection) has its own default node
//! (none at first: a request without a node is `ERROR:105` until `set node`), SDO time-out
//! (`--timeout` at first) and block-transfer switch (off). The gateway serves one network: the
//! bus of `--bus` (two ports merged by the dual-bus layer are one network). As in
//! CANopenNode's single-network gateway, any net number (0–65535) names it, and `set network`
//! is taken; a net above 65535 is `ERROR:106`. A station (`duocan station run`) serves the
//! same gateway over all of its networks, each under a net number of its own ([`GatewayNets`];
//! see `crate::cmd::station::gateway`).
//!
//! **What it does not do, and says so.** Node guarding and heartbeat-consumer set-up
//! (`enable`/`disable guarding|heartbeat`), PDO configuration and transfer (`set rpdo`,
//! `set tpdo`, `r[ead] p[do]`, `w[rite] p[do]`), `init`, `set heartbeat`, `set id`,
//! `set command_*`, `boot_up_indication` and CANopenNode's `led` and `log` are recognised and
//! answered `ERROR:100`; so is any command 309-3 does not have. Nothing is sent unasked: no
//! boot-up, EMCY or PDO indications.
//!
//! **Where it still answers otherwise than CANopenNode's gateway, and why.** (The vcan test
//! tier sends one cocomm script to both, each talking to the same CANopenNode device, and fails
//! on any difference not listed here.)
//! - The text behind `#` is duocan's (CiA 301's meaning of an abort code, 309-3's of its own
//!   codes, and what was wrong), not CANopenNode's wording; the code before it is the same.
//! - A request without a readable sequence number is answered `[0] ERROR:101`; CANopenNode
//!   answers it with the sequence number of the request before (0 in a new session).
//! - `help` pages are duocan's own text, as `#` lines closed by `[<sequence>] OK`; CANopenNode
//!   sends its page as plain lines without a sequence number or `OK`.
//! - `info version` is answered (309-3 has it); CANopenNode's gateway answers `ERROR:100`. So
//!   are the 309-3 types CANopenNode lacks (`i24`…`i56`, `u24`…`u56`, `t`, `td`: `ERROR:101`
//!   there).
//! - Numbers are decimal or `0x` hex, as 309-3 writes them: `010` is ten here, where
//!   CANopenNode's gateway (reading numbers with C's `strtoul`) takes it as octal eight, and a
//!   leading `+` is refused here.
//! - `set sdo_timeout` takes up to an hour, as the tool's `--timeout`; CANopenNode's gateway up
//!   to 65535 ms.
//! - A `vs` read shows a control character (a line feed among them) as U+FFFD, and bytes
//!   that are not UTF-8 likewise: an answer stays one line. CANopenNode passes them through
//!   (it drops NUL and CR, as this gateway does).
//! - An `r64` write is parsed as a double; CANopenNode parses it as a float first, losing
//!   digits. `r32`/`r64` writes of `nan` and `inf` are refused here (a value no dictionary range
//!   check can judge).
//! - The LSS timing is the network's LSS master's (`--lss-answer-ms`, `--lss-settle-ms`): the
//!   `<ms>` of `_lss_fastscan` and `lss_allnodes` is read but does not change it, and
//!   `lss_allnodes` carries out fastscan of every part only (scan types 1 and 2 are
//!   `ERROR:100`). `_lss_fastscan` leaves the slave it found in configuration mode, as
//!   CANopenNode's does, by selecting it again after the scan.
//! - LED and log are CANopenNode's device's, not a gateway's: `ERROR:100`.
//!
//! **Bounds.** A request line is at most [`MAX_LINE`] bytes (longer: `ERROR:101`, the line
//! skipped); a value at most the library's transfer limit (64 KiB); at most [`MAX_CLIENTS`]
//! clients at once (one more is told `ERROR:102` and closed). The TCP port is loopback-only
//! unless `--allow-remote`, and the local socket its owner's only: the gateway has no
//! authentication, and anyone who reaches it drives the bus.

mod error;
mod exec;
mod help;
mod lss;
mod nets;
mod parse;
mod serve;
pub mod socket;
pub(crate) mod value;

pub use nets::GatewayNets;
pub use serve::{accept, GatewayListener, GatewayStats, Served};

#[cfg(test)]
mod tests;

use crate::args::parse_timeout_ms;
use crate::fail::Fail;
use crate::{bus, Global};
use duocan::cia305::LssMasterConfig;
use std::net::SocketAddr;
use std::path::PathBuf;
use tokio::io::BufReader;

/// Longest request line, in bytes: room for a 64 KiB domain in base64 and the words around it.
pub const MAX_LINE: usize = 128 * 1024;

/// Most clients (TCP or local socket) served at once.
pub const MAX_CLIENTS: usize = 16;

/// The arguments of `duocan gateway`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Serve on this TCP address instead of standard input (127.0.0.1:PORT; port 0 picks a
    /// free one, printed on standard error)
    #[arg(long, value_name = "ADDR:PORT", conflicts_with = "socket")]
    listen: Option<SocketAddr>,
    /// Accept --listen on an address other than loopback (no authentication: anyone who
    /// reaches the port drives the bus)
    #[arg(long, requires = "listen")]
    allow_remote: bool,
    /// Serve on a local (Unix domain) socket at this path instead of standard input, as
    /// CANopenNode's gateway does for `cocomm -s PATH` (only its owner may connect)
    #[arg(long, value_name = "PATH")]
    socket: Option<PathBuf>,
    /// How long an LSS request waits for the slaves' answer, in milliseconds
    #[arg(long, default_value = "50", value_parser = parse_timeout_ms, value_name = "MS")]
    lss_answer_ms: u64,
    /// LSS fastscan (`_lss_fastscan`, `lss_allnodes`): how long an answered step waits for
    /// further answers, in milliseconds
    #[arg(long, default_value = "5", value_parser = parse_timeout_ms, value_name = "MS")]
    lss_settle_ms: u64,
}

/// Runs `duocan gateway`.
pub async fn run(g: &Global, a: Args) -> Result<(), Fail> {
    if g.json {
        return Err(Fail::usage(
            "gateway: the answers are CiA 309-3 text lines; --json does not apply",
        ));
    }
    if let Some(addr) = a.listen {
        if !addr.ip().is_loopback() && !a.allow_remote {
            return Err(Fail::usage(format!(
                "--listen {addr}: not a loopback address; the gateway has no authentication, \
                 so give --allow-remote to serve other machines"
            )));
        }
    }
    let ms = duocan::Duration::from_millis;
    let lss = LssMasterConfig::default()
        .with_timeout(ms(a.lss_answer_ms))
        .with_settle(ms(a.lss_settle_ms));
    let bus = bus::open_with(g, bus::options(g, false).with_lss(lss))?;
    let nets = GatewayNets::single(bus.net.clone());
    let r = match (a.listen, a.socket) {
        (None, None) => {
            let input = BufReader::new(tokio::io::stdin());
            serve::serve(&nets, g.timeout, input, tokio::io::stdout(), "\n").await;
            Ok(())
        }
        (listen, socket) => listeners(nets, g.timeout, listen, socket).await,
    };
    bus.close().await;
    r
}

/// Serves clients on the TCP address or the local socket until interrupted (the socket file
/// removed then).
async fn listeners(
    nets: GatewayNets,
    timeout_ms: u64,
    listen: Option<SocketAddr>,
    socket: Option<PathBuf>,
) -> Result<(), Fail> {
    let (listener, _file) = match (listen, socket) {
        (Some(addr), _) => {
            let l = tokio::net::TcpListener::bind(addr)
                .await
                .map_err(|e| Fail::usage(format!("--listen {addr}: {e}")))?;
            eprintln!("duocan gateway: listening on {}", l.local_addr()?);
            (GatewayListener::Tcp(l), None)
        }
        (None, Some(path)) => {
            let shown = path.display();
            let (l, file) = socket::bind(&path, 0o600)
                .map_err(|why| Fail::usage(format!("--socket {shown}: {why}")))?;
            eprintln!("duocan gateway: listening on {shown}");
            (GatewayListener::Unix(l), Some(file))
        }
        (None, None) => return Ok(()),
    };
    // Not `eprintln!`, which panics when standard error is gone (a closed pipe): a note
    // nobody can read must not stop the gateway.
    let note = |what: &str| {
        use std::io::Write;
        let _ = writeln!(std::io::stderr(), "duocan gateway: {what}");
    };
    let served = Served::new(nets, timeout_ms, MAX_CLIENTS, note);
    let interrupted = async {
        let _ = tokio::signal::ctrl_c().await;
    };
    accept(listener, served, interrupted).await;
    Ok(())
}
