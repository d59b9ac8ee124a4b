//! The port's blocking side ([`Port::reader`](crate::port::Port::reader)): a reader thread
//! receives the group's datagrams as a bare loop does, one `recvfrom` each, and sends the
//! device's answers on a send socket of its own; the port's task keeps sending on the port's
//! (non-blocking) one.
//!
//! Why a second send socket: the blocking one waits at most [`READER_WAIT`] for room, while
//! the task's must never wait, and a socket's blocking mode is shared by every handle of it.
//! Both sockets' datagrams come back through multicast loopback; the reader drops those of
//! either, as the port drops its own. Each frame comes with its datagram's receive timestamp,
//! as the port's own reads give it (see `rx.rs`).

use super::rx::Stamps;
use super::{decode, encode, open_tx, timestamp, UdpBusConfig};
use crate::port::asynch::{timed_out, READER_WAIT};
use crate::port::{PortCounters, PortError, PortInput, PortReader};
use crate::Frame;
use std::io;
use std::net::{SocketAddr, UdpSocket};

/// Receives and answers by blocking, each call waiting at most [`READER_WAIT`].
pub(super) struct Reader {
    name: String,
    channel: Option<String>,
    rx: UdpSocket,
    tx: UdpSocket,
    /// The port's send socket and this reader's: datagrams from them are our own.
    own: [SocketAddr; 2],
    dest: SocketAddr,
    counters: PortCounters,
    buf: Vec<u8>,
    stamps: Stamps,
}

impl Reader {
    /// A reader on the port's receive socket `rx` (made blocking) with a new blocking send
    /// socket; `own` is the port's send socket's address, `stamps` the port's conversion.
    pub(super) fn new(
        cfg: &UdpBusConfig,
        name: &str,
        rx: UdpSocket,
        own: SocketAddr,
        dest: SocketAddr,
        counters: PortCounters,
        stamps: Stamps,
    ) -> Result<Reader, (UdpSocket, PortError)> {
        let io = |what: &str, e| PortError::io(name, what, e);
        let blocking = |s: &UdpSocket| {
            s.set_nonblocking(false)?;
            s.set_read_timeout(Some(READER_WAIT))?;
            s.set_write_timeout(Some(READER_WAIT))
        };
        if let Err(e) = blocking(&rx) {
            return Err((rx, io("blocking receive socket", e)));
        }
        let tx = match open_tx(cfg, name).and_then(|(tx, addr)| {
            blocking(&tx).map_err(|e| io("blocking send socket", e))?;
            Ok((tx, addr))
        }) {
            Ok(tx) => tx,
            Err(e) => return Err((rx, e)),
        };
        Ok(Reader {
            name: name.to_owned(),
            channel: cfg.channel.clone(),
            rx,
            own: [own, tx.1],
            tx: tx.0,
            dest,
            counters,
            buf: vec![0; super::MAX_DATAGRAM],
            stamps,
        })
    }
}

impl PortReader for Reader {
    fn read(&mut self) -> Result<Option<PortInput>, PortError> {
        loop {
            let (n, from, at, dropped) = match self.stamps.recv(&self.rx, &mut self.buf) {
                Ok(x) => x,
                Err(e) if timed_out(&e) => return Ok(None),
                Err(e) => return Err(PortError::io(&self.name, "receive failed", e)),
            };
            if let Some(d) = dropped {
                self.counters.rx_overrun_total(d);
            }
            if from.is_some_and(|a| self.own.contains(&a)) {
                continue;
            }
            match decode(self.buf.get(..n).unwrap_or_default()) {
                Ok((f, _)) => {
                    self.counters.rx_frames();
                    return Ok(Some(PortInput::Frame(f, at)));
                }
                Err(e) => {
                    self.counters.rx_invalid();
                    tracing::warn!(port = %self.name, ?from, len = n, error = %e, "datagram refused");
                }
            }
        }
    }

    fn write(&mut self, frame: &Frame) -> Result<bool, PortError> {
        let bytes = encode(frame, timestamp(), self.channel.as_deref());
        match self.tx.send_to(&bytes, self.dest) {
            Ok(_) => {
                self.counters.tx_frames();
                Ok(true)
            }
            Err(e) if timed_out(&e) => Ok(false),
            Err(e) => {
                self.counters.tx_failed();
                Err(PortError::io(&self.name, "send failed", e))
            }
        }
    }
}

/// Makes a receive socket taken from a reader's failed start usable by the port again.
pub(super) fn back_to_async(rx: UdpSocket) -> io::Result<tokio::net::UdpSocket> {
    rx.set_nonblocking(true)?;
    tokio::net::UdpSocket::from_std(rx)
}
