//! Streamed SDO transfers through the front door: domains of any size from an `AsyncRead` or
//! into an `AsyncWrite`, with progress.
//!
//! **The rule.** [`RemoteSdo::write_from`] feeds the client's streamed download
//! ([`SdoClient::download_stream`](crate::sdo::SdoClient::download_stream)) from a reader as
//! its window has room; [`RemoteSdo::read_to`] writes what a streamed upload received into a
//! writer as it arrives. The core wakes the caller through the network's device when there is
//! room to fill or data to take; nothing is polled on a timer.
//!
//! **Memory.** This side holds one window ([`STREAM_WINDOW`] bytes in the client, one copy of
//! it here), whatever the value's size. The node's SDO server is another matter: a duocan
//! node collects a download whole before its dictionary sees it, so the largest value it takes
//! is its own transfer limit.
//!
//! **Back-pressure.** A slow writer holds the upload (the client stops acknowledging), a slow
//! reader holds the download; either longer than the SDO timeout aborts the transfer, as the
//! node would.
//!
//! **On a CANopen FD network** ([`NetOptions::with_fd`](super::NetOptions::with_fd)) the nodes
//! serve USDO, which duocan has no streamed transfer of: a stream goes whole over USDO
//! ([`super::usdo`]), read into memory or collected from the reader first, so it is bounded by
//! [`MAX_TRANSFER`](super::MAX_TRANSFER) (beyond it, [`SdoErrorKind::TooLong`]); the calls,
//! the bytes and the errors are the same, the progress is told once, at the end.
//!
//! **Errors.** The one [`NetError`]: the node's or the client's abort as
//! [`NetError::Sdo`], the local reader's or writer's failure as [`NetError::Io`] (the transfer
//! is aborted and the node told).
//!
//! ```
//! use duocan::net::{NetError, Network};
//!
//! # #[tokio::main] async fn main() -> Result<(), NetError> {
//! let net = Network::open_named("sim-nodes")?;
//! let sdo = net.node(5).sdo();
//! let mut name = Vec::new();
//! let n = sdo.read_to(0x1008, 0, &mut name, |p| println!("{} of {:?}", p.done, p.total)).await?;
//! assert_eq!(n, 21);
//! assert_eq!(name, duocan::net::SIM_DEVICE_NAME.as_bytes());
//! # Ok(()) }
//! ```

use super::door::Door;
use super::error::NetError;
use super::sdo::RemoteSdo;
use super::starts::Stream;
use crate::cia301::sdo::{Direction, RequestId, SdoError, SdoErrorKind, TransferMode};
use crate::frame::cob_id::NodeId;
use crate::od::abort::AbortCode;
use crate::runtime::Handle;
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};

/// The window of a streamed transfer: what the client buffers of a value at most.
pub const STREAM_WINDOW: usize = 4096;

/// How long a transfer aborted for a local failure keeps the node's turn.
const SETTLE: std::time::Duration = std::time::Duration::from_millis(20);

/// How far a streamed transfer is, as its progress callback sees it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub struct TransferProgress {
    /// Bytes done: confirmed by the node (a write) or written to the writer (a read).
    pub done: u64,
    /// The value's size, if known: given to the write, announced by the node for a read.
    pub total: Option<u64>,
}

/// A streamed transfer running: its id (known once the runtime started it) and its wake-up.
struct Running {
    handle: Handle<Door>,
    stream: Stream,
    node: NodeId,
    index: u16,
    sub: u8,
}

impl Running {
    fn id(&self) -> Option<RequestId> {
        self.stream.id.lock().ok().and_then(|g| *g)
    }

    /// Aborts the transfer after a local failure and names the failure.
    async fn fail(&self, e: std::io::Error) -> NetError {
        if let Some(id) = self.id() {
            let _ = self
                .handle
                .try_call(move |d, now| {
                    d.core.client()?.abort(now, id, AbortCode::GENERAL);
                    // Its session is free now, not at the next input: a start waiting for
                    // one takes it.
                    d.retry(now);
                    Ok::<_, NetError>(())
                })
                .await;
            // The node may have answered the last frame before it heard the abort: that
            // answer must not meet the next transfer to it (which would take it for its own
            // and abort), so this one keeps the node's turn until it has passed.
            tokio::time::sleep(SETTLE).await;
        }
        NetError::Io {
            node: self.node,
            index: self.index,
            sub: self.sub,
            kind: e.kind(),
            message: e.to_string(),
        }
    }
}

