//! The bound on the station's open HTTP connections (REST, event streams, dashboards, all
//! together): a listener that hands the HTTP server a connection only while fewer than
//! `http_max_connections` are open ([`config::Http`](super::config::Http)).
//!
//! One more is answered `503 Service Unavailable` with a JSON message, closed and counted
//! ([`ConnStats`], in `/metrics`); a browser's keep-alive or an event stream holds its slot
//! until it closes, so the bound is on what the station holds, not on the request rate (that
//! is [`access`](super::access)'s). Refusals are bounded too: at most [`MAX_REFUSING`] at
//! once, each for at most [`REFUSAL`]; a flood beyond that is closed without a word (and
//! still counted).

use axum::serve::Listener;
use std::io;
use std::pin::Pin;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::task::{Context, Poll};
use std::time::Duration;
use tokio::io::{AsyncRead, AsyncReadExt as _, AsyncWrite, AsyncWriteExt as _, ReadBuf};
use tokio::sync::{OwnedSemaphorePermit, Semaphore};

/// Refusals answered at once; more connections beyond the bound are closed at once.
pub const MAX_REFUSING: usize = 16;
/// How long a refusal may take: its answer written, the client's request read away so that
/// closing does not reset the connection before the client reads the answer.
pub const REFUSAL: Duration = Duration::from_secs(2);

struct Inner {
    max: usize,
    open: Arc<Semaphore>,
    refusing: Arc<Semaphore>,
    refused: AtomicU64,
}

/// The connections open and refused, shared by the listener and `/metrics`.
#[derive(Clone)]
pub struct ConnStats(Arc<Inner>);

impl ConnStats {
    /// Counts for at most `max` connections at once.
    pub fn new(max: usize) -> Self {
        Self(Arc::new(Inner {
            max,
            open: Arc::new(Semaphore::new(max)),
            refusing: Arc::new(Semaphore::new(MAX_REFUSING)),
            refused: AtomicU64::new(0),
        }))
    }

    /// Connections open now.
    pub fn open(&self) -> usize {
        self.0.max - self.0.open.available_permits()
    }

    /// The most connections open at once.
    pub fn max(&self) -> usize {
        self.0.max
    }

    /// Connections refused so far for want of room.
    pub fn refused(&self) -> u64 {
        self.0.refused.load(Ordering::Relaxed)
    }
}

/// A listener whose connections are bounded by a [`ConnStats`].
pub struct Bounded<L> {
    inner: L,
    stats: ConnStats,
}

impl<L> Bounded<L> {
    /// `inner`'s connections, at most `stats.max()` open at once.
    pub fn new(inner: L, stats: ConnStats) -> Self {
        Self { inner, stats }
    }
}

/// A connection that holds its slot until it is dropped.
pub struct Counted<Io> {
    io: Io,
    _slot: OwnedSemaphorePermit,
}

impl<Io> Counted<Io> {
    /// The connection itself.
    pub fn inner(&self) -> &Io {
        &self.io
    }
}

impl<L> Listener for Bounded<L>
where
    L: Listener,
    L::Io: AsyncRead + AsyncWrite + Unpin + Send + 'static,
{
    type Io = Counted<L::Io>;
    type Addr = L::Addr;

    async fn accept(&mut self) -> (Self::Io, Self::Addr) {
        loop {
            let (io, addr) = self.inner.accept().await;
            if let Ok(slot) = self.stats.0.open.clone().try_acquire_owned() {
                return (Counted { io, _slot: slot }, addr);
            }
            self.stats.0.refused.fetch_add(1, Ordering::Relaxed);
            tracing::debug!(target: "duocan::station", "http: a connection refused: {} open",
                self.stats.max());
            if let Ok(turn) = self.stats.0.refusing.clone().try_acquire_owned() {
                let max = self.stats.max();
                tokio::spawn(async move {
                    let _turn = turn;
                    let _ = tokio::time::timeout(REFUSAL, refuse(io, max)).await;
                });
            }
        }
    }

    fn local_addr(&self) -> io::Result<Self::Addr> {
        self.inner.local_addr()
    }
}

/// The 503 of a connection beyond the bound of `max`.
pub fn refusal(max: usize) -> String {
    let body = serde_json::json!({
        "error": format!("too many connections open (at most {max}): try again later"),
    })
    .to_string();
    format!(
        "HTTP/1.1 503 Service Unavailable\r\ncontent-type: application/json\r\n\
         content-length: {}\r\nretry-after: 1\r\nconnection: close\r\n\r\n{body}",
        body.len()
    )
}

async fn refuse<Io: AsyncRead + AsyncWrite + Unpin>(mut io: Io, max: usize) -> io::Result<()> {
    io.write_all(refusal(max).as_bytes()).await?;
    io.shutdown().await?;
    // Read what the client sent until it closes (bounded by REFUSAL and this much): a socket
    // closed with unread data resets, and the reset may overtake the answer.
    let mut buf = [0u8; 1024];
    let mut left = 64 * 1024usize;
    while left > 0 {
        match io.read(&mut buf).await? {
            0 => break,
            n => left = left.saturating_sub(n),
        }
    }
    Ok(())
}

impl<Io: AsyncRead + Unpin> AsyncRead for Counted<Io> {
    fn poll_read(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<io::Result<()>> {
        Pin::new(&mut self.get_mut().io).poll_read(cx, buf)
    }
}

impl<Io: AsyncWrite + Unpin> AsyncWrite for Counted<Io> {
    fn poll_write(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<io::Result<usize>> {
        Pin::new(&mut self.get_mut().io).poll_write(cx, buf)
    }

    fn poll_flush(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.get_mut().io).poll_flush(cx)
    }

    fn poll_shutdown(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.get_mut().io).poll_shutdown(cx)
    }

    fn poll_write_vectored(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        bufs: &[io::IoSlice<'_>],
    ) -> Poll<io::Result<usize>> {
        Pin::new(&mut self.get_mut().io).poll_write_vectored(cx, bufs)
    }

    fn is_write_vectored(&self) -> bool {
        self.io.is_write_vectored()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn one_connection_beyond_the_bound_is_refused_with_a_503() {
        let tcp = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
        let addr = tcp.local_addr().unwrap();
        let stats = ConnStats::new(2);
        let mut l = Bounded::new(tcp, stats.clone());
        let a = tokio::net::TcpStream::connect(addr).await.unwrap();
        let (ca, _) = l.accept().await;
        let _b = tokio::net::TcpStream::connect(addr).await.unwrap();
        let (_cb, _) = l.accept().await;
        assert_eq!(stats.open(), 2);
        let mut c = tokio::net::TcpStream::connect(addr).await.unwrap();
        c.write_all(b"GET / HTTP/1.1\r\n\r\n").await.unwrap();
        // The third is refused while accept waits for a fourth.
        let accepting = tokio::spawn(async move { l.accept().await });
        let mut answer = String::new();
        c.read_to_string(&mut answer).await.unwrap();
        assert!(answer.starts_with("HTTP/1.1 503 "), "{answer}");
        assert!(
            answer.ends_with("(at most 2): try again later\"}"),
            "{answer}"
        );
        assert_eq!(stats.refused(), 1);
        // A slot freed is a connection taken again.
        drop((a, ca));
        assert_eq!(stats.open(), 1);
        let _d = tokio::net::TcpStream::connect(addr).await.unwrap();
        let got = tokio::time::timeout(Duration::from_secs(10), accepting).await;
        let Ok(Ok(_fourth)) = got else {
            panic!("the fourth was not taken");
        };
        assert_eq!((stats.open(), stats.refused()), (2, 1));
    }
}
