//! A remote node: its SDO server, NMT commands, its state and the waits on it.

use super::core::CoreEvent;
use super::door::Door;
use super::error::{Awaited, NetError};
use super::events::NetEvent;
use super::sdo::RemoteSdo;
use super::Network;
use crate::cia301::nmt::{NmtCommand, NmtState, NmtTarget};
use crate::eds::Description;
use crate::frame::cob_id::NodeId;
use crate::frame::instant::Instant;
use crate::runtime::RuntimeClosed;
use std::path::Path;
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::oneshot;

/// One node on a [`Network`], by node-ID; get it with [`Network::node`]. Cheap to clone.
///
/// **The boot-up rule.** A boot-up counts for [`RemoteNode::wait_for_boot_up`] if it arrived
/// at or after the moment this object was made (`net.node(5)`), even if that was before the
/// wait started: `node.reset().await?; node.wait_for_boot_up(t).await?` cannot miss a node
/// that boots faster than the caller gets to the wait (python `canopen` only counts boot-ups
/// that arrive after the wait begins). [`RemoteNode::wait_for_boot_up_since`] takes the
/// instant explicitly.
#[derive(Clone)]
pub struct RemoteNode {
    net: Network,
    raw: u8,
    since: Instant,
    desc: Option<Arc<Description>>,
}

/// The end of a watch: its result, or why there is none.
enum Watch<R> {
    /// It was already true when the watch started.
    Done(R),
    /// The runtime stopped, or the waiter went away.
    Closed,
}

impl<R> From<RuntimeClosed> for Watch<R> {
    fn from(_: RuntimeClosed) -> Self {
        Watch::Closed
    }
}

impl RemoteNode {
    pub(super) fn new(
        net: Network,
        raw: u8,
        since: Instant,
        desc: Option<Arc<Description>>,
    ) -> Self {
        RemoteNode {
            net,
            raw,
            since,
            desc,
        }
    }

    /// This node with a device description attached (for this handle and its clones; use
    /// [`Network::add_node`] to attach it for every handle): names from it work in the by-name
    /// calls ([`RemoteSdo::read_named`]) and name the values of received PDOs.
    #[must_use]
    pub fn with_description(mut self, desc: impl Into<Arc<Description>>) -> Self {
        self.desc = Some(desc.into());
        self
    }

    /// [`RemoteNode::with_description`] from an EDS or DCF file (read leniently: what a real
    /// file gets wrong is a warning in [`Description::warnings`], not an error).
    pub fn with_eds(self, path: impl AsRef<Path>) -> Result<Self, NetError> {
        Ok(self.with_description(Description::read(path)?))
    }

    /// The device description attached, if any.
    #[must_use]
    pub fn description(&self) -> Option<&Description> {
        self.desc.as_deref()
    }

    pub(super) fn description_arc(&self) -> Option<Arc<Description>> {
        self.desc.clone()
    }

    /// The node-ID, or the error every call on an invalid one returns.
    pub fn id(&self) -> Result<NodeId, NetError> {
        NodeId::new(self.raw).ok_or(NetError::NoSuchNode(self.raw))
    }

    /// The node's SDO server, with the network's SDO options.
    #[must_use]
    pub fn sdo(&self) -> RemoteSdo {
        RemoteSdo::new(self.clone(), self.net.shared.opts.sdo)
    }

    pub(super) fn network(&self) -> &Network {
        &self.net
    }

    /// Sends an NMT command to this node.
    pub async fn send_nmt(&self, cmd: NmtCommand) -> Result<(), NetError> {
        let id = self.id()?;
        self.net.nmt(Some(id), cmd, NmtTarget::Node(id)).await
    }
    /// NMT start: the node goes operational.
    pub async fn start(&self) -> Result<(), NetError> {
        self.send_nmt(NmtCommand::Start).await
    }
    /// NMT stop: the node goes stopped.
    pub async fn stop(&self) -> Result<(), NetError> {
        self.send_nmt(NmtCommand::Stop).await
    }
    /// NMT enter pre-operational.
    pub async fn enter_pre_operational(&self) -> Result<(), NetError> {
        self.send_nmt(NmtCommand::EnterPreOperational).await
    }
    /// NMT reset node: the node reboots and sends a boot-up.
    pub async fn reset(&self) -> Result<(), NetError> {
        self.send_nmt(NmtCommand::ResetNode).await
    }
    /// NMT reset communication: the node sends a boot-up.
    pub async fn reset_communication(&self) -> Result<(), NetError> {
        self.send_nmt(NmtCommand::ResetCommunication).await
    }