impl RemoteSdo {
    /// Reads (index, sub), a value of any size, into `out` as it arrives, and returns its
    /// length; `progress` hears how far it is after every piece written. The client holds at
    /// most [`STREAM_WINDOW`] bytes of it; python `canopen`'s `node.sdo[i][s].open("rb")`.
    pub async fn read_to<W: AsyncWrite + Unpin>(
        &self,
        index: u16,
        sub: u8,
        mut out: W,
        mut progress: impl FnMut(TransferProgress),
    ) -> Result<u64, NetError> {
        if self.is_fd() {
            let data = self.read_bytes(index, sub).await?;
            let node = self.node.id()?;
            out.write_all(&data)
                .await
                .map_err(|e| io(node, index, sub, e))?;
            out.flush().await.map_err(|e| io(node, index, sub, e))?;
            let n = data.len() as u64;
            progress(TransferProgress {
                done: n,
                total: Some(n),
            });
            return Ok(n);
        }
        let (node, _turn) = self.turn().await?;
        let opts = self.opts;
        let (run, done) = self.start(node, index, sub, move |c, now| {
            c.upload_stream(now, node, index, sub, STREAM_WINDOW, opts)
        });
        tokio::pin!(done);
        let mut buf = vec![0; STREAM_WINDOW];
        let mut written = 0u64;
        loop {
            tokio::select! {
                biased;
                r = &mut done => {
                    let tail = r?;
                    if let Err(e) = out.write_all(&tail).await {
                        return Err(run.fail(e).await);
                    }
                    out.flush().await.map_err(|e| io(node, index, sub, e))?;
                    written += tail.len() as u64;
                    progress(TransferProgress { done: written, total: Some(written) });
                    return Ok(written);
                }
                _ = run.stream.wake.notified() => {
                    let Some(id) = run.id() else { continue };
                    let (back, n, total) = run
                        .handle
                        .try_call(move |d, now| {
                            let c = d.core.client()?;
                            let n = c.read_stream(now, id, &mut buf).unwrap_or(0);
                            let total = c.stream_progress(id).and_then(|(_, t)| t);
                            Ok::<_, NetError>((buf, n, total))
                        })
                        .await?;
                    buf = back;
                    if n == 0 {
                        continue;
                    }
                    if let Err(e) = out.write_all(&buf[..n]).await {
                        return Err(run.fail(e).await);
                    }
                    written += n as u64;
                    progress(TransferProgress { done: written, total: total.map(|t| t as u64) });
                }
            }
        }
    }

    /// Writes (index, sub) from `input`, a value of any size, and returns its length: `size`
    /// bytes (announced to the node; an input that ends sooner is an error, one that goes on
    /// is not read further), or everything up to the end of `input` if `None`. `progress`
    /// hears how much the node has confirmed. The client holds at most [`STREAM_WINDOW`]
    /// bytes of it; python `canopen`'s `node.sdo[i][s].open("wb", size=n)`. A `size` of 1 to
    /// 4 bytes goes expedited (unless the options ask for segmented or block transfer), as
    /// [`write_bytes`](Self::write_bytes) sends it; with [`TransferMode::Expedited`] any other
    /// size is refused ([`SdoErrorKind::TransferMode`]).
    pub async fn write_from<R: AsyncRead + Unpin>(
        &self,
        index: u16,
        sub: u8,
        mut input: R,
        size: Option<u64>,
        mut progress: impl FnMut(TransferProgress),
    ) -> Result<u64, NetError> {
        let announced = match size.map(u32::try_from) {
            Some(Err(_)) => {
                return Err(NetError::Argument(format!(
                    "a size of {} bytes cannot be announced over SDO (at most {}): give None to stream without one",
                    size.unwrap_or(0),
                    u32::MAX
                )))
            }
            Some(Ok(n)) => Some(n),
            None => None,
        };
        if self.is_fd() {
            return self.write_whole(index, sub, input, size, progress).await;
        }
        // A stream is never expedited (the initiate would carry the data, not there yet):
        // 1 to 4 bytes announced are read first and written as `write_bytes` writes them,
        // expedited unless segmented or block transfer is asked for. Expedited asked for any
        // other size is refused as `write_bytes` refuses it, not sent segmented.
        match (self.opts.mode, announced) {
            (TransferMode::Auto | TransferMode::Expedited, Some(n @ 1..=4)) => {
                let mut data = vec![0; n as usize];
                if let Err(e) = input.read_exact(&mut data).await {
                    return Err(NetError::Io {
                        node: self.node.id()?,
                        index,
                        sub,
                        kind: e.kind(),
                        message: format!("the input ended before the {n} bytes announced: {e}"),
                    });
                }
                self.write_bytes(index, sub, data).await?;
                progress(TransferProgress {
                    done: u64::from(n),
                    total: size,
                });
                return Ok(u64::from(n));
            }
            (TransferMode::Expedited, _) => {
                return Err(NetError::Sdo(SdoError {
                    node: self.node.id()?,
                    index,
                    sub,
                    direction: Direction::Download,
                    kind: SdoErrorKind::TransferMode,
                }))
            }
            _ => {}
        }
        let (node, _turn) = self.turn().await?;
        let opts = self.opts;
        let (run, done) = self.start(node, index, sub, move |c, now| {
            c.download_stream(now, node, index, sub, announced, STREAM_WINDOW, opts)
        });
        tokio::pin!(done);
        let mut buf = vec![0; STREAM_WINDOW];
        let mut fed = 0u64;
        let mut ended = false;
        let mut room = 0;
        let mut confirmed = 0;
        loop {
            tokio::select! {
                biased;
                r = &mut done => {
                    r?;
                    progress(TransferProgress { done: fed, total: size });
                    return Ok(fed);
                }
                _ = run.stream.wake.notified(), if room == 0 => {
                    let Some(id) = run.id() else { continue };
                    room = run.handle.try_call(move |d, _| Ok::<_, NetError>(d.core.client()?.wants_data(id))).await?;
                }
                r = read_some(&mut input, &mut buf, room, size.map(|s| s - fed)), if room > 0 && !ended => {
                    let n = match r {
                        Ok(n) => n,
                        Err(e) => return Err(run.fail(e).await),
                    };
                    fed += n as u64;
                    ended = n == 0 || size == Some(fed);
                    if n == 0 && size.is_some_and(|s| fed < s) {
                        let e = std::io::Error::new(
                            std::io::ErrorKind::UnexpectedEof,
                            format!("the input ended after {fed} of the {} bytes announced", size.unwrap_or(0)),
                        );
                        return Err(run.fail(e).await);
                    }
                    let Some(id) = run.id() else { continue };
                    let chunk = buf[..n].to_vec();
                    let (left, done) = run
                        .handle
                        .try_call(move |d, now| {
                            let c = d.core.client()?;
                            let _ = c.feed(now, id, &chunk, ended);
                            Ok::<_, NetError>((c.wants_data(id), c.stream_progress(id).map(|(d, _)| d)))
                        })
                        .await?;
                    room = left;
                    if let Some(d) = done.filter(|d| *d > confirmed) {
                        confirmed = d;
                        progress(TransferProgress { done: d as u64, total: size });
                    }
                }
            }
        }
    }

