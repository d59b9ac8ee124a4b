//! How protocol servers reach a node's dictionary.
//!
//! The SDO server and the PDO engine do not see the node that owns the dictionary: they see this
//! trait, which the node implements. A write through it is checked as a bus-side write (access
//! rights, value limits, the CiA 301 rules on PDO and SDO parameters) and the node reacts to it
//! as to any write (a new heartbeat time restarts the producer, and so on).

use super::abort::AbortCode;
use super::Entry;
use crate::frame::instant::Instant;

/// What protocol servers (SDO, PDO) use to reach a node's dictionary: bus-side access rights
/// and checks, and the stack's reactions to writes.
pub trait ObjectAccess {
    /// Finds an entry (no access check).
    fn entry(&self, index: u16, sub: u8) -> Result<Entry<'_>, AbortCode>;
    /// Reads as a remote client may.
    fn read(&self, index: u16, sub: u8) -> Result<&[u8], AbortCode>;
    /// Writes as a remote client may; the stack reacts as to any write.
    fn write(&mut self, now: Instant, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode>;
}
