//! One PDO of a remote node: its configuration over SDO, its values on the bus.

use super::table::{AnyFrame, Learned, PdoTable, Slot};
use super::{label, PdoMap, PdoValues, PdoVariable};
use crate::cia301::pdo::params::{self, sub};
use crate::cia301::pdo::{Dir, MapEntry, MAX_ENTRIES};
use crate::cia301::sdo::SdoErrorKind;
use crate::cia302::pdo_config::{AccessError, PdoConfig, PdoConfigurator, SdoAccess};
use crate::frame::cob_id::{CobId, NodeId};
use crate::net::error::{Awaited, NetError};
use crate::net::events::NetEvent;
use crate::net::remote::RemoteNode;
use crate::net::value::AnyValue;
use crate::od::OdValue;
use std::sync::Arc;
use std::time::Duration;

/// The "save" signature written to 0x1010 (ASCII `save`, little-endian).
const SAVE: u32 = 0x6576_6173;

/// One PDO of a [`RemoteNode`]: `node.tpdo(1)` (a PDO the node transmits) or `node.rpdo(1)`
/// (one it receives). Cheap to clone; nothing is sent until a call.
#[derive(Clone)]
pub struct RemotePdo {
    node: RemoteNode,
    dir: Dir,
    pdo: u16,
}

impl RemoteNode {
    /// The node's TPDO `pdo` (1–512): python's `node.tpdo[pdo]`.
    #[must_use]
    pub fn tpdo(&self, pdo: u16) -> RemotePdo {
        RemotePdo {
            node: self.clone(),
            dir: Dir::Transmit,
            pdo,
        }
    }

    /// The node's RPDO `pdo` (1–512): python's `node.rpdo[pdo]`.
    #[must_use]
    pub fn rpdo(&self, pdo: u16) -> RemotePdo {
        RemotePdo {
            node: self.clone(),
            dir: Dir::Receive,
            pdo,
        }
    }

    /// Waits at most `timeout` for the node's TPDO `pdo` and returns its values (the
    /// network decodes it once it knows its mapping: [`RemotePdo::read`], [`RemotePdo::save`]
    /// or [`RemotePdo::learn`]).
    pub async fn wait_for_pdo(&self, pdo: u16, timeout: Duration) -> Result<PdoValues, NetError> {
        let id = self.id()?;
        self.watch(
            Awaited::Pdo(pdo),
            timeout,
            |_| None,
            move |e| match e {
                NetEvent::Pdo {
                    node,
                    pdo: n,
                    values,
                    ..
                } if *node == id && *n == pdo => Some(values.clone()),
                _ => None,
            },
        )
        .await
    }

    /// Reads every TPDO (`Dir::Transmit`) or RPDO of the node (python `node.tpdo.read()`):
    /// those the node's description has, or without one PDO 1, 2, … up to the first the node
    /// does not have. Each is learned as [`RemotePdo::read`] learns it.
    pub async fn read_pdos(&self, dir: Dir) -> Result<Vec<PdoMap>, NetError> {
        let comm = match dir {
            Dir::Transmit => params::TPDO_COMM,
            Dir::Receive => params::RPDO_COMM,
        };
        let mut maps = Vec::new();
        for n in 1..=params::MAX_PDOS {
            let pdo = RemotePdo {
                node: self.clone(),
                dir,
                pdo: n,
            };
            if let Some(d) = self.description() {
                if d.object_at(comm + (n - 1)).is_some() {
                    maps.push(pdo.read().await?);
                }
                continue;
            }
            match pdo.read().await {
                Ok(m) => maps.push(m),
                // The first PDO the node does not have ends the list.
                Err(NetError::Sdo(e))
                    if matches!(e.kind, SdoErrorKind::Server(_)) && e.index == comm + (n - 1) =>
                {
                    break
                }
                Err(e) => return Err(e),
            }
        }
        Ok(maps)
    }

    /// Waits at most `timeout` for an emergency message from the node and returns it (one
    /// that arrived before the call does not count: watch [`Network::events`] for every one).
    ///
    /// [`Network::events`]: crate::net::Network::events
    pub async fn wait_for_emcy(
        &self,
        timeout: Duration,
    ) -> Result<crate::cia301::emcy::EmcyMessage, NetError> {
        let id = self.id()?;
        self.watch(
            Awaited::Emcy,
            timeout,
            |_| None,
            move |e| match e.emcy() {
                Some((node, m)) if node == id => Some(m),
                _ => None,
            },
        )
        .await
    }

    /// Stores the node's parameters (0x1010 sub 1, "save"), so that what was configured
    /// survives a power cycle: python `node.store()`.
    pub async fn store_parameters(&self) -> Result<(), NetError> {
        self.sdo()
            .write(crate::od::comm::STORE_PARAMETERS, 1, SAVE)
            .await
    }
}

