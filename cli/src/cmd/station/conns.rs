//! The bound on the station's open HTTP connections (REST, event streams, dashboards, all
//! together): a listener that hands the HTTP server a connection only while fewer than
//! `http_max_connections` are open ([`config::Http`](super::config::Http)).
//!
//! One more is answered `503 Service Unavailable` with a JSON message, closed and counted
//! ([`ConnStats`], in `/metrics`); a browser's keep-alive or an event stream holds its slot
//! until it closes, so the bound is on what the station holds, not on the request rate (that
//! is [`access`](super::access)'s). So that idle clients cannot hold every slot, a connection
//! is closed when nothing moved on it for [`IDLE`] since it opened or since the station last
//! wrote to it (an event stream writes a keep-alive comment every 15 s; a dashboard asks twice
//! a second), or for [`BUSY`] since the client last sent something (a request may be worked on
//! that long: an LSS fastscan of many devices says nothing until it is done). Refusals are bounded too:
//! at most [`MAX_REFUSING`] at once, each for at most [`REFUSAL`]; a flood beyond that is
//! closed without a word (and still counted).

use axum::serve::Listener;
use std::future::Future as _;
use std::io;
use std::pin::Pin;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::task::{Context, Poll};
use std::time::Duration;
use tokio::io::{AsyncRead, AsyncReadExt as _, AsyncWrite, AsyncWriteExt as _, ReadBuf};
use tokio::sync::{OwnedSemaphorePermit, Semaphore};

/// A connection on which nothing moved for this long since it opened or since the station
/// last wrote to it is closed.
pub const IDLE: Duration = Duration::from_secs(60);
/// A connection on which nothing moved for this long since the client last sent something is
/// closed.
pub const BUSY: Duration = Duration::from_secs(600);
/// Refusals answered at once; more connections beyond the bound are closed at once.
pub const MAX_REFUSING: usize = 16;
/// How long a refusal may take: its answer written, the client's request read away so that
/// closing does not reset the connection before the client reads the answer.
pub const REFUSAL: Duration = Duration::from_secs(2);

struct Inner {
    max: usize,
    idle: Duration,
    open: Arc<Semaphore>,
    refusing: Arc<Semaphore>,
    refused: AtomicU64,
}

/// The connections open and refused, shared by the listener and `/metrics`.
#[derive(Clone)]
pub struct ConnStats(Arc<Inner>);

impl ConnStats {
    /// Counts for at most `max` connections at once, each closed after [`IDLE`] idle.
    pub fn new(max: usize) -> Self {
        Self::with_idle(max, IDLE)
    }

    /// Counts for at most `max` connections at once, each closed after `idle` idle.
    pub fn with_idle(max: usize, idle: Duration) -> Self {
        Self(Arc::new(Inner {
            max,
            idle,
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

/// A connection that holds its slot until it is dropped, and fails its reads once it has
/// been idle too long (the server then closes it).
pub struct Counted<Io> {
    io: Io,
    _slot: OwnedSemaphorePermit,
    idle: Duration,
    /// When it is idle too long, put off by every byte read or written.
    deadline: Pin<Box<tokio::time::Sleep>>,
}

impl<Io> Counted<Io> {
    fn new(io: Io, slot: OwnedSemaphorePermit, idle: Duration) -> Self {
        let deadline = Box::pin(tokio::time::sleep(idle));
        Self {
            io,
            _slot: slot,
            idle,
            deadline,
        }
    }

    /// The connection itself.
    pub fn inner(&self) -> &Io {
        &self.io
    }

    /// Something moved (`read`: from the client, which may now wait for its answer): the
    /// idle time starts over.
    fn moved(&mut self, read: bool) {
        let idle = if read { BUSY.max(self.idle) } else { self.idle };
        self.deadline
            .as_mut()
            .reset(tokio::time::Instant::now() + idle);
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
                return (Counted::new(io, slot, self.stats.0.idle), addr);
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
        let me = self.get_mut();
        let before = buf.filled().len();
        match Pin::new(&mut me.io).poll_read(cx, buf) {
            Poll::Ready(Ok(())) if buf.filled().len() > before => {
                me.moved(true);
                Poll::Ready(Ok(()))
            }
            Poll::Pending => match me.deadline.as_mut().poll(cx) {
                Poll::Ready(()) => Poll::Ready(Err(io::ErrorKind::TimedOut.into())),
                Poll::Pending => Poll::Pending,
            },
            done => done,
        }
    }
}

impl<Io: AsyncWrite + Unpin> AsyncWrite for Counted<Io> {
    fn poll_write(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<io::Result<usize>> {
        let me = self.get_mut();
        let r = Pin::new(&mut me.io).poll_write(cx, buf);
        if matches!(r, Poll::Ready(Ok(n)) if n > 0) {
            me.moved(false);
        }
        r
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
        let me = self.get_mut();
        let r = Pin::new(&mut me.io).poll_write_vectored(cx, bufs);
        if matches!(r, Poll::Ready(Ok(n)) if n > 0) {
            me.moved(false);
        }
        r
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

    #[tokio::test]
    async fn an_idle_connection_is_closed_and_frees_its_slot() {
        let tcp = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
        let addr = tcp.local_addr().unwrap();
        let stats = ConnStats::with_idle(1, Duration::from_millis(300));
        let mut l = Bounded::new(tcp, stats.clone());
        let mut client = tokio::net::TcpStream::connect(addr).await.unwrap();
        let (mut conn, _) = l.accept().await;
        // Bytes keep it open: one read within the idle time, one written back.
        client.write_all(b"x").await.unwrap();
        let mut one = [0u8; 1];
        conn.read_exact(&mut one).await.unwrap();
        // Then silence after the last write: the next read fails once the idle time is
        // over, not before.
        let started = tokio::time::Instant::now();
        conn.write_all(b"y").await.unwrap();
        client.read_exact(&mut one).await.unwrap();
        let read = tokio::time::timeout(Duration::from_secs(10), conn.read(&mut one)).await;
        let e = read.expect("still waiting after 10 s").unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::TimedOut);
        assert!(
            started.elapsed() >= Duration::from_millis(250),
            "{:?}",
            started.elapsed()
        );
        assert_eq!(stats.open(), 1);
        drop(conn);
        assert_eq!(stats.open(), 0);
    }
}
