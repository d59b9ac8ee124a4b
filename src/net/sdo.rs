//! A remote node's SDO server: typed values, strings and domains.

use super::door::Door;
use super::error::NetError;
use super::remote::RemoteNode;
use super::starts::{Begin, Start, Stream};
use super::usdo::UsdoStart;
use crate::cia301::sdo::{SdoOptions, TransferMode};
use crate::frame::cob_id::NodeId;
use crate::od::OdValue;
use tokio::sync::oneshot;

/// A node's turn, held for one transfer.
pub(super) type Turn<'a> = tokio::sync::MutexGuard<'a, ()>;

/// The SDO server of a [`RemoteNode`]: `node.sdo().read::<u32>(0x1018, 1).await?`.
///
/// Values are addressed by `(index, sub)` and typed by the Rust type asked for (any
/// [`OdValue`]: the unsigned and signed integers, `f32`, `f64`, `bool`); a value of another
/// size than the type is [`NetError::WrongSize`]. Strings and domains of any size up to
/// [`MAX_TRANSFER`](super::MAX_TRANSFER) go whole, in the smallest transfer mode that fits
/// unless the options say otherwise; domains of any size stream from an `AsyncRead` or to an
/// `AsyncWrite` ([`RemoteSdo::write_from`], [`RemoteSdo::read_to`]).
#[derive(Clone)]
pub struct RemoteSdo {
    pub(super) node: RemoteNode,
    pub(super) opts: SdoOptions,
}

impl RemoteSdo {
    pub(super) fn new(node: RemoteNode, opts: SdoOptions) -> Self {
        RemoteSdo { node, opts }
    }

    pub(super) fn remote(&self) -> &RemoteNode {
        &self.node
    }

    /// These transfers with other options (mode, timeout, block size, CRC).
    #[must_use]
    pub fn with_options(mut self, opts: SdoOptions) -> Self {
        self.opts = opts;
        self
    }

    /// These transfers in `mode` (expedited, segmented, block).
    #[must_use]
    pub fn with_mode(mut self, mode: TransferMode) -> Self {
        self.opts = self.opts.with_mode(mode);
        self
    }

    /// Reads a value of type `T`.
    pub async fn read<T: OdValue>(&self, index: u16, sub: u8) -> Result<T, NetError> {
        let data = self.transfer(index, sub, None).await?;
        T::decode(&data).ok_or(NetError::WrongSize {
            node: self.node.id()?,
            index,
            sub,
            expected: core::mem::size_of::<T>(),
            got: data.len(),
        })
    }

    /// Writes a value of type `T` (its little-endian bytes, as CANopen sends them).
    pub async fn write<T: OdValue>(&self, index: u16, sub: u8, value: T) -> Result<(), NetError> {
        let mut buf = [0; 8];
        let n = value.encode(&mut buf);
        self.transfer(index, sub, Some(buf[..n].to_vec()))
            .await
            .map(drop)
    }

    /// Reads a VISIBLE_STRING (or any text): UTF-8, with trailing NULs some nodes pad with
    /// removed.
    pub async fn read_string(&self, index: u16, sub: u8) -> Result<String, NetError> {
        let mut data = self.transfer(index, sub, None).await?;
        while data.last() == Some(&0) {
            data.pop();
        }
        match String::from_utf8(data) {
            Ok(s) => Ok(s),
            Err(_) => Err(NetError::NotText {
                node: self.node.id()?,
                index,
                sub,
            }),
        }
    }

    /// Writes a string's bytes.
    pub async fn write_string(&self, index: u16, sub: u8, text: &str) -> Result<(), NetError> {
        self.write_bytes(index, sub, text.as_bytes()).await
    }

    /// Reads the raw bytes of any entry (a DOMAIN, an OCTET_STRING, a record's raw value).
    pub async fn read_bytes(&self, index: u16, sub: u8) -> Result<Vec<u8>, NetError> {
        self.transfer(index, sub, None).await
    }

    /// Writes raw bytes to any entry.
    pub async fn write_bytes(
        &self,
        index: u16,
        sub: u8,
        data: impl Into<Vec<u8>>,
    ) -> Result<(), NetError> {
        self.transfer(index, sub, Some(data.into())).await.map(drop)
    }

    /// Waits for this node's turn (held while the guard lives).
    pub(super) async fn turn(&self) -> Result<(NodeId, Turn<'_>), NetError> {
        let node = self.node.id()?;
        let net = self.node.network();
        if net.is_listen_only() {
            return Err(NetError::ListenOnly { node: Some(node) });
        }
        let turn = net.shared.per_node[usize::from(node.raw())].lock().await;
        Ok((node, turn))
    }

    /// One transfer: a read when `data` is `None`. Transfers to one node take turns; a start
    /// the core's client refuses as busy or for want of a session waits in the door, at most
    /// for the transfer's own timeout ([`super::starts`]).
    async fn transfer(
        &self,
        index: u16,
        sub: u8,
        data: Option<Vec<u8>>,
    ) -> Result<Vec<u8>, NetError> {
        let (node, _turn) = self.turn().await?;
        if self.node.network().shared.opts.fd.is_some() {
            return self.usdo(node, index, sub, data).await;
        }
        let opts = self.opts;
        let begin: Begin = Box::new(move |c, now| match &data {
            None => c.upload(now, node, index, sub, opts),
            Some(v) => c.download(now, node, index, sub, v, opts),
        });
        self.submit(node, None, begin).await
    }

    /// One whole-value transfer over USDO, on a CANopen FD network ([`super::usdo`]).
    async fn usdo(
        &self,
        node: NodeId,
        index: u16,
        sub: u8,
        data: Option<Vec<u8>>,
    ) -> Result<Vec<u8>, NetError> {
        let (reply, outcome) = oneshot::channel();
        let timeout = self.opts.timeout;
        let handle = &self.node.network().shared.handle;
        let started = handle
            .try_call(move |d: &mut Door, now| {
                let start = UsdoStart {
                    node,
                    index,
                    sub,
                    data,
                    timeout,
                    due: now + timeout,
                    reply,
                };
                d.usdo(now, start)
            })
            .await;
        finished(node, started, outcome).await
    }

    /// Hands a transfer's start to the door and waits for its outcome: the data read (empty
    /// for a write, the data not yet taken for a stream) or the error.
    pub(super) async fn submit(
        &self,
        node: NodeId,
        stream: Option<Stream>,
        begin: Begin,
    ) -> Result<Vec<u8>, NetError> {
        let (reply, outcome) = oneshot::channel();
        let timeout = self.opts.timeout;
        let handle = &self.node.network().shared.handle;
        let started = handle
            .try_call(move |d: &mut Door, now| {
                let due = now + timeout;
                d.sdo(
                    now,
                    Start {
                        begin,
                        due,
                        reply,
                        stream,
                    },
                )
            })
            .await;
        finished(node, started, outcome).await
    }
}

/// A transfer handed to the door (`started`), waited for to its outcome; a standby master's
/// refusal names the node asked.
async fn finished(
    node: NodeId,
    started: Result<(), NetError>,
    outcome: oneshot::Receiver<Result<Vec<u8>, NetError>>,
) -> Result<Vec<u8>, NetError> {
    let r = match started {
        Ok(()) => outcome.await.unwrap_or(Err(NetError::Closed)),
        Err(e) => Err(e),
    };
    r.map_err(|e| match e {
        NetError::Standby { node: None } => NetError::Standby { node: Some(node) },
        e => e,
    })
}
