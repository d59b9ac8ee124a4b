//! Asynchronous SDO transfers through a [`Handle`]: `handle.sdo_read(node, …).await`.
//!
//! The device holds an [`SdoClient`] (usually `Composite::new(node, client)` in a station). A
//! read or write starts the transfer on the device (under the runtime's lock) and waits for the
//! client's [`SdoEvent`] that names its [`RequestId`] (through [`Handle::request`], so the
//! result cannot be missed); many
//! transfers can be in flight at once, to different nodes. A refusal to start, a failed
//! transfer and a stopped runtime come back as one error (the host's [`SdoHost::Error`],
//! [`RuntimeError`] for a plain client), so each call ends in `?`.

use super::handle::{Handle, RuntimeClosed, RuntimeError};
use crate::cia301::sdo::{RequestId, SdoClient, SdoError, SdoEvent, SdoOptions, TransferBuffer};
use crate::frame::instant::Instant;
use crate::frame::storage::Storage;
use crate::machine::{Composite, CompositeEvent, Station, StationEvent};
use crate::NodeId;

/// One transfer to start: a read when `data` is `None`, else a write of `data`.
#[derive(Clone, Copy, Debug)]
pub struct SdoStart<'a> {
    /// The server's node.
    pub node: NodeId,
    /// Object index.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// What to write, or `None` to read.
    pub data: Option<&'a [u8]>,
    /// TransferMode, timeout, block size.
    pub opts: SdoOptions,
}

/// A device (or machine) with an SDO client in it.
pub trait SdoHost {
    /// The one error of a transfer through a [`Handle`]: the host's refusal to start, the
    /// transfer's [`SdoError`] and a stopped runtime all convert into it.
    type Error: From<SdoError> + From<RuntimeClosed> + Send + 'static;
    /// Starts the transfer `r`.
    fn sdo_start(&mut self, now: Instant, r: SdoStart<'_>) -> Result<RequestId, Self::Error>;
}

impl<B: TransferBuffer, const N: usize, S: Storage> SdoHost for SdoClient<B, N, S> {
    type Error = RuntimeError;
    fn sdo_start(&mut self, now: Instant, r: SdoStart<'_>) -> Result<RequestId, RuntimeError> {
        let started = match r.data {
            None => self.upload(now, r.node, r.index, r.sub, r.opts),
            Some(d) => self.download(now, r.node, r.index, r.sub, d, r.opts),
        };
        Ok(started?)
    }
}

/// The client of a pair is its second machine (`Composite::new(node, client)`).
impl<A, C: SdoHost> SdoHost for Composite<A, C> {
    type Error = C::Error;
    fn sdo_start(&mut self, now: Instant, r: SdoStart<'_>) -> Result<RequestId, C::Error> {
        self.b.sdo_start(now, r)
    }
}

impl<L, M: SdoHost> SdoHost for Station<L, M> {
    type Error = M::Error;
    fn sdo_start(&mut self, now: Instant, r: SdoStart<'_>) -> Result<RequestId, M::Error> {
        self.machine.sdo_start(now, r)
    }
}

/// How to find the client's events among a device's events.
pub trait SdoEvents {
    /// The transfer result in `e`, if `e` is one: its request and the data read (empty for a
    /// write) or the error.
    fn sdo_result(&self) -> Option<(RequestId, Result<Vec<u8>, SdoError>)>;
}

impl<B: TransferBuffer> SdoEvents for SdoEvent<B> {
    fn sdo_result(&self) -> Option<(RequestId, Result<Vec<u8>, SdoError>)> {
        Some((
            self.request,
            self.result
                .as_ref()
                .map(|b| b.as_slice().to_vec())
                .map_err(|e| *e),
        ))
    }
}

impl<A, B: SdoEvents> SdoEvents for CompositeEvent<A, B> {
    fn sdo_result(&self) -> Option<(RequestId, Result<Vec<u8>, SdoError>)> {
        match self {
            CompositeEvent::B(e) => e.sdo_result(),
            CompositeEvent::A(_) => None,
        }
    }
}

impl<L, M: SdoEvents> SdoEvents for StationEvent<L, M> {
    fn sdo_result(&self) -> Option<(RequestId, Result<Vec<u8>, SdoError>)> {
        match self {
            StationEvent::Machine(m) => m.sdo_result(),
            StationEvent::Link(_) => None,
        }
    }
}

impl<D> Handle<D>
where
    D: crate::Device + SdoHost + Send + 'static,
    D::Event: SdoEvents + Clone + Send + 'static,
{
    /// Reads (index, sub) of `node` over SDO.
    pub async fn sdo_read(
        &self,
        node: NodeId,
        index: u16,
        sub: u8,
        opts: SdoOptions,
    ) -> Result<Vec<u8>, D::Error> {
        let r = SdoStart {
            node,
            index,
            sub,
            data: None,
            opts,
        };
        self.request(move |d, now| d.sdo_start(now, r), result_of)
            .await
    }

    /// Writes `data` to (index, sub) of `node` over SDO.
    pub async fn sdo_write(
        &self,
        node: NodeId,
        index: u16,
        sub: u8,
        data: Vec<u8>,
        opts: SdoOptions,
    ) -> Result<(), D::Error> {
        self.request(
            move |d, now| {
                let r = SdoStart {
                    node,
                    index,
                    sub,
                    data: Some(&data),
                    opts,
                };
                d.sdo_start(now, r)
            },
            result_of,
        )
        .await
        .map(|_| ())
    }
}

/// The outcome of transfer `id` if `e` is its completion, in the host's error.
fn result_of<V: SdoEvents, E: From<SdoError>>(id: &RequestId, e: &V) -> Option<Result<Vec<u8>, E>> {
    match e.sdo_result() {
        Some((rid, r)) if rid == *id => Some(r.map_err(E::from)),
        _ => None,
    }
}
