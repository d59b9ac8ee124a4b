//! A node on a redundant network: its SDO server (typed, as on a single bus), NMT commands and
//! the master's view of it.

use super::RedundantNetwork;
use crate::network::{NetworkError, RedundantError, Role};
use alloc::string::String;
use alloc::vec::Vec;
use duocan::master::SlaveView;
use duocan::nmt::NmtTarget;
use duocan::od::OdValue;
use duocan::sdo::{SdoErrorKind, SdoOptions, TransferMode};
use duocan::{NmtCommand, NodeId};

/// How often a transfer that found the node's SDO client busy with the network's own transfer
/// tries again: a few frames' time on a busy bus, short beside any SDO timeout.
const BUSY_RETRY: core::time::Duration = core::time::Duration::from_millis(5);

/// One node of a [`RedundantNetwork`], by node-ID; get it with [`RedundantNetwork::node`].
/// The same calls as the single-bus `duocan::net::RemoteNode`; the frames go out on both buses
/// and the answer is taken from whichever delivers it first.
#[derive(Clone)]
pub struct RedundantNode {
    net: RedundantNetwork,
    raw: u8,
}

impl RedundantNode {
    pub(super) fn new(net: RedundantNetwork, raw: u8) -> Self {
        RedundantNode { net, raw }
    }

    /// The node-ID, or the error every call on an invalid one returns.
    pub fn id(&self) -> Result<NodeId, RedundantError> {
        NodeId::new(self.raw).ok_or(RedundantError::BadNodeId {
            role: Role::Node,
            id: self.raw,
        })
    }

    /// The node's SDO server.
    #[must_use]
    pub fn sdo(&self) -> RedundantSdo {
        RedundantSdo {
            node: self.clone(),
            opts: self.net.sdo_options(),
        }
    }

    /// Sends an NMT command to this node (active master only).
    pub async fn send_nmt(&self, cmd: NmtCommand) -> Result<(), RedundantError> {
        let id = self.id()?;
        self.net.nmt(cmd, NmtTarget::Node(id)).await
    }
    /// NMT start: the node goes operational.
    pub async fn start(&self) -> Result<(), RedundantError> {
        self.send_nmt(NmtCommand::Start).await
    }
    /// NMT stop: the node goes stopped.
    pub async fn stop(&self) -> Result<(), RedundantError> {
        self.send_nmt(NmtCommand::Stop).await
    }
    /// NMT enter pre-operational.
    pub async fn enter_pre_operational(&self) -> Result<(), RedundantError> {
        self.send_nmt(NmtCommand::EnterPreOperational).await
    }
    /// NMT reset node.
    pub async fn reset(&self) -> Result<(), RedundantError> {
        self.send_nmt(NmtCommand::ResetNode).await
    }

    /// What the master knows of the node: its last state heard, whether it is lost, its
    /// boot process.
    pub async fn view(&self) -> Result<SlaveView, RedundantError> {
        let id = self.id()?;
        Ok(self.net.handle().call(move |n, _| n.slave(id)).await?)
    }
}

/// The SDO server of a [`RedundantNode`]: `node.sdo().read::<u32>(0x1018, 1).await?`, with the
/// method names of the single-bus `duocan::net::RemoteSdo`.
///
/// Values are addressed by `(index, sub)` and typed by the Rust type asked for (any
/// [`OdValue`]); a value of another size is [`RedundantError::WrongSize`]. Only the active
/// master runs SDO transfers: on a standby one they fail with
/// [`NetworkError::Standby`](crate::NetworkError::Standby).
#[derive(Clone)]
pub struct RedundantSdo {
    node: RedundantNode,
    opts: SdoOptions,
}

impl RedundantSdo {
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
    pub async fn read<T: OdValue>(&self, index: u16, sub: u8) -> Result<T, RedundantError> {
        let data = self.transfer(index, sub, None).await?;
        T::decode(&data).ok_or(RedundantError::WrongSize {
            node: self.node.id()?,
            index,
            sub,
            expected: core::mem::size_of::<T>(),
            got: data.len(),
        })
    }
    /// Writes a value of type `T` (its little-endian bytes).
    pub async fn write<T: OdValue>(
        &self,
        index: u16,
        sub: u8,
        value: T,
    ) -> Result<(), RedundantError> {
        let mut buf = [0; 8];
        let n = value.encode(&mut buf);
        self.transfer(index, sub, Some(buf[..n].to_vec()))
            .await
            .map(drop)
    }
    /// Reads text (trailing NULs removed).
    pub async fn read_string(&self, index: u16, sub: u8) -> Result<String, RedundantError> {
        let node = self.node.id()?;
        let mut data = self.transfer(index, sub, None).await?;
        while data.last() == Some(&0) {
            data.pop();
        }
        String::from_utf8(data).map_err(|_| RedundantError::NotText { node, index, sub })
    }
    /// Writes a string's bytes.
    pub async fn write_string(
        &self,
        index: u16,
        sub: u8,
        text: &str,
    ) -> Result<(), RedundantError> {
        self.write_bytes(index, sub, text.as_bytes()).await
    }
    /// Reads the raw bytes of any entry.
    pub async fn read_bytes(&self, index: u16, sub: u8) -> Result<Vec<u8>, RedundantError> {
        self.transfer(index, sub, None).await
    }
    /// Writes raw bytes to any entry.
    pub async fn write_bytes(
        &self,
        index: u16,
        sub: u8,
        data: impl Into<Vec<u8>>,
    ) -> Result<(), RedundantError> {
        self.transfer(index, sub, Some(data.into())).await.map(drop)
    }

    /// One transfer (a read when `data` is `None`). Transfers from this handle to one node take
    /// turns, but the network's own processes share the client with it: the supervisor checks
    /// and configures a pair member as it boots, over SDO. A transfer they have running makes a
    /// start "busy" (or leaves no session free); the call waits for it, trying again every
    /// [`BUSY_RETRY`] until the transfer's own timeout has passed, so that "busy" is never the
    /// caller's problem. Only the start is tried again: a transfer that ran and failed is the
    /// answer.
    async fn transfer(
        &self,
        index: u16,
        sub: u8,
        data: Option<Vec<u8>>,
    ) -> Result<Vec<u8>, RedundantError> {
        let node = self.node.id()?;
        let net = &self.node.net;
        let _turn = net.turn(node.raw()).lock().await;
        let h = net.handle();
        let give_up = tokio::time::Instant::now() + core::time::Duration::from(self.opts.timeout);
        loop {
            let r = match &data {
                None => h.sdo_read(node, index, sub, self.opts).await,
                Some(d) => h
                    .sdo_write(node, index, sub, d.clone(), self.opts)
                    .await
                    .map(|()| Vec::new()),
            };
            match r {
                Err(NetworkError::Sdo(e))
                    if matches!(e.kind, SdoErrorKind::Busy | SdoErrorKind::NoSession { .. })
                        && tokio::time::Instant::now() + BUSY_RETRY <= give_up =>
                {
                    tokio::time::sleep(BUSY_RETRY).await;
                }
                r => return r.map_err(RedundantError::from),
            }
        }
    }
}
