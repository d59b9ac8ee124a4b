//! `duocan gateway [--listen ADDR:PORT [--allow-remote]]`: the CiA 309-3 ASCII command
//! interface, so that scripts written for other CANopen gateways (CANopenNode's `cocomm`,
//! commercial 309-3 gateways) drive a duocan network unchanged.
//!
//! **What it speaks.** One request per line, on standard input (the default; until end of
//! input) or on a TCP port (`--listen`, several clients at once):
//!
//! ```text
//! ["[" <sequence> "]"] [[<net>] <node>] <command>      # a comment
//! [1] 5 read 0x1018 1 u32          SDO upload            -> [1] 13683200
//! [2] 5 w 0x1017 0 u16 250         SDO download          -> [2] OK
//! [3] set node 5                   default node          -> [3] OK
//! [4] r 0x1008 0 vs                (node 5)              -> [4] "duocan simulated node"
//! [5] start                        NMT (node 0: all)     -> [5] OK
//! [6] r 0x1234 0 u8                the node aborts       -> [6] ERROR: 0x06020000
//! ```
//!
//! Commands: `r[ead]`, `w[rite]`, `start`, `stop`, `preop[erational]`, `reset node`,
//! `reset comm[unication]`, `set network`, `set node`, `set sdo_timeout <ms>`,
//! `set sdo_block <0|1>`, `info version`, `help`; the data types are those of 309-3
//! (`b`, `i8`…`i64`, `u8`…`u64`, `r32`, `r64`, `vs`, `os`, `us`, `d`, `t`, `td`) with
//! CANopenNode's `x8`…`x64` and `hex` (see `value`). Commands and types are case-insensitive;
//! `#` starts a comment; blank lines and comments get no response.
//!
//! **What it answers.** Exactly one line per request, in order: `OK`, the value, or
//! `ERROR: <code>`, behind the request's `[<sequence>]` when it had one. The codes are 309-3's
//! internal ones (100 request not supported, 101 syntax error, 102 not processed as things
//! are, 103 time-out, 105 no default node, 106 unsupported net, 107 unsupported node) or the
//! SDO abort code in hex (`ERROR: 0x06020000`; a node that does not answer in time is the
//! client's abort `0x05040000`). `help` answers with `#` comment lines, then `OK`. Lines end
//! with LF on standard output and CR LF on TCP, as 309-3 writes them; a request may end with
//! either.
//!
//! **Its state.** Each client (standard input, or one TCP connection) has its own default
//! node (none at first: a request without a node is `ERROR: 105` until `set node`), SDO
//! time-out (`--timeout` at first) and block-transfer switch (off). There is one net, 1: the
//! bus of `--bus` (two ports merged by the dual-bus layer are one net); another is
//! `ERROR: 106`.
//!
//! **What it does not do, and says so.** Node guarding and heartbeat-consumer set-up
//! (`enable`/`disable guarding|heartbeat`), PDO configuration and transfer (`set rpdo`,
//! `set tpdo`, `r[ead] p[do]`, `w[rite] p[do]`), `init`, `set heartbeat`, `set id`,
//! `set command_*`, `boot_up_indication`, the LSS requests and CANopenNode's `led` and `log`
//! are recognised and answered `ERROR: 100`; so is any command 309-3 does not have. Nothing
//! is sent unasked: no boot-up, EMCY or PDO indications.
//!
//! **Bounds.** A request line is at most [`MAX_LINE`] bytes (longer: `ERROR: 101`, the line
//! skipped); a value at most the library's transfer limit (64 KiB); at most [`MAX_CLIENTS`]
//! TCP clients at once (one more is told `ERROR: 102` and closed). The port is loopback-only
//! unless `--allow-remote`: the gateway has no authentication, and anyone who reaches it
//! drives the bus.

mod exec;
mod help;
mod parse;
mod value;

#[cfg(test)]
mod tests;

use crate::fail::Fail;
use crate::{bus, Global};
use duocan::net::Network;
use exec::{answer, Session};
use std::net::SocketAddr;
use std::sync::Arc;
use tokio::io::{AsyncBufRead, AsyncBufReadExt, AsyncWrite, AsyncWriteExt, BufReader};

/// Longest request line, in bytes: room for a 64 KiB domain in base64 and the words around it.
pub const MAX_LINE: usize = 128 * 1024;

