//! The bounded node-ID ↔ board-address table of a [`super::RailwayProfile`].

use super::address::DeviceAddress;
use crate::frame::cob_id::NodeId;
use core::fmt;

/// Why an entry could not be added.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TableError {
    /// A node's address is its board address: the I/O port must be 0.
    NotABoard {
        /// The node.
        node: NodeId,
        /// The address given.
        address: DeviceAddress,
    },
    /// Another node has this address already.
    AddressTaken {
        /// The address.
        address: DeviceAddress,
        /// The node holding it.
        by: NodeId,
    },
}

impl fmt::Display for TableError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TableError::NotABoard { node, address } => write!(
                f,
                "{node}: address {address} names I/O port {}; a node's address is its board (port 0)",
                address.port()
            ),
            TableError::AddressTaken { address, by } => {
                write!(f, "address {address} is already {by}'s: one board, one node-ID")
            }
        }
    }
}

impl core::error::Error for TableError {}

const NONE: u32 = u32::MAX;

/// Node-ID → address and address → node-ID, both bounded (every node-ID 1–127 can have one
/// address: 1 KiB, no heap). Lookups by address are a binary search over 127 entries at most.
#[derive(Clone, PartialEq, Eq)]
pub(super) struct Table {
    /// Raw address per node-ID (index 0 unused), `NONE` when absent.
    by_node: [u32; 128],
    /// `address << 7 | node-ID`, sorted: sorted by address, since addresses are unique.
    by_address: heapless::Vec<u32, 127>,
}

impl Table {
    pub(super) const fn new() -> Self {
        Table {
            by_node: [NONE; 128],
            by_address: heapless::Vec::new(),
        }
    }

    pub(super) fn add(&mut self, node: NodeId, address: DeviceAddress) -> Result<(), TableError> {
        if address.port() != 0 {
            return Err(TableError::NotABoard { node, address });
        }
        match self.node_at(address) {
            Some(by) if by == node => return Ok(()),
            Some(by) => return Err(TableError::AddressTaken { address, by }),
            None => {}
        }
        self.remove(node);
        let entry = address.raw() << 7 | node.raw() as u32;
        // 127 node-IDs, 127 slots, and the node's old entry is gone: there is room.
        if self.by_address.push(entry).is_ok() {
            // Into its place from the end, one swap at a time: what `insert` does, without
            // the general overlapping copy (1.5 KB of code in an image that needs it nowhere
            // else).
            let v = &mut self.by_address[..];
            let mut i = v.len() - 1;
            while i > 0 && v[i - 1] > v[i] {
                v.swap(i - 1, i);
                i -= 1;
            }
            self.by_node[node.raw() as usize] = address.raw();
        }
        Ok(())
    }

    pub(super) fn remove(&mut self, node: NodeId) -> Option<DeviceAddress> {
        let raw = core::mem::replace(&mut self.by_node[node.raw() as usize], NONE);
        if raw == NONE {
            return None;
        }
        let entry = raw << 7 | node.raw() as u32;
        if let Ok(i) = self.by_address.binary_search(&entry) {
            // To the end, one swap at a time, and off it (what `remove` does; see `add`).
            let v = &mut self.by_address[..];
            for j in i + 1..v.len() {
                v.swap(j - 1, j);
            }
            self.by_address.pop();
        }
        DeviceAddress::from_raw(raw).ok()
    }

    #[inline]
    pub(super) fn address(&self, node: NodeId) -> Option<DeviceAddress> {
        match self.by_node[node.raw() as usize] {
            NONE => None,
            raw => DeviceAddress::from_raw(raw).ok(),
        }
    }

    /// The node whose board address is exactly `address`.
    #[inline]
    pub(super) fn node_at(&self, address: DeviceAddress) -> Option<NodeId> {
        let i = self
            .by_address
            .binary_search_by_key(&address.raw(), |e| e >> 7)
            .ok()?;
        NodeId::new((self.by_address[i] & 0x7F) as u8)
    }

    pub(super) fn len(&self) -> usize {
        self.by_address.len()
    }

    pub(super) fn iter(&self) -> impl Iterator<Item = (NodeId, DeviceAddress)> + '_ {
        (1..=127u8).filter_map(|n| {
            let node = NodeId::new(n)?;
            Some((node, self.address(node)?))
        })
    }
}

impl fmt::Debug for Table {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_map().entries(self.iter()).finish()
    }
}
