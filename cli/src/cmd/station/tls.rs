//! HTTPS for the station ([`serve`] serves plain HTTP too): a listener that hands the HTTP server only connections whose TLS
//! handshake is done (the certificate and key of the station file,
//! [`config::Tls`](super::config::Tls)).
//!
//! Handshakes run side by side, each bounded in time ([`HANDSHAKE`]) and at most
//! [`MAX_HANDSHAKES`] at once: a client that connects and says nothing, or speaks plain HTTP
//! to the HTTPS port, holds up no one else and is dropped.

use super::conns::{Bounded, ConnStats};
use axum::extract::connect_info::IntoMakeServiceWithConnectInfo;
use rustls::ServerConfig;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::{mpsc, Semaphore};
use tokio_rustls::server::TlsStream;
use tokio_rustls::TlsAcceptor;

/// A handshake not done after this long is given up.
pub const HANDSHAKE: Duration = Duration::from_secs(10);
/// Handshakes under way at once; more connections wait in the kernel's backlog.
pub const MAX_HANDSHAKES: usize = 32;

/// Connections over TLS, for `axum::serve`.
pub struct Listener {
    ready: mpsc::Receiver<(TlsStream<TcpStream>, SocketAddr)>,
    local: SocketAddr,
    accepting: tokio::task::JoinHandle<()>,
}

impl Listener {
    /// Takes the connections of `tcp` and shakes hands with each under `config`.
    pub fn new(tcp: TcpListener, config: Arc<ServerConfig>) -> std::io::Result<Self> {
        let local = tcp.local_addr()?;
        let acceptor = TlsAcceptor::from(config);
        let (tx, ready) = mpsc::channel(MAX_HANDSHAKES);
        let accepting = tokio::spawn(async move {
            let turns = Arc::new(Semaphore::new(MAX_HANDSHAKES));
            loop {
                let Ok(turn) = turns.clone().acquire_owned().await else {
                    return;
                };
                let (stream, peer) = match tcp.accept().await {
                    Ok(c) => c,
                    Err(e) => {
                        // Out of file descriptors, say: accepting again at once would spin.
                        tracing::warn!(target: "duocan::station", "https: accept: {e}");
                        tokio::time::sleep(Duration::from_millis(500)).await;
                        continue;
                    }
                };
                let (acceptor, tx) = (acceptor.clone(), tx.clone());
                tokio::spawn(async move {
                    let _turn = turn;
                    match tokio::time::timeout(HANDSHAKE, acceptor.accept(stream)).await {
                        Ok(Ok(tls)) => {
                            let _ = tx.send((tls, peer)).await;
                        }
                        Ok(Err(e)) => {
                            tracing::debug!(target: "duocan::station", "https: {peer}: {e}");
                        }
                        Err(_) => {
                            tracing::debug!(target: "duocan::station", "https: {peer}: handshake timed out");
                        }
                    }
                });
            }
        });
        Ok(Self {
            ready,
            local,
            accepting,
        })
    }
}

impl Drop for Listener {
    fn drop(&mut self) {
        self.accepting.abort();
    }
}

impl axum::serve::Listener for Listener {
    type Io = TlsStream<TcpStream>;
    type Addr = SocketAddr;

    async fn accept(&mut self) -> (Self::Io, Self::Addr) {
        match self.ready.recv().await {
            Some(c) => c,
            // The accepting task ended (the runtime stops): no connection comes any more.
            None => std::future::pending().await,
        }
    }

    fn local_addr(&self) -> std::io::Result<SocketAddr> {
        Ok(self.local)
    }
}

/// Serves `app` on `tcp`, over TLS under `config` if given, until the runtime stops; at most
/// `conns.max()` connections at once (over TLS: handshakes done).
pub async fn serve(
    tcp: TcpListener,
    config: Option<Arc<ServerConfig>>,
    app: IntoMakeServiceWithConnectInfo<axum::Router, SocketAddr>,
    conns: ConnStats,
) {
    use axum::serve::ListenerExt as _;
    // Small answers go out at once rather than wait for more to fill a segment. (The tap
    // also gives each request its client's address: axum knows it of a tapped listener.)
    let done = match config {
        Some(config) => match Listener::new(tcp, config) {
            Ok(tls) => {
                let tls = Bounded::new(tls, conns).tap_io(|s| {
                    let _ = s.inner().get_ref().0.set_nodelay(true);
                });
                axum::serve(tls, app).await
            }
            Err(e) => Err(e),
        },
        None => {
            let tcp = Bounded::new(tcp, conns).tap_io(|s| {
                let _ = s.inner().set_nodelay(true);
            });
            axum::serve(tcp, app).await
        }
    };
    if let Err(e) = done {
        tracing::error!(target: "duocan::station", "http: {e}");
    }
}