impl RemotePdo {
    fn id(&self) -> Result<NodeId, NetError> {
        let node = self.node.id()?;
        if !(1..=params::MAX_PDOS).contains(&self.pdo) {
            return Err(NetError::NoSuchPdo {
                node,
                pdo: self.pdo,
            });
        }
        Ok(node)
    }

    fn indices(&self) -> (u16, u16) {
        let (c, m) = match self.dir {
            Dir::Transmit => (params::TPDO_COMM, params::TPDO_MAPPING),
            Dir::Receive => (params::RPDO_COMM, params::RPDO_MAPPING),
        };
        (c + (self.pdo - 1), m + (self.pdo - 1))
    }

    /// An empty, disabled map of this PDO (transmission type 255, no optional parameters),
    /// to fill in and [`learn`](RemotePdo::learn) or [`save`](RemotePdo::save) without
    /// reading the node first.
    pub fn blank(&self) -> Result<PdoMap, NetError> {
        let node = self.id()?;
        Ok(PdoMap::new(
            node,
            self.dir,
            self.pdo,
            self.node.description_arc(),
            self.node.network().fd_client().is_some(),
        ))
    }

    /// Reads the PDO's configuration over SDO (python `read()`): COB-ID, validity,
    /// transmission type, inhibit time, event timer, SYNC start value (the optional ones
    /// `None` where the node has no such entry) and the mapping, named from the node's
    /// description. The network learns the mapping: from now on this PDO is decoded (a TPDO)
    /// or can be sent (an RPDO).
    pub async fn read(&self) -> Result<PdoMap, NetError> {
        let mut map = self.blank()?;
        let (comm, mapping) = self.indices();
        let sdo = self.node.sdo();
        let transmit = self.dir == Dir::Transmit;
        map.cob_id = CobId(sdo.read::<u32>(comm, sub::COB_ID).await?);
        map.enabled = map.cob_id.is_valid();
        map.transmission_type = sdo.read::<u8>(comm, sub::TRANSMISSION_TYPE).await?;
        if transmit {
            map.inhibit_100us = self.optional(comm, sub::INHIBIT_TIME).await?;
            map.sync_start = self.optional(comm, sub::SYNC_START).await?;
        }
        map.event_timer_ms = self.optional(comm, sub::EVENT_TIMER).await?;
        let n = sdo.read::<u8>(mapping, 0).await?.min(MAX_ENTRIES);
        for k in 1..=n {
            let e = MapEntry::from_raw(sdo.read::<u32>(mapping, k).await?);
            map.entries.push(PdoVariable::new(
                e.index,
                e.sub,
                e.bits,
                map.desc.as_deref(),
            ));
        }
        self.learn(&map).await?;
        Ok(map)
    }

    /// An entry the node may not have: `None` if it aborts the read.
    async fn optional<T: OdValue>(&self, index: u16, sub: u8) -> Result<Option<T>, NetError> {
        match self.node.sdo().read::<T>(index, sub).await {
            Ok(v) => Ok(Some(v)),
            Err(NetError::Sdo(e)) if matches!(e.kind, SdoErrorKind::Server(_)) => Ok(None),
            Err(e) => Err(e),
        }
    }

    /// Writes `map` to the node over SDO (python `save()`), in the order devices need:
    /// disable the PDO (COB-ID bit 31), write the transmission type and the optional
    /// parameters `map` has, the mapping (count 0, the entries, the count), then the COB-ID
    /// with bit 31 as [`PdoMap::enabled`] says. A node that refuses to disable a PDO is
    /// accepted if the PDO already is what `map` asks for. The network learns the mapping.
    /// Nothing is stored: see [`RemotePdo::save_and_store`].
    pub async fn save(&self, map: &PdoMap) -> Result<(), NetError> {
        let node = self.id()?;
        if (map.node, map.dir, map.pdo) != (node, self.dir, self.pdo) {
            return Err(NetError::Argument(format!(
                "this is node {}'s {}, the map is node {}'s {}: save it on its own PDO",
                node.raw(),
                label(self.dir, self.pdo),
                map.node.raw(),
                map.label()
            )));
        }
        let cfg = self.config(map)?;
        let mut job = PdoConfigurator::new(node, self.dir, self.pdo, cfg);
        let sdo = self.node.sdo();
        while let Some(a) = job.next() {
            let r = match a {
                SdoAccess::Read { index, sub } => sdo.read_bytes(index, sub).await,
                SdoAccess::Write { index, sub, .. } => sdo
                    .write_bytes(index, sub, a.data())
                    .await
                    .map(|()| Vec::new()),
            };
            match r {
                Ok(d) => job.handle(Ok(&d)),
                Err(NetError::Sdo(e)) => job.handle(Err(match e.kind {
                    SdoErrorKind::Server(code) => AccessError::Aborted(code),
                    SdoErrorKind::Client(code) => AccessError::NoAnswer(Some(code)),
                    _ => AccessError::NoAnswer(None),
                })),
                Err(other) => return Err(other),
            }
        }
        match job.result() {
            Some(Ok(_)) => self.learn(map).await,
            Some(Err(e)) => Err(NetError::PdoConfig(e)),
            None => Err(NetError::Closed),
        }
    }

