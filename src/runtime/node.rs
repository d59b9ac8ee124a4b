//! Typed handle operations for devices that contain a [`Node`].

use super::handle::{Handle, RuntimeError};
use crate::cia301::nmt::{NmtCommand, NmtState, NmtTarget};
use crate::frame::instant::Instant;
use crate::frame::storage::Storage;
use crate::machine::{Composite, Station};
use crate::node::{Node, QueueFull};
use crate::od::abort::AbortCode;
use crate::od::ObjectDictionary;
use crate::profile::IdProfile;

/// What the handle can do to the local node of a device (object-safe view of [`Node`]).
pub trait LocalNode {
    /// Reads an entry as the device itself.
    fn read_entry(&self, index: u16, sub: u8) -> Result<Vec<u8>, AbortCode>;
    /// Writes an entry as the device itself, with the stack's reactions.
    fn write_entry(
        &mut self,
        now: Instant,
        index: u16,
        sub: u8,
        data: &[u8],
    ) -> Result<(), AbortCode>;
    /// Queues an NMT command.
    fn send_nmt(
        &mut self,
        now: Instant,
        cmd: NmtCommand,
        target: NmtTarget,
    ) -> Result<(), QueueFull>;
    /// The local NMT state.
    fn state(&self) -> NmtState;
    /// Power-on: boot-up message, pre-operational (or operational for a master).
    fn power_on(&mut self, now: Instant);
}

impl<
        D: ObjectDictionary,
        P: IdProfile,
        const GUARDED: usize,
        const TPDOS: usize,
        const RPDOS: usize,
        S: Storage,
    > LocalNode for Node<D, P, GUARDED, TPDOS, RPDOS, S>
{
    fn read_entry(&self, index: u16, sub: u8) -> Result<Vec<u8>, AbortCode> {
        self.od().get(index, sub).map(|e| e.data.to_vec())
    }
    fn write_entry(
        &mut self,
        now: Instant,
        index: u16,
        sub: u8,
        data: &[u8],
    ) -> Result<(), AbortCode> {
        self.write(now, index, sub, data)
    }
    fn send_nmt(
        &mut self,
        now: Instant,
        cmd: NmtCommand,
        target: NmtTarget,
    ) -> Result<(), QueueFull> {
        self.nmt_command(now, cmd, target)
    }
    fn state(&self) -> NmtState {
        self.nmt_state()
    }
    fn power_on(&mut self, now: Instant) {
        self.boot(now)
    }
}

/// A device (or machine) with a local node in it.
pub trait NodeHost {
    /// The node.
    fn local_node(&mut self) -> &mut dyn LocalNode;
}

// A tapped machine records its frames and still hands out its node (the capture layer sits
// below the runtime, so the runtime says how the two fit).
impl<M: NodeHost> NodeHost for crate::capture::recorder::Tapped<M> {
    fn local_node(&mut self) -> &mut dyn LocalNode {
        self.inner.local_node()
    }
}

impl<
        D: ObjectDictionary,
        P: IdProfile,
        const GUARDED: usize,
        const TPDOS: usize,
        const RPDOS: usize,
        S: Storage,
    > NodeHost for Node<D, P, GUARDED, TPDOS, RPDOS, S>
{
    fn local_node(&mut self) -> &mut dyn LocalNode {
        self
    }
}

/// The node of a pair is its first machine (`Composite::new(node, sdo_client)`).
impl<A: NodeHost, B> NodeHost for Composite<A, B> {
    fn local_node(&mut self) -> &mut dyn LocalNode {
        self.a.local_node()
    }
}

impl<L, M: NodeHost> NodeHost for Station<L, M> {
    fn local_node(&mut self) -> &mut dyn LocalNode {
        self.machine.local_node()
    }
}

impl<D> Handle<D>
where
    D: crate::Device + NodeHost + Send + 'static,
    D::Event: Clone + Send + 'static,
{
    /// Reads an entry of the local dictionary.
    pub async fn read(&self, index: u16, sub: u8) -> Result<Vec<u8>, RuntimeError> {
        self.try_call(move |d, _| Ok(d.local_node().read_entry(index, sub)?))
            .await
    }
    /// Writes an entry of the local dictionary (the stack reacts: heartbeat period, …).
    pub async fn write(&self, index: u16, sub: u8, data: Vec<u8>) -> Result<(), RuntimeError> {
        self.try_call(move |d, now| Ok(d.local_node().write_entry(now, index, sub, &data)?))
            .await
    }
    /// Sends an NMT command.
    pub async fn nmt(&self, cmd: NmtCommand, target: NmtTarget) -> Result<(), RuntimeError> {
        self.try_call(move |d, now| Ok(d.local_node().send_nmt(now, cmd, target)?))
            .await
    }
    /// The local node's NMT state.
    pub async fn nmt_state(&self) -> Result<NmtState, RuntimeError> {
        Ok(self.call(|d, _| d.local_node().state()).await?)
    }
    /// Boots the local node (sends its boot-up message).
    pub async fn boot(&self) -> Result<(), RuntimeError> {
        Ok(self.call(|d, now| d.local_node().power_on(now)).await?)
    }
}