/// Most TCP clients served at once.
pub const MAX_CLIENTS: usize = 16;

/// The arguments of `duocan gateway`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Serve on this TCP address instead of standard input (127.0.0.1:PORT; port 0 picks a
    /// free one, printed on standard error)
    #[arg(long, value_name = "ADDR:PORT")]
    listen: Option<SocketAddr>,
    /// Accept --listen on an address other than loopback (no authentication: anyone who
    /// reaches the port drives the bus)
    #[arg(long, requires = "listen")]
    allow_remote: bool,
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
    let bus = bus::open(g, false)?;
    let r = match a.listen {
        None => {
            let input = BufReader::new(tokio::io::stdin());
            serve(&bus.net, g.timeout, input, tokio::io::stdout(), "\n").await;
            Ok(())
        }
        Some(addr) => listen(&bus.net, g.timeout, addr).await,
    };
    bus.close().await;
    r
}

/// Serves TCP clients on `addr` until interrupted.
async fn listen(net: &Network, timeout_ms: u64, addr: SocketAddr) -> Result<(), Fail> {
    let listener = tokio::net::TcpListener::bind(addr)
        .await
        .map_err(|e| Fail::usage(format!("--listen {addr}: {e}")))?;
    let bound = listener.local_addr()?;
    eprintln!("duocan gateway: listening on {bound}");
    let slots = Arc::new(tokio::sync::Semaphore::new(MAX_CLIENTS));
    loop {
        let (mut stream, _) = tokio::select! {
            r = listener.accept() => match r {
                Ok(c) => c,
                Err(e) => {
                    // A client that went away before it was accepted: keep serving the others.
                    eprintln!("duocan gateway: accept: {e}");
                    continue;
                }
            },
            _ = tokio::signal::ctrl_c() => return Ok(()),
        };
        let Ok(slot) = slots.clone().try_acquire_owned() else {
            let _ = stream.write_all(b"ERROR: 102\r\n").await;
            continue;
        };
        let net = net.clone();
        tokio::spawn(async move {
            let (r, w) = stream.split();
            serve(&net, timeout_ms, BufReader::new(r), w, "\r\n").await;
            drop(slot);
        });
    }
}

/// Answers the requests of one client, line by line, until its input ends (or its output
/// cannot be written).
async fn serve<R, W>(net: &Network, timeout_ms: u64, mut input: R, mut output: W, eol: &str)
where
    R: AsyncBufRead + Unpin,
    W: AsyncWrite + Unpin,
{
    let mut session = Session::new(timeout_ms);
    let mut buf = Vec::new();
    loop {
        let response = match read_line(&mut input, &mut buf).await {
            Ok(Some(true)) => match std::str::from_utf8(&buf) {
                Ok(line) => answer(net, &mut session, line).await,
                Err(_) => Some("ERROR: 101".to_string()),
            },
            Ok(Some(false)) => Some("ERROR: 101".to_string()),
            Ok(None) | Err(_) => return,
        };
        if let Some(text) = response {
            let text = text.replace('\n', eol) + eol;
            if output.write_all(text.as_bytes()).await.is_err() || output.flush().await.is_err() {
                return;
            }
        }
    }
}

/// Reads one line into `buf` (without its LF): `Some(true)`; `Some(false)` for a line longer
/// than [`MAX_LINE`] (read to its end and dropped, never held whole); `None` at the end of
/// input.
async fn read_line<R: AsyncBufRead + Unpin>(
    input: &mut R,
    buf: &mut Vec<u8>,
) -> std::io::Result<Option<bool>> {
    buf.clear();
    let mut too_long = false;
    loop {
        let chunk = input.fill_buf().await?;
        if chunk.is_empty() {
            // End of input: a last line without its LF still counts.
            return Ok((!buf.is_empty() || too_long).then_some(!too_long));
        }
        let (part, done) = match chunk.iter().position(|b| *b == b'\n') {
            Some(i) => (&chunk[..i], i + 1),
            None => (chunk, chunk.len()),
        };
        if !too_long {
            if buf.len() + part.len() > MAX_LINE {
                too_long = true;
                buf.clear();
            } else {
                buf.extend_from_slice(part);
            }
        }
        let ended = done > part.len();
        input.consume(done);
        if ended {
            return Ok(Some(!too_long));
        }
    }
}