    /// Reads the PDO's configuration ([`RemotePdo::read`]), lets `change` edit it and saves
    /// it ([`RemotePdo::save`]): the common "set the event timer of TPDO 1" in one call.
    /// Returns the map as saved. Nothing is written if the read fails; a save that fails
    /// says how far it got ([`NetError::PdoConfig`]).
    pub async fn edit(&self, change: impl FnOnce(&mut PdoMap)) -> Result<PdoMap, NetError> {
        let mut map = self.read().await?;
        change(&mut map);
        self.save(&map).await?;
        Ok(map)
    }

    /// [`RemotePdo::save`], then [`RemoteNode::store_parameters`]: the configuration
    /// survives the node's power cycle.
    pub async fn save_and_store(&self, map: &PdoMap) -> Result<(), NetError> {
        self.save(map).await?;
        self.node.store_parameters().await
    }

    fn config(&self, map: &PdoMap) -> Result<PdoConfig, NetError> {
        usable_cob_id(map)?;
        let entries: Vec<MapEntry> = map.entries.iter().map(PdoVariable::entry).collect();
        if self.node.network().fd_client().is_some() {
            if map.bits() > crate::cia301::pdo::FD_MAX_BITS {
                return Err(map.error("the mapping is longer than 512 bits: map fewer entries"));
            }
        } else if map.bits() > crate::cia301::pdo::MAX_BITS {
            return Err(map.error(
                "the mapping is longer than 64 bits: map fewer entries (a CANopen FD network carries 512)",
            ));
        }
        let mut cfg = PdoConfig::new(map.cob_id.with_valid(map.enabled), map.transmission_type)
            .mapping(&entries)
            .ok_or_else(|| map.error("the mapping has more than 64 entries"))?;
        cfg.inhibit_100us = map.inhibit_100us;
        cfg.event_timer_ms = map.event_timer_ms;
        cfg.sync_start = map.sync_start;
        Ok(cfg)
    }

    /// Tells the network the PDO is configured as `map` says, without asking the node: a TPDO
    /// is decoded from now on, an RPDO can be sent. A disabled map makes the network forget
    /// the PDO.
    pub async fn learn(&self, map: &PdoMap) -> Result<(), NetError> {
        let node = self.id()?;
        usable_cob_id(map)?;
        let transmit = self.dir == Dir::Transmit;
        let pdo = self.pdo;
        let learned = match (map.enabled, map.cob_id.can_id()) {
            (true, Some(id)) => Some(Learned {
                node,
                pdo,
                id,
                slots: map.entries.iter().map(slot).collect::<Vec<_>>().into(),
            }),
            _ => None,
        };
        let full = map.error(&format!(
            "the network already knows {} PDOs in this direction: forget some (learn a disabled map)",
            super::MAX_LEARNED
        ));
        self.node
            .network()
            .shared
            .handle
            .try_call(move |d, _| {
                d.pdos
                    .learn(transmit, node, pdo, learned)
                    .map_err(|()| full)
            })
            .await
    }

    /// Sends the node's RPDO with `values`, one per mapped entry that is not a dummy, in
    /// mapping order, each encoded as its data type (from the description) and width say:
    /// python `rpdo[n].transmit()`. A mapping the network does not know yet (from
    /// [`RemotePdo::read`], [`RemotePdo::save`] or [`RemotePdo::learn`]) is read from the node
    /// first, once; a value that does not fit its entry is
    /// [`NetError::BadValue`]. A network that may not send refuses: listen-only
    /// ([`NetError::ListenOnly`]), or a standby redundant master ([`NetError::Standby`]: the
    /// active master's application drives the outputs, two would fight over them).
    pub async fn send(&self, values: &[AnyValue]) -> Result<(), NetError> {
        let node = self.id()?;
        let what = label(self.dir, self.pdo);
        if self.dir != Dir::Receive {
            return Err(not_ours(node, what));
        }
        let values = values.to_vec();
        self.send_with(node, what, move |t, node, pdo, fd| {
            t.encode(node, pdo, &values, fd)
        })
        .await
    }

