//! A slave's configuration from its DCF (CiA 302-3 configuration manager, `std`): every
//! `ParameterValue` that differs from the device's default becomes an SDO write, in an order
//! real devices accept.
//!
//! # The order
//!
//! Objects are written in index order, except that each PDO is written as one block at the
//! place of its communication parameter (0x1400+n, 0x1800+n), its mapping (0x1600+n,
//! 0x1A00+n) inside that block. Devices refuse a new mapping, and often a new COB-ID or
//! transmission type, while the PDO is valid, and refuse mapping entries while the mapping
//! count is not zero (CiA 301), so a PDO block is:
//!
//! 1. the COB-ID (sub 1) with bit 31 set: the PDO is invalid;
//! 2. the other communication parameters that differ, by sub-index;
//! 3. if the mapping differs: the mapping count (sub 0) set to 0, the mapping entries that
//!    differ, then the count the DCF gives;
//! 4. the COB-ID the DCF gives (valid or not), unless it is the invalid value already written.
//!
//! A mapping whose count the description marks read-only (a static mapping) is not written.
//! Entries the description marks read-only or constant are not written (a DCF often carries
//! their values, 0x1000 or 0x1018, for identification), nor store and restore (0x1010,
//! 0x1011: commands, given by [`SlaveConfig::with_store`] instead) or the configuration stamp
//! (0x1020: the master writes it after the configuration). The producer heartbeat time (0x1017),
//! when it differs, becomes [`SlaveConfig::heartbeat_producer_ms`]: the master writes it
//! after every other step, so the heartbeat starts from a configured slave.
//!
//! SRDO objects (CiA 304) change the order once more: writing an SRDO's parameters, mapping or
//! checksum (0x1301–0x1340, 0x1381–0x13C0, 0x13FF) clears the slave's "configuration valid"
//! mark (0x13FE), so when any of them is written, 0x13FE is written after everything else with
//! the value the DCF gives, even when that equals the default.
//!
//! A write the slave refuses is reported per object and the others are still written
//! ([`WriteAborts::Continue`]).

use super::config::{ConfigStep, SlaveConfig, WriteAborts};
use crate::cia304::srdo::config as srdo_config;
use crate::eds::{AccessType, Description, SubObject};
use crate::frame::cob_id::NodeId;
use crate::od::comm;
use alloc::collections::{BTreeMap, BTreeSet};
use alloc::vec::Vec;

/// Bit 31 of a PDO COB-ID: the PDO is invalid.
const INVALID: u32 = 1 << 31;

/// The communication parameter index of the PDO `index` belongs to (its own index for a
/// communication parameter, index − 0x200 for a mapping), or `None` outside the PDO areas.
fn pdo_comm(index: u16) -> Option<u16> {
    match index {
        0x1400..=0x15FF | 0x1800..=0x19FF => Some(index),
        0x1600..=0x17FF | 0x1A00..=0x1BFF => Some(index - 0x200),
        _ => None,
    }
}

/// The slave's configuration stamp (0x1020 verify configuration): written by the master after
/// the configuration, never from the DCF.
const VERIFY_CONFIGURATION: u16 = 0x1020;

fn writable(e: &SubObject) -> bool {
    matches!(
        e.access,
        AccessType::Rw | AccessType::Wo | AccessType::Rwr | AccessType::Rww
    ) && !is_command(e.index)
}

/// Objects a DCF may carry values of that are commands or the master's own bookkeeping, not
/// configuration: store and restore (a "save" written midway would store half a configuration,
/// a "load" would undo it) and the configuration stamp (written last, by the master).
fn is_command(index: u16) -> bool {
    matches!(
        index,
        comm::STORE_PARAMETERS | comm::RESTORE_DEFAULTS | VERIFY_CONFIGURATION
    )
}

fn write(index: u16, sub: u8, data: Vec<u8>) -> ConfigStep {
    ConfigStep::Write { index, sub, data }
}

