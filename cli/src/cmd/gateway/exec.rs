//! Carrying out a request on the network, and the answer that goes back.

use super::nets::GatewayNets;
use super::parse::{parse_line, Bad, Code, Command, Line, Request};
use super::value::show_value;
use duocan::net::NetError;
use duocan::sdo::{SdoOptions, TransferMode};
use duocan::Duration;

/// What one client has set: its default net and node, and how its SDO transfers go. Each
/// client (standard input, or one connection) has its own.
#[derive(Clone, Debug)]
pub struct Session {
    net: u16,
    node: Option<u8>,
    timeout_ms: u64,
    block: bool,
}

impl Session {
    /// A new client's settings: default net `net`, no default node, SDO time-out
    /// `timeout_ms`, block transfer off.
    pub fn new(net: u16, timeout_ms: u64) -> Session {
        Session {
            net,
            node: None,
            timeout_ms,
            block: false,
        }
    }

    fn sdo_options(&self) -> SdoOptions {
        SdoOptions::default()
            .with_timeout(Duration::from_millis(self.timeout_ms))
            .with_mode(if self.block {
                TransferMode::Block
            } else {
                TransferMode::Auto
            })
    }
}

/// The answer to `line`: empty for a blank line or a comment (CANopenNode answers those
/// with an empty line, and `cocomm` waits for it), else the response; lines before the last
/// one are `#` comments (the help, `lss_allnodes`).
pub async fn answer(nets: &GatewayNets, session: &mut Session, line: &str) -> String {
    match parse_line(line) {
        Line::Empty => String::new(),
        // A request whose sequence number cannot be read is answered as number 0 (what
        // CANopenNode's gateway answers before its first request).
        Line::Error(seq, bad) => with_sequence(seq.unwrap_or(0), &error(&bad)),
        Line::Request(r) => {
            let seq = r.seq;
            let body = execute(nets, session, r).await;
            with_sequence(seq, &body.unwrap_or_else(|bad| error(&bad)))
        }
    }
}

/// `[<n>] ` in front of the response's last line (the one a client waits for).
fn with_sequence(n: u32, body: &str) -> String {
    match body.rsplit_once('\n') {
        Some((comments, last)) => format!("{comments}\n[{n}] {last}"),
        None => format!("[{n}] {body}"),
    }
}

/// `ERROR:<code> #<meaning>[: <what was wrong>]`: the code as CANopenNode writes it (no space),
/// and the comment 309-3 allows behind it, which `cocomm` users read.
fn error(bad: &Bad) -> String {
    let text = match &bad.why {
        Some(why) => format!("{}: {why}", bad.code.text()),
        None => bad.code.text().to_string(),
    };
    format!("ERROR:{} #{}", bad.code as u16, one_line(&text))
}

/// `text` with its control characters replaced: a response is one line, whatever a request
/// quoted back holds.
fn one_line(text: &str) -> String {
    text.chars()
        .map(|c| if c.is_control() { '\u{FFFD}' } else { c })
        .collect()
}

/// The response to a network error: the SDO abort code and its meaning if there is one (a
/// time-out is the client's abort 0x05040000), else the 309-3 code closest to what happened.
fn net_error(e: &NetError) -> Result<String, Bad> {
    match e.abort_code() {
        Some(code) => Ok(format!(
            "ERROR:0x{:08X} #{}",
            code.0,
            code.description().unwrap_or("not a CiA 301 abort code")
        )),
        None => Err(Bad::because(
            match e {
                NetError::Timeout { .. } => Code::Timeout,
                _ => Code::InternalState,
            },
            e.to_string(),
        )),
    }
}

async fn execute(nets: &GatewayNets, s: &mut Session, r: Request) -> Result<String, Bad> {
    let ok = || Ok("OK".to_string());
    // The request's net, else the client's default: which numbers name a network is the
    // gateway's (`GatewayNets`), so the standalone gateway and the station answer alike.
    let net_no = r.net.unwrap_or(s.net);
    let net = || nets.get(net_no);
    match r.command {
        Command::SetNetwork(n) => {
            nets.get(n)?;
            s.net = n;
            ok()
        }
        Command::SetNode(n) => {
            s.node = Some(n);
            ok()
        }
        Command::SetSdoTimeout(ms) => {
            s.timeout_ms = ms;
            ok()
        }
        Command::SetSdoBlock(on) => {
            s.block = on;
            ok()
        }
        Command::Version => Ok(version()),
        Command::Help(page) => Ok(super::help::text(page)),
        Command::NotSupported(what) => Err(Bad::because(
            Code::NotSupported,
            format!("{what}: not carried out by this gateway"),
        )),
        Command::Lss(l) => super::lss::execute(net()?, l).await,
        Command::Nmt(cmd) => {
            let net = net()?;
            let node = r
                .node
                .or(s.node)
                .ok_or_else(|| Bad::code(Code::NoDefaultNode))?;
            let sent = if node == 0 {
                net.nmt_all(cmd).await
            } else {
                net.node(node).send_nmt(cmd).await
            };
            sent.map_or_else(|e| net_error(&e), |()| ok())
        }
        Command::Read { index, sub, ty } => {
            let net = net()?;
            let node = sdo_node(r.node, s)?;
            let sdo = net.node(node).sdo().with_options(s.sdo_options());
            match sdo.read_bytes(index, sub).await {
                Ok(data) => Ok(show_value(ty, &data)),
                Err(e) => net_error(&e),
            }
        }
        Command::Write { index, sub, data } => {
            let net = net()?;
            let node = sdo_node(r.node, s)?;
            let sdo = net.node(node).sdo().with_options(s.sdo_options());
            match sdo.write_bytes(index, sub, data).await {
                Ok(()) => ok(),
                Err(e) => net_error(&e),
            }
        }
    }
}

/// The node an SDO request is for: the one given, else the default; 0 (all nodes) has no SDO
/// server.
fn sdo_node(given: Option<u8>, s: &Session) -> Result<u8, Bad> {
    match given.or(s.node) {
        None => Err(Bad::code(Code::NoDefaultNode)),
        Some(0) => Err(Bad::because(
            Code::UnsupportedNode,
            "node 0 (all nodes) has no SDO server",
        )),
        Some(n) => Ok(n),
    }
}

/// `info version`: vendor-ID, product code, revision, serial number, gateway class, protocol
/// version, implementation version. duocan has no CiA vendor-ID: 0, product 0, serial 0;
/// revision and implementation are the tool's version; class 1 (SDO and NMT); protocol 3.0
/// (CiA 309-3 version 3.0).
fn version() -> String {
    let v = env!("CARGO_PKG_VERSION");
    let mut parts = v.split('.');
    let major = parts.next().unwrap_or("0");
    let minor = parts.next().unwrap_or("0");
    format!("0 0 {major}.{minor} 0 1 3.0 {major}.{minor}")
}
