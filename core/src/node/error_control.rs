//! What the bus sees of the node's error control: the heartbeat at once on a change, and the
//! EMCY that tells every master a monitored producer or the guarding master went silent.

use super::NodeCore;
use crate::cia301::emcy;
use crate::frame::cob_id::NodeId;
use crate::frame::instant::Instant;
use crate::frame::storage::Storage;
use crate::frame::Frame;
use crate::od::ObjectDictionary;
use crate::profile::IdProfile;

impl<
        D: ObjectDictionary,
        P: IdProfile,
        const GUARDED: usize,
        const TPDOS: usize,
        const RPDOS: usize,
        S: Storage,
    > NodeCore<D, P, GUARDED, TPDOS, RPDOS, S>
{
    /// Sends the heartbeat now (if produced and the state allows error control) and restarts
    /// the grid from now: after an NMT state change and a new producer time, so that a master
    /// sees the change at once rather than up to a period later.
    pub(super) fn heartbeat_now(&mut self, now: Instant) {
        if self.hb.beat_now(now) && self.state.services().error_control {
            let f = Frame::from_array(self.profile.heartbeat(self.id()), [self.state.code()]);
            let _ = self.send(f);
        }
    }

    /// Life guarding or a consumed heartbeat changed: CiA 301 gives both one error, 0x8130
    /// with the communication bit of 0x1001, recorded in 0x1003. It is raised (one EMCY) when
    /// the first of them is lost, and cleared when none is lost any more (the error-reset EMCY
    /// when no other error remains). `lost` names the silent producer, sent in the first
    /// manufacturer-specific byte (zero for life guarding). Lost heartbeats count only where
    /// [`NodeConfig::heartbeat_loss_emcy`](super::NodeConfig::heartbeat_loss_emcy) says so.
    pub(super) fn monitoring_changed(&mut self, now: Instant, lost: Option<NodeId>) {
        let heartbeat_lost = self.cfg.heartbeat_loss_emcy && self.consumer.any_lost();
        if self.guard.is_lost() || heartbeat_lost {
            let node = lost.map_or(0, NodeId::raw);
            self.emcy_raise(
                now,
                emcy::code::LIFE_GUARD,
                emcy::register::COMMUNICATION,
                [node, 0, 0, 0, 0],
            );
        } else {
            self.emcy_clear(now, emcy::code::LIFE_GUARD);
        }
    }
}