    /// The node's last state heard (boot-up, heartbeat), `None` if it was never heard.
    pub async fn state(&self) -> Result<Option<NmtState>, NetError> {
        let id = self.id()?;
        let h = &self.net.shared.handle;
        Ok(h.call(move |d, _| d.core.remote(id).map(|(s, _)| s))
            .await?)
    }

    /// When the node's last boot-up arrived, if one did since the network was opened.
    pub async fn last_boot_up(&self) -> Result<Option<Instant>, NetError> {
        let id = self.id()?;
        let h = &self.net.shared.handle;
        Ok(h.call(move |d, _| d.boot_ups[usize::from(id.raw())])
            .await?)
    }

    /// Watches the node's heartbeat: if none arrives for `timeout`, the network reports
    /// [`NetEvent::HeartbeatLost`] (and [`NetEvent::HeartbeatResumed`] when it comes back).
    /// A node that sends nothing at all for `timeout` from this call on is reported too, as
    /// [`NetEvent::NotHeard`] (CiA 301 monitoring starts at the first heartbeat, so a node dead
    /// from the start would otherwise go unnoticed). The timeout is in whole milliseconds, at
    /// most 65 535 (what the consumer entry 0x1016 holds; longer is capped); zero stops
    /// watching. Nothing is sent to the node. On a core that guards some nodes itself (a
    /// redundant master's slaves), watching one of those changes nothing, and its loss is
    /// that core's own event.
    pub async fn watch_heartbeat(&self, timeout: Duration) -> Result<(), NetError> {
        let id = self.id()?;
        let ms = u16::try_from(timeout.as_millis()).unwrap_or(u16::MAX);
        let h = &self.net.shared.handle;
        h.try_call(move |d, now| {
            d.core.watch_heartbeat(now, id, ms)?;
            d.await_first(now, id, crate::Duration::from_millis(u64::from(ms)));
            Ok(())
        })
        .await
    }

    /// Waits until the node's heartbeat says `state` (at once if the last one did), at most
    /// `timeout`.
    pub async fn wait_for_state(&self, state: NmtState, timeout: Duration) -> Result<(), NetError> {
        let id = self.id()?;
        self.watch(
            Awaited::State(state),
            timeout,
            move |d| (d.core.remote(id).map(|(s, _)| s) == Some(state)).then_some(()),
            move |e| match *e {
                NetEvent::State { node, to, .. } if node == id && to == state => Some(()),
                _ => None,
            },
        )
        .await
    }

    /// Waits for the node's boot-up, at most `timeout`, and returns when it arrived. A boot-up
    /// since this object was made counts (the rule in the type's documentation).
    pub async fn wait_for_boot_up(&self, timeout: Duration) -> Result<Instant, NetError> {
        self.wait_for_boot_up_since(self.since, timeout).await
    }

    /// Waits for a boot-up that arrived at or after `since` (a [`Network::now`] reading), at
    /// most `timeout`, and returns when it arrived.
    pub async fn wait_for_boot_up_since(
        &self,
        since: Instant,
        timeout: Duration,
    ) -> Result<Instant, NetError> {
        let id = self.id()?;
        self.watch(
            Awaited::BootUp,
            timeout,
            move |d| d.boot_ups[usize::from(id.raw())].filter(|t| *t >= since),
            move |e| match *e {
                NetEvent::BootUp { node, at } if node == id && at >= since => Some(at),
                _ => None,
            },
        )
        .await
    }

    /// Waits at most `timeout` for `pick` to accept an event of this node, unless `now`
    /// already answers. Both run inside the runtime in one step, so nothing falls between
    /// the check and the watch.
    pub(super) async fn watch<R: Send + 'static>(
        &self,
        awaited: Awaited,
        timeout: Duration,
        now: impl FnOnce(&mut Door) -> Option<R> + Send + 'static,
        mut pick: impl FnMut(&NetEvent) -> Option<R> + Send + 'static,
    ) -> Result<R, NetError> {
        let node = self.id()?;
        // The watcher inside the runtime lets go at the next event after this side gave up.
        let (alive, _waiting) = oneshot::channel::<()>();
        let w = self.net.shared.handle.request(
            move |d, _| match now(d) {
                Some(r) => Err(Watch::Done(r)),
                None => Ok(()),
            },
            move |(), e| {
                if alive.is_closed() {
                    return Some(Err(Watch::Closed));
                }
                match e {
                    CoreEvent::Net(e) => pick(e).map(Ok),
                    _ => None,
                }
            },
        );
        match tokio::time::timeout(timeout, w).await {
            Ok(Ok(r) | Err(Watch::Done(r))) => Ok(r),
            Ok(Err(Watch::Closed)) => Err(NetError::Closed),
            Err(_) => Err(NetError::Timeout {
                node,
                awaited,
                after: timeout,
            }),
        }
    }
}
