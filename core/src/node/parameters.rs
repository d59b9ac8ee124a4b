//! 0x1010 store parameters and 0x1011 restore default parameters on a node, and the stored
//! values at power-on and at each reset (the model: [`crate::od::parameters`]).

use super::{NodeCore, NodeEventKind, StorageAction, Writer};
use crate::frame::instant::Instant;
use crate::frame::storage::Storage;
use crate::od::abort::AbortCode;
use crate::od::parameters::{capability, LoadReport, ParameterGroup, StorageError, LOAD, SAVE};
use crate::od::{comm, ObjectDictionary};
use crate::profile::IdProfile;
use core::ops::RangeInclusive;

impl<
        D: ObjectDictionary,
        P: IdProfile,
        const GUARDED: usize,
        const TPDOS: usize,
        const RPDOS: usize,
        S: Storage,
    > NodeCore<D, P, GUARDED, TPDOS, RPDOS, S>
{
    /// Writes the stored values of `range` over the power-on values just restored (power-on,
    /// reset-node, reset-communication). A failure leaves the power-on values and says so.
    pub(super) fn load_stored(&mut self, now: Instant, range: RangeInclusive<u16>) {
        match self.od.load_parameters(range) {
            Ok(r) if r == LoadReport::default() => {}
            Ok(r) => self.event(now, NodeEventKind::ParametersLoaded(r)),
            Err(error) => self.event(
                now,
                NodeEventKind::StorageFailed {
                    action: StorageAction::Load,
                    error,
                },
            ),
        }
    }

    /// A write of `data` to 0x1010/0x1011 sub `sub` ≥ 1 that passed the type checks: the
    /// signature selects the command, the sub-index the group. Nothing is written to the
    /// dictionary: the entry keeps reading as the capability bits.
    pub(super) fn storage_write(
        &mut self,
        now: Instant,
        index: u16,
        sub: u8,
        data: &[u8],
        by: Writer,
    ) -> Result<(), AbortCode> {
        let signature = match <[u8; 4]>::try_from(data) {
            Ok(b) => u32::from_le_bytes(b),
            Err(_) => return Err(AbortCode::TYPE_MISMATCH),
        };
        let store = index == comm::STORE_PARAMETERS;
        let expected = if store { SAVE } else { LOAD };
        // CiA 301: a wrong signature is refused with 0x08000020 and nothing happens; a
        // sub-index this stack gives no group to cannot be stored either.
        let group = ParameterGroup::from_sub(sub)
            .filter(|_| signature == expected)
            .ok_or(AbortCode::CANNOT_STORE)?;
        self.storage_command(now, store, group, by)
            .map_err(StorageError::abort_code)
    }

    /// Stores (`store`) or restores a group and reports it.
    pub(super) fn storage_command(
        &mut self,
        now: Instant,
        store: bool,
        group: ParameterGroup,
        by: Writer,
    ) -> Result<(), StorageError> {
        let (r, action, done) = if store {
            (
                self.od.store_parameters(group),
                StorageAction::Store(group),
                NodeEventKind::ParametersStored { group, by },
            )
        } else {
            (
                self.od.restore_defaults(group),
                StorageAction::Restore(group),
                NodeEventKind::DefaultsRestored { group, by },
            )
        };
        match r {
            Ok(()) => self.event(now, done),
            Err(error) => self.event(now, NodeEventKind::StorageFailed { action, error }),
        }
        r
    }

    /// Sets what 0x1010/0x1011 sub 1–4 read: the medium's capability bits for the groups this
    /// stack defines, zero for any other sub-index (boot and every reset).
    pub(super) fn publish_storage_capabilities(&mut self) {
        let caps = self.od.storage_capabilities();
        for (index, mask) in [
            (
                comm::STORE_PARAMETERS,
                capability::ON_COMMAND | capability::AUTONOMOUS,
            ),
            // Restoring has only the one bit.
            (comm::RESTORE_DEFAULTS, capability::ON_COMMAND),
        ] {
            let highest = self.od.get_u32(index, 0).unwrap_or(0).min(0xFE) as u8;
            for sub in 1..=highest {
                let v = match ParameterGroup::from_sub(sub) {
                    Some(_) => caps & mask,
                    None => 0,
                };
                let _ = self.od.store(index, sub, &v.to_le_bytes());
            }
        }
    }
}
