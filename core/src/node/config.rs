//! The dictionary as configuration: reading the services' parameters, the rules of
//! communication objects, and the services' reactions to writes.

use super::{NodeCore, NodeEventKind, Writer};
use crate::cia301::heartbeat::ConsumerSetting;
use crate::cia301::nmt::NmtState;
use crate::cia301::pdo::{self};
use crate::cia301::sync::SyncConfig;
use crate::cia304::srdo::config as srdo_config;
use crate::frame::cob_id::CobId;
use crate::frame::instant::{Duration, Instant};
use crate::frame::storage::Storage;
use crate::od::abort::AbortCode;
use crate::od::ObjectAccess;
use crate::od::{check_value, comm, Access, Entry, ObjectDictionary};
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
    /// 0x1300 holds 1: the global fail-safe command is in use.
    pub(super) fn gfc_valid(&self) -> bool {
        self.od.get_u32(srdo_config::GFC_PARAMETER, 0) == Some(1)
    }

    pub(super) fn u16_of(&self, index: u16) -> u16 {
        self.od.get_u32(index, 0).unwrap_or(0) as u16
    }

    pub(super) fn sync_config(&self) -> SyncConfig {
        SyncConfig {
            cob_id: CobId(
                self.od
                    .get_u32(comm::SYNC_COB_ID, 0)
                    .unwrap_or(CobId::INVALID),
            ),
            period: Duration::from_micros(self.od.get_u32(comm::SYNC_PERIOD, 0).unwrap_or(0) as u64),
            window: Duration::from_micros(self.od.get_u32(comm::SYNC_WINDOW, 0).unwrap_or(0) as u64),
            overflow: self.od.get_u32(comm::SYNC_OVERFLOW, 0).unwrap_or(0) as u8,
        }
    }

    #[cfg(feature = "guarding")]
    pub(super) fn guard_params(&self) -> (Duration, u8) {
        (
            Duration::from_millis(self.u16_of(comm::GUARD_TIME) as u64),
            self.od.get_u32(comm::LIFE_TIME_FACTOR, 0).unwrap_or(0) as u8,
        )
    }

    pub(super) fn emcy_params(&self) -> (CobId, u16) {
        let default = crate::frame::cob_id::CobId::from_id(self.profile.emcy(self.id()));
        (
            CobId(self.od.get_u32(comm::EMCY_COB_ID, 0).unwrap_or(default.0)),
            self.u16_of(comm::EMCY_INHIBIT),
        )
    }

    /// Reads every service's parameters from the dictionary (boot, reset communication).
    pub(super) fn apply_config(&mut self, now: Instant) {
        self.hb.restart(
            now,
            Duration::from_millis(self.u16_of(comm::HEARTBEAT_PRODUCER) as u64),
        );
        self.consumer.clear();
        let subs = self
            .od
            .get_u32(comm::HEARTBEAT_CONSUMER, 0)
            .unwrap_or(0)
            .min(127) as u8;
        for sub in 1..=subs {
            if let Some(v) = self.od.get_u32(comm::HEARTBEAT_CONSUMER, sub) {
                // A dictionary holding two entries for one node keeps the first (CiA 301 would
                // have refused the second write).
                let _ = self.consumer.configure(sub, ConsumerSetting::from_u32(v));
            }
        }
        #[cfg(feature = "guarding")]
        {
            self.guard.reset();
            let (gt, lf) = self.guard_params();
            self.guard.configure(now, gt, lf);
        }
        self.sync.reset(now, self.sync_config());
        #[cfg(feature = "time")]
        self.time.configure(
            now,
            CobId(
                self.od
                    .get_u32(comm::TIME_COB_ID, 0)
                    .unwrap_or(CobId::INVALID),
            ),
        );
        let (cob, inhibit) = self.emcy_params();
        self.emcy.configure(cob, inhibit);
        self.history_slots = (1..=254u8)
            .take_while(|s| self.od.get(comm::ERROR_HISTORY, *s).is_ok())
            .count() as u8;
        let (engine, mut io) = self.pdo_io();
        engine.load_all(now, &mut io);
        self.pdo_emcy(now);
    }

    /// Bus-side or local write with CiA 301 checks, the communication objects' own rules, and
    /// the services' reactions.
    pub(super) fn write_checked(
        &mut self,
        now: Instant,
        index: u16,
        sub: u8,
        data: &[u8],
        by: Writer,
    ) -> Result<(), AbortCode> {
        let e = self.od.get(index, sub)?;
        let allowed = match by {
            Writer::Sdo => e.def.access.writable(),
            Writer::Local => e.def.access != Access::Const,
        };
        if !allowed {
            return Err(AbortCode::READ_ONLY);
        }
        check_value(e.def, data)?;
        if matches!(index, comm::STORE_PARAMETERS | comm::RESTORE_DEFAULTS) && sub >= 1 {
            return self.storage_write(now, index, sub, data, by);
        }
        self.validate_comm(index, sub, data)?;
        self.od.store(index, sub, data)?;
        self.on_written(now, index, sub, by);
        Ok(())
    }

    /// Rules of communication objects that depend on other entries or on running services.
    pub(super) fn validate_comm(&self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        pdo::check_write(&self.od, index, sub, data, self.pdo.max_bits())?;
        // CiA 304: the SRDO configuration changes only outside operational.
        if srdo_config::locked_in_operational(index) && self.state == NmtState::Operational {
            return Err(AbortCode::DEVICE_STATE);
        }
        let new = || {
            let mut b = [0u8; 4];
            let n = data.len().min(4);
            b[..n].copy_from_slice(&data[..n]);
            u32::from_le_bytes(b)
        };
        match index {
            comm::HEARTBEAT_CONSUMER if sub >= 1 => {
                self.consumer.check(sub, ConsumerSetting::from_u32(new()))
            }
            // CiA 301: the overflow value may only change while SYNC production is off.
            comm::SYNC_OVERFLOW if self.od.get_u32(comm::SYNC_PERIOD, 0).unwrap_or(0) != 0 => {
                Err(AbortCode::DEVICE_STATE)
            }
            // The identifier of an active producer (bit 30) must not change under way.
            comm::SYNC_COB_ID => {
                let old = CobId(self.od.get_u32(index, 0).unwrap_or(0));
                let new = CobId(new());
                if old.bit30() && new.bit30() && (old.0 & 0x3FFF_FFFF) != (new.0 & 0x3FFF_FFFF) {
                    Err(AbortCode::VALUE_RANGE)
                } else {
                    Ok(())
                }
            }
            // A valid EMCY COB-ID must be invalidated before its identifier changes.
            comm::EMCY_COB_ID => {
                let old = CobId(self.od.get_u32(index, 0).unwrap_or(0));
                let new = CobId(new());
                if old.is_valid() && new.is_valid() && old.0 != new.0 {
                    Err(AbortCode::VALUE_RANGE)
                } else {
                    Ok(())
                }
            }
            _ => Ok(()),
        }
    }

    pub(super) fn on_written(&mut self, now: Instant, index: u16, sub: u8, by: Writer) {
        self.pdo_written(now, index, sub);
        // A changed SRDO parameter, mapping or checksum voids the "configuration valid" mark.
        if srdo_config::invalidates(index) {
            let _ = self.od.store(srdo_config::CONFIG_VALID, 0, &[0]);
        }
        match index {
            comm::HEARTBEAT_PRODUCER => {
                let period = Duration::from_millis(self.u16_of(comm::HEARTBEAT_PRODUCER) as u64);
                // A new producer time is announced at once and its grid starts there; the
                // same time written again leaves the grid alone.
                if period != self.hb.period() {
                    self.hb.restart(now, period);
                    self.heartbeat_now(now);
                }
            }
            comm::HEARTBEAT_CONSUMER if sub >= 1 => {
                let v = self.od.get_u32(index, sub).unwrap_or(0);
                let _ = self.consumer.configure(sub, ConsumerSetting::from_u32(v));
                // A reconfigured entry starts over: a loss it reported is gone.
                self.monitoring_changed(now, None);
            }
            #[cfg(feature = "guarding")]
            comm::GUARD_TIME | comm::LIFE_TIME_FACTOR => {
                let (gt, lf) = self.guard_params();
                self.guard.configure(now, gt, lf);
            }
            comm::SYNC_COB_ID | comm::SYNC_PERIOD | comm::SYNC_WINDOW | comm::SYNC_OVERFLOW => {
                self.sync.configure(now, self.sync_config())
            }
            #[cfg(feature = "time")]
            comm::TIME_COB_ID => self.time.configure(
                now,
                CobId(self.od.get_u32(index, 0).unwrap_or(CobId::INVALID)),
            ),
            comm::EMCY_COB_ID | comm::EMCY_INHIBIT => {
                let (cob, inhibit) = self.emcy_params();
                self.emcy.configure(cob, inhibit);
            }
            comm::ERROR_HISTORY if sub == 0 => {
                for s in 1..=self.history_slots {
                    let _ = self.od.store(index, s, &0u32.to_le_bytes());
                }
            }
            _ => {}
        }
        self.event(now, NodeEventKind::ObjectWritten { index, sub, by });
    }
}

impl<
        D: ObjectDictionary,
        P: IdProfile,
        const GUARDED: usize,
        const TPDOS: usize,
        const RPDOS: usize,
        S: Storage,
    > ObjectAccess for NodeCore<D, P, GUARDED, TPDOS, RPDOS, S>
{
    fn entry(&self, index: u16, sub: u8) -> Result<Entry<'_>, AbortCode> {
        self.od.get(index, sub)
    }
    fn read(&self, index: u16, sub: u8) -> Result<&[u8], AbortCode> {
        self.od.read(index, sub)
    }
    fn write(&mut self, now: Instant, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        self.write_checked(now, index, sub, data, Writer::Sdo)
    }
}