    /// Sends the node's RPDO with the entries named in `values` set (names from the node's
    /// description, without regard to case) and every other one as last sent (zero at
    /// first): python `rpdo[n]["Output 1"].raw = 5; rpdo[n].transmit()`. A name the mapping
    /// does not carry is [`NetError::BadValue`], listing the names it does.
    pub async fn send_named(&self, values: &[(&str, AnyValue)]) -> Result<(), NetError> {
        let node = self.id()?;
        let what = label(self.dir, self.pdo);
        if self.dir != Dir::Receive {
            return Err(not_ours(node, what));
        }
        let named: Vec<(String, AnyValue)> = values
            .iter()
            .map(|(n, v)| ((*n).to_owned(), v.clone()))
            .collect();
        self.send_with(node, what, move |t, node, pdo, fd| {
            t.encode_named(node, pdo, &named, fd)
        })
        .await
    }

    /// Sends the frame `make` encodes from the learned mapping; a mapping not known yet is
    /// read from the node first (once: a disabled PDO stays unknown, and says so).
    async fn send_with(
        &self,
        node: NodeId,
        what: String,
        make: impl Fn(&mut PdoTable, NodeId, u16, bool) -> Option<Result<AnyFrame, String>>
            + Clone
            + Send
            + 'static,
    ) -> Result<(), NetError> {
        let net = self.node.network();
        if net.is_listen_only() {
            return Err(NetError::ListenOnly { node: Some(node) });
        }
        if self.try_send(node, what.clone(), make.clone()).await? {
            return Ok(());
        }
        self.read().await?;
        if self.try_send(node, what.clone(), make).await? {
            return Ok(());
        }
        Err(NetError::Pdo {
            node,
            pdo: what,
            why: "it is disabled on the node: enable it (save a map with enabled set) first".into(),
        })
    }

    /// Sends the frame `make` encodes; false (nothing sent) if the mapping is not known.
    async fn try_send(
        &self,
        node: NodeId,
        what: String,
        make: impl FnOnce(&mut PdoTable, NodeId, u16, bool) -> Option<Result<AnyFrame, String>>
            + Send
            + 'static,
    ) -> Result<bool, NetError> {
        let pdo = self.pdo;
        self.node
            .network()
            .shared
            .handle
            .try_call(move |d, now| {
                let fd = d.usdo.is_some();
                match make(&mut d.pdos, node, pdo, fd) {
                    None => Ok(false),
                    Some(Err(why)) => Err(NetError::BadValue {
                        node,
                        object: what,
                        why,
                    }),
                    Some(Ok(AnyFrame::Classic(f))) => d.send_own(now, f).map(|()| true),
                    Some(Ok(AnyFrame::Fd(f))) => d.send_own_fd(now, &f).map(|()| true),
                }
            })
            .await
            .map_err(|e| match e {
                NetError::Standby { node: None } => NetError::Standby { node: Some(node) },
                NetError::ListenOnly { node: None } => NetError::ListenOnly { node: Some(node) },
                e => e,
            })
    }

    /// Waits at most `timeout` for this TPDO and returns its values
    /// ([`RemoteNode::wait_for_pdo`]).
    pub async fn wait(&self, timeout: Duration) -> Result<PdoValues, NetError> {
        self.id()?;
        self.node.wait_for_pdo(self.pdo, timeout).await
    }
}

/// An enabled PDO must be on an identifier a PDO may use (CiA 301 restricts NMT, SYNC, EMCY,
/// TIME, SDO, heartbeat…): a blank map enabled without a COB-ID would otherwise be on 0x000.
fn usable_cob_id(map: &PdoMap) -> Result<(), NetError> {
    let cob = map.cob_id;
    let raw = (cob.0 & 0x7FF) as u16;
    if map.enabled && !cob.is_extended() && crate::cia301::pdo::restricted_id(raw) {
        return Err(map.error(&format!(
            "COB-ID {raw:#05x} is reserved for other services (NMT, SYNC, EMCY, SDO, heartbeat…): set map.cob_id to a PDO identifier, such as 0x180 + node-ID for TPDO 1"
        )));
    }
    Ok(())
}

fn not_ours(node: NodeId, pdo: String) -> NetError {
    NetError::Pdo {
        node,
        pdo,
        why: "the node transmits this PDO; the network sends only RPDOs: use node.rpdo(n)".into(),
    }
}

fn slot(v: &PdoVariable) -> Slot {
    Slot {
        index: v.index,
        sub: v.sub,
        bits: v.bits,
        data_type: v.data_type,
        name: v.name.as_deref().map(Arc::from),
        dummy: v.is_dummy(),
    }
}
