//! Serving clients: one task per connection, each with its own [`Session`], a bounded number
//! at once, on a TCP port or a local socket, until told to stop. The standalone gateway and the
//! station's gateway share this: they differ only in the networks they hand it
//! ([`GatewayNets`]) and in what stops them.

use super::exec::{answer, Session};
use super::nets::GatewayNets;
use super::MAX_LINE;
use std::future::Future;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use tokio::io::{AsyncBufRead, AsyncBufReadExt, AsyncRead, AsyncWrite, AsyncWriteExt, BufReader};

/// What a gateway's listeners serve, and their bounds: shared by its TCP port and its local
/// socket, so that the client limit is for both together.
#[derive(Clone)]
pub struct Served {
    nets: Arc<GatewayNets>,
    timeout_ms: u64,
    slots: Arc<tokio::sync::Semaphore>,
    max_clients: usize,
    refused: Arc<AtomicU64>,
    note: fn(&str),
}

/// A gateway's client counts as they are now, for a station's `/metrics`: cheap to clone,
/// read at any time while the gateway serves (and after).
#[derive(Clone)]
pub struct GatewayStats {
    slots: Arc<tokio::sync::Semaphore>,
    max_clients: usize,
    refused: Arc<AtomicU64>,
}

impl GatewayStats {
    /// Clients refused so far because the limit was reached (each told `ERROR:102`).
    #[must_use]
    pub fn refused(&self) -> u64 {
        self.refused.load(Ordering::Relaxed)
    }
    /// Clients being served now, on every listener together.
    #[must_use]
    pub fn clients(&self) -> usize {
        self.max_clients
            .saturating_sub(self.slots.available_permits())
    }
    /// The limit of clients at once.
    #[must_use]
    pub fn max_clients(&self) -> usize {
        self.max_clients
    }
}

impl Served {
    /// `nets` for at most `max_clients` clients at once, each starting with the SDO time-out
    /// `timeout_ms`; `note` tells the operator what the listeners cannot tell a client (an
    /// accept that failed, a client refused).
    pub fn new(nets: GatewayNets, timeout_ms: u64, max_clients: usize, note: fn(&str)) -> Served {
        Served {
            nets: Arc::new(nets),
            timeout_ms,
            slots: Arc::new(tokio::sync::Semaphore::new(max_clients)),
            max_clients,
            refused: Arc::new(AtomicU64::new(0)),
            note,
        }
    }

    /// The counts of its clients, live.
    #[must_use]
    pub fn stats(&self) -> GatewayStats {
        GatewayStats {
            slots: self.slots.clone(),
            max_clients: self.max_clients,
            refused: self.refused.clone(),
        }
    }
}

/// A bound listener: a TCP port or a local socket.
#[derive(Debug)]
pub enum GatewayListener {
    /// A TCP port.
    Tcp(tokio::net::TcpListener),
    /// A local (Unix domain) stream socket.
    Unix(tokio::net::UnixListener),
}

/// Accepts clients on `listener` until `stop` is ready, then ends every connection (a
/// request being carried out is dropped with it, as when its client goes away).
pub async fn accept(listener: GatewayListener, served: Served, stop: impl Future<Output = ()>) {
    tokio::pin!(stop);
    let mut clients = tokio::task::JoinSet::new();
    loop {
        let accepted = tokio::select! {
            r = accept_one(&listener) => r,
            () = &mut stop => break,
            // Finished clients reaped as they go: the set holds the live ones only.
            Some(_) = clients.join_next(), if !clients.is_empty() => continue,
        };
        match accepted {
            Ok(Stream::Tcp(s)) => client(&served, &mut clients, s).await,
            Ok(Stream::Unix(s)) => client(&served, &mut clients, s).await,
            // A client that went away before it was accepted: keep serving the others. A
            // pause, so that an error that lasts (no file descriptors left) does not spin.
            Err(e) => {
                (served.note)(&format!("accept: {e}"));
                tokio::time::sleep(std::time::Duration::from_millis(50)).await;
            }
        }
    }
    clients.abort_all();
    while clients.join_next().await.is_some() {}
}

enum Stream {
    Tcp(tokio::net::TcpStream),
    Unix(tokio::net::UnixStream),
}

async fn accept_one(listener: &GatewayListener) -> std::io::Result<Stream> {
    match listener {
        GatewayListener::Tcp(l) => l.accept().await.map(|(s, _)| Stream::Tcp(s)),
        GatewayListener::Unix(l) => l.accept().await.map(|(s, _)| Stream::Unix(s)),
    }
}

/// Serves one accepted client in a task of `clients`, or tells it `ERROR:102` and closes it
/// when the limit is reached (counted, and noted).
async fn client<S>(served: &Served, clients: &mut tokio::task::JoinSet<()>, mut stream: S)
where
    S: AsyncRead + AsyncWrite + Unpin + Send + 'static,
{
    let Ok(slot) = served.slots.clone().try_acquire_owned() else {
        let n = served.refused.fetch_add(1, Ordering::Relaxed) + 1;
        (served.note)(&format!(
            "a client refused: too many clients at once ({n} refused so far)"
        ));
        // Bounded: a client that does not read its refusal is not waited for.
        let refusal =
            b"[0] ERROR:102 #request not processed in the present state: too many clients\r\n";
        let _ = tokio::time::timeout(std::time::Duration::from_secs(1), stream.write_all(refusal))
            .await;
        return;
    };
    let nets = served.nets.clone();
    let timeout_ms = served.timeout_ms;
    clients.spawn(async move {
        let (r, w) = tokio::io::split(stream);
        serve(&nets, timeout_ms, BufReader::new(r), w, "\r\n").await;
        drop(slot);
    });
}

/// Answers the requests of one client, line by line, until its input ends (or its output
/// cannot be written). Each answer ends with `eol`, once: the lines of a longer answer (the
/// help) are parted by LF alone, as CANopenNode's are, since `cocomm` reads an answer up to
/// the first CR LF.
pub async fn serve<R, W>(
    nets: &GatewayNets,
    timeout_ms: u64,
    mut input: R,
    mut output: W,
    eol: &str,
) where
    R: AsyncBufRead + Unpin,
    W: AsyncWrite + Unpin,
{
    let mut session = Session::new(nets.default_net(), timeout_ms);
    let mut buf = Vec::new();
    loop {
        let response = match read_line(&mut input, &mut buf).await {
            Ok(Some(true)) => match std::str::from_utf8(&buf) {
                Ok(line) => answer(nets, &mut session, line).await,
                Err(_) => "[0] ERROR:101 #syntax error: the line is not UTF-8 text".to_string(),
            },
            Ok(Some(false)) => {
                format!("[0] ERROR:101 #syntax error: a line longer than {MAX_LINE} bytes")
            }
            Ok(None) | Err(_) => return,
        };
        let text = response + eol;
        if output.write_all(text.as_bytes()).await.is_err() || output.flush().await.is_err() {
            return;
        }
    }
}

/// Reads one line into `buf` (without its LF): `Some(true)`; `Some(false)` for a line longer
/// than [`MAX_LINE`] (read to its end and dropped, never held whole); `None` at the end of
/// input.
pub async fn read_line<R: AsyncBufRead + Unpin>(
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