/// The writes one PDO block needs; `changed` holds the block's differing entries by
/// (index, sub).
fn pdo_block(
    dcf: &Description,
    node: u8,
    comm_index: u16,
    changed: &BTreeMap<(u16, u8), Vec<u8>>,
    out: &mut Vec<ConfigStep>,
) {
    let map_index = comm_index + 0x200;
    let cob = dcf
        .entry_at(comm_index, 1)
        .filter(|e| writable(e))
        .and_then(|e| <[u8; 4]>::try_from(e.value_bytes(node).as_slice()).ok())
        .map(u32::from_le_bytes);
    if let Some(cob) = cob {
        out.push(write(comm_index, 1, (cob | INVALID).to_le_bytes().to_vec()));
    }
    for ((index, sub), data) in changed.range((comm_index, 2)..=(comm_index, u8::MAX)) {
        out.push(write(*index, *sub, data.clone()));
    }
    let count = dcf.entry_at(map_index, 0).filter(|e| writable(e));
    let entries = changed.range((map_index, 1)..=(map_index, u8::MAX));
    let remapped = changed.contains_key(&(map_index, 0)) || entries.clone().next().is_some();
    if let (Some(count), true) = (count, remapped) {
        // Zero in the count's own type (UNSIGNED8 in CiA 301; a file may say otherwise).
        let count = count.value_bytes(node);
        out.push(write(map_index, 0, alloc::vec![0; count.len()]));
        for ((index, sub), data) in entries {
            out.push(write(*index, *sub, data.clone()));
        }
        out.push(write(map_index, 0, count));
    }
    if let Some(cob) = cob.filter(|c| c & INVALID == 0) {
        out.push(write(comm_index, 1, cob.to_le_bytes().to_vec()));
    }
}

impl super::ConciseDcf {
    /// The concise DCF of a slave's DCF: the writes of [`SlaveConfig::with_dcf`] for node
    /// `node`, in their order, the producer heartbeat time (0x1017) last. Applied by the
    /// master (0x1F22 sub n), it writes what [`SlaveConfig::from_dcf`] writes.
    #[must_use]
    pub fn from_dcf(node: NodeId, dcf: &Description) -> super::ConciseDcf {
        let cfg = SlaveConfig::new(node).with_dcf(dcf);
        // A DCF gives writes only: never a PDO step.
        super::ConciseDcf::from_config(&cfg).unwrap_or_default()
    }
}

impl SlaveConfig {
    /// A slave configured from its DCF: [`SlaveConfig::new`] with the writes of
    /// [`SlaveConfig::with_dcf`].
    #[must_use]
    pub fn from_dcf(node: NodeId, dcf: &Description) -> SlaveConfig {
        SlaveConfig::new(node).with_dcf(dcf)
    }

    /// Adds a write for every `ParameterValue` of `dcf` that differs from the device's default
    /// (values with `$NODEID` taken for this slave's node-ID), in the order of the module docs
    /// (PDOs invalid while they change, the mapping count last, the COB-ID last). The
    /// producer heartbeat time (0x1017), if it differs, sets the producer time unless one is
    /// set already. A refused write is reported and the others are still written
    /// ([`WriteAborts::Continue`]).
    #[must_use]
    pub fn with_dcf(mut self, dcf: &Description) -> SlaveConfig {
        self.write_aborts = WriteAborts::Continue;
        let node = self.node.raw();
        let changed: BTreeMap<(u16, u8), Vec<u8>> = dcf
            .parameter_values()
            .filter(|e| writable(e))
            .filter_map(|e| {
                let v = e.value_bytes(node);
                (v != e.default_bytes(node)).then_some(((e.index, e.sub), v))
            })
            .collect();
        // Each unit once, in index order: a PDO at its communication parameter's index.
        let units: BTreeSet<u16> = changed
            .keys()
            .map(|(index, _)| pdo_comm(*index).unwrap_or(*index))
            .collect();
        let srdo = changed
            .keys()
            .any(|(index, _)| srdo_config::invalidates(*index));
        for unit in units {
            if unit == srdo_config::CONFIG_VALID {
                continue;
            }
            if pdo_comm(unit).is_some() {
                pdo_block(dcf, node, unit, &changed, &mut self.steps);
                continue;
            }
            for ((index, sub), data) in changed.range((unit, 0)..=(unit, u8::MAX)) {
                let heartbeat = (*index, *sub) == (comm::HEARTBEAT_PRODUCER, 0);
                if heartbeat && self.heartbeat_producer_ms.is_none() {
                    if let Ok(b) = <[u8; 2]>::try_from(data.as_slice()) {
                        self.heartbeat_producer_ms = Some(u16::from_le_bytes(b));
                        continue;
                    }
                }
                self.steps.push(write(*index, *sub, data.clone()));
            }
        }
        let valid = dcf
            .parameter_values()
            .find(|e| (e.index, e.sub) == (srdo_config::CONFIG_VALID, 0));
        if let Some(e) = valid {
            let data = e.value_bytes(node);
            if srdo || data != e.default_bytes(node) {
                self.steps.push(write(srdo_config::CONFIG_VALID, 0, data));
            }
        }
        self
    }
}

#[cfg(test)]
mod tests;