    /// Starts a streamed transfer with `begin` (through the door, which registers its wake-up
    /// as it starts); returns it and the future of its outcome (the data not yet taken).
    fn start<F>(
        &self,
        node: NodeId,
        index: u16,
        sub: u8,
        begin: F,
    ) -> (
        Running,
        impl std::future::Future<Output = Result<Vec<u8>, NetError>> + '_,
    )
    where
        F: FnMut(&mut super::NetClient, crate::Instant) -> Result<RequestId, crate::sdo::SdoError>
            + Send
            + 'static,
    {
        let run = Running {
            handle: self.node.network().shared.handle.clone(),
            stream: Stream::default(),
            node,
            index,
            sub,
        };
        let done = self.submit(node, Some(run.stream.clone()), Box::new(begin));
        (run, done)
    }
}

/// Reads at most `room` bytes (and no more than `left` of an announced size) into `buf`.
async fn read_some<R: AsyncRead + Unpin>(
    input: &mut R,
    buf: &mut [u8],
    room: usize,
    left: Option<u64>,
) -> std::io::Result<usize> {
    let n = left.map_or(room, |l| room.min(usize::try_from(l).unwrap_or(usize::MAX)));
    let n = n.min(buf.len());
    if n == 0 {
        return Ok(0);
    }
    input.read(&mut buf[..n]).await
}

impl RemoteSdo {
    /// True on a CANopen FD network: transfers go over USDO.
    fn is_fd(&self) -> bool {
        self.node.network().shared.opts.fd.is_some()
    }

    /// [`RemoteSdo::write_from`] on a CANopen FD network: the input collected whole (at most
    /// [`MAX_TRANSFER`](super::MAX_TRANSFER) bytes), then one USDO write.
    async fn write_whole<R: AsyncRead + Unpin>(
        &self,
        index: u16,
        sub: u8,
        input: R,
        size: Option<u64>,
        mut progress: impl FnMut(TransferProgress),
    ) -> Result<u64, NetError> {
        let node = self.node.id()?;
        let limit = super::MAX_TRANSFER;
        let too_long = |len: u64| {
            NetError::Sdo(SdoError {
                node,
                index,
                sub,
                direction: Direction::Download,
                kind: SdoErrorKind::TooLong {
                    len: usize::try_from(len).unwrap_or(usize::MAX),
                    limit,
                },
            })
        };
        if let Some(n) = size.filter(|&n| n > limit as u64) {
            return Err(too_long(n));
        }
        // One byte past the limit, to tell a value too long from one that fits exactly.
        let want = size.unwrap_or(limit as u64 + 1);
        let mut data = Vec::new();
        input
            .take(want)
            .read_to_end(&mut data)
            .await
            .map_err(|e| io(node, index, sub, e))?;
        let n = data.len() as u64;
        if n > limit as u64 {
            return Err(too_long(n));
        }
        if let Some(s) = size.filter(|&s| n < s) {
            return Err(NetError::Io {
                node,
                index,
                sub,
                kind: std::io::ErrorKind::UnexpectedEof,
                message: format!("the input ended after {n} of the {s} bytes announced"),
            });
        }
        self.write_bytes(index, sub, data).await?;
        progress(TransferProgress {
            done: n,
            total: Some(n),
        });
        Ok(n)
    }
}

fn io(node: NodeId, index: u16, sub: u8, e: std::io::Error) -> NetError {
    NetError::Io {
        node,
        index,
        sub,
        kind: e.kind(),
        message: e.to_string(),
    }
}
