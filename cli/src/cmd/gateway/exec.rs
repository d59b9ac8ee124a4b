//! Carrying out a request on the network, and the one line that answers it.

use super::parse::{parse_line, Code, Command, Line, Request};
use super::value::{show_value, ValueError};
use duocan::net::{NetError, Network};
use duocan::sdo::{SdoOptions, TransferMode};
use duocan::Duration;

/// The only net: a duocan gateway serves one logical bus (two ports merged are one net).
pub const NET: u16 = 1;

/// The SDO abort code answered for a value read whose size is not its type's.
const LENGTH_MISMATCH: u32 = 0x0607_0010;

/// What one client has set: its default net and node, and how its SDO transfers go. Each
/// client (standard input, or one TCP connection) has its own.
#[derive(Clone, Debug)]
pub struct Session {
    net: u16,
    node: Option<u8>,
    timeout_ms: u64,
    block: bool,
}

impl Session {
    /// A new client's settings: net 1, no default node, SDO time-out `timeout_ms`, block
    /// transfer off.
    pub fn new(timeout_ms: u64) -> Session {
        Session {
            net: NET,
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

/// The answer to `line`: `None` for a blank line or a comment, else the response (lines
/// before the last one are `#` comments: the help).
pub async fn answer(net: &Network, session: &mut Session, line: &str) -> Option<String> {
    let (seq, body) = match parse_line(line) {
        Line::Empty => return None,
        Line::Error(seq, code) => (seq, error(code)),
        Line::Request(r) => (r.seq, execute(net, session, r).await),
    };
    Some(match seq {
        Some(n) => with_sequence(n, &body),
        None => body,
    })
}

/// `[<n>] ` in front of the response's last line (the one a client waits for).
fn with_sequence(n: u32, body: &str) -> String {
    match body.rsplit_once('\n') {
        Some((comments, last)) => format!("{comments}\n[{n}] {last}"),
        None => format!("[{n}] {body}"),
    }
}

fn error(code: Code) -> String {
    format!("ERROR: {}", code as u16)
}

fn ok() -> String {
    "OK".to_string()
}

/// The response to a network error: the SDO abort code if there is one (a time-out is the
/// client's abort 0x05040000), else the 309-3 code closest to what happened.
fn net_error(e: &NetError) -> String {
    match e.abort_code() {
        Some(code) => format!("ERROR: 0x{:08X}", code.0),
        None => error(match e {
            NetError::Timeout { .. } => Code::Timeout,
            _ => Code::InternalState,
        }),
    }
}

async fn execute(net: &Network, s: &mut Session, r: Request) -> String {
    // The net a request names, or the default: there is only net 1.
    if r.net.unwrap_or(s.net) != NET && r.command != Command::NotSupported {
        return error(Code::UnsupportedNet);
    }
    match r.command {
        Command::SetNetwork(n) if n == NET => {
            s.net = n;
            ok()
        }
        Command::SetNetwork(_) => error(Code::UnsupportedNet),
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
        Command::Version => version(),
        Command::Help => super::help::text(),
        Command::NotSupported => error(Code::NotSupported),
        Command::Nmt(cmd) => {
            let Some(node) = r.node.or(s.node) else {
                return error(Code::NoDefaultNode);
            };
            let sent = if node == 0 {
                net.nmt_all(cmd).await
            } else {
                net.node(node).send_nmt(cmd).await
            };
            sent.map_or_else(|e| net_error(&e), |()| ok())
        }
        Command::Read { index, sub, ty } => {
            let sdo = match sdo_node(r.node, s) {
                Ok(node) => net.node(node).sdo().with_options(s.sdo_options()),
                Err(code) => return error(code),
            };
            match sdo.read_bytes(index, sub).await {
                Ok(data) => match show_value(ty, &data) {
                    Ok(text) => text,
                    Err(ValueError::Length | ValueError::Syntax) => {
                        format!("ERROR: 0x{LENGTH_MISMATCH:08X}")
                    }
                },
                Err(e) => net_error(&e),
            }
        }
        Command::Write { index, sub, data } => {
            let sdo = match sdo_node(r.node, s) {
                Ok(node) => net.node(node).sdo().with_options(s.sdo_options()),
                Err(code) => return error(code),
            };
            match sdo.write_bytes(index, sub, data).await {
                Ok(()) => ok(),
                Err(e) => net_error(&e),
            }
        }
    }
}

/// The node an SDO request is for: the one given, else the default; 0 (all nodes) has no SDO
/// server.
fn sdo_node(given: Option<u8>, s: &Session) -> Result<u8, Code> {
    match given.or(s.node) {
        None => Err(Code::NoDefaultNode),
        Some(0) => Err(Code::UnsupportedNode),
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
