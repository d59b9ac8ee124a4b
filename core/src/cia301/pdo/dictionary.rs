//! The PDO parameters in the dictionary: which object is which, the CiA 301 rules a write to
//! them must pass (checked before it is stored), and reading a PDO's parameters for the engine.

use super::mapping::{self, check_entry, Dir, MapEntry, Mapping, MAX_ENTRIES};
use super::params::{self, RPDO_COMM, RPDO_MAPPING, TPDO_COMM, TPDO_MAPPING};
use super::rpdo::{Rpdo, RpdoParams};
use super::tpdo::{Tpdo, TpdoParams};
use crate::frame::cob_id::CobId;
use crate::frame::instant::Duration;
use crate::frame::Id;
use crate::od::abort::AbortCode;
use crate::od::ObjectDictionary;

/// Which PDO parameter object `index` is: direction, mapping (true) or communication, PDO slot.
pub(crate) fn classify(index: u16) -> Option<(Dir, bool, u16)> {
    match index {
        0x1400..=0x15FF => Some((Dir::Receive, false, index - RPDO_COMM)),
        0x1600..=0x17FF => Some((Dir::Receive, true, index - RPDO_MAPPING)),
        0x1800..=0x19FF => Some((Dir::Transmit, false, index - TPDO_COMM)),
        0x1A00..=0x1BFF => Some((Dir::Transmit, true, index - TPDO_MAPPING)),
        _ => None,
    }
}

pub(super) const fn comm_index(dir: Dir, slot: u16) -> u16 {
    match dir {
        Dir::Receive => RPDO_COMM + slot,
        Dir::Transmit => TPDO_COMM + slot,
    }
}

pub(super) const fn map_index(dir: Dir, slot: u16) -> u16 {
    match dir {
        Dir::Receive => RPDO_MAPPING + slot,
        Dir::Transmit => TPDO_MAPPING + slot,
    }
}

/// CiA 301's restricted 11-bit identifiers: no PDO may use them.
pub const fn restricted_id(raw: u16) -> bool {
    raw <= 0x7F
        || (raw >= 0x101 && raw <= 0x180)
        || (raw >= 0x581 && raw <= 0x5FF)
        || (raw >= 0x601 && raw <= 0x67F)
        || (raw >= 0x6E0 && raw <= 0x6FF)
        || raw >= 0x701
}

pub(super) fn le_u32(data: &[u8]) -> u32 {
    mapping::le_u64(data) as u32
}

/// The CiA 301 rules of a write to a PDO parameter object, checked against the dictionary as it
/// is before the write. Other indices pass. A mapping's total length is checked against
/// `max_bits`, the frame a PDO of this node has: 64 bits classic, 512 on a CANopen FD network.
pub(crate) fn check_write<D: ObjectDictionary + ?Sized>(
    od: &D,
    index: u16,
    sub: u8,
    data: &[u8],
    max_bits: u32,
) -> Result<(), AbortCode> {
    let Some((dir, is_map, slot)) = classify(index) else {
        return Ok(());
    };
    let comm = comm_index(dir, slot);
    let cob = CobId(
        od.get_u32(comm, params::sub::COB_ID)
            .unwrap_or(CobId::INVALID),
    );
    let valid = cob.is_valid();
    let v = le_u32(data);
    if is_map {
        if valid {
            return Err(AbortCode::VALUE_RANGE);
        }
        if sub == 0 {
            // 0xFE/0xFF make the PDO an MPDO: its entries are not used, so not checked.
            #[cfg(feature = "mpdo")]
            if crate::cia301::mpdo::Mode::from_mapping_count(v).is_some() {
                return Ok(());
            }
            if v > MAX_ENTRIES as u32 {
                return Err(AbortCode::VALUE_RANGE);
            }
            let mut bits = 0u32;
            for s in 1..=v as u8 {
                let raw = od.get_u32(index, s).ok_or(AbortCode::PDO_LENGTH)?;
                let e = MapEntry::from_raw(raw);
                check_entry(od, dir, e)?;
                bits += e.bits as u32;
            }
            if bits > max_bits {
                return Err(AbortCode::PDO_LENGTH);
            }
            return Ok(());
        }
        if od.get_u32(index, 0).unwrap_or(0) != 0 {
            return Err(AbortCode::VALUE_RANGE);
        }
        return match v {
            0 => Ok(()),
            raw => check_entry(od, dir, MapEntry::from_raw(raw)),
        };
    }
    let ttype = od
        .get_u32(comm, params::sub::TRANSMISSION_TYPE)
        .unwrap_or(255) as u8;
    let rtr_only = |t: u8| dir == Dir::Transmit && (t == 252 || t == 253);
    match sub {
        params::sub::COB_ID => {
            let new = CobId(v);
            if !new.is_valid() {
                return Ok(());
            }
            if valid && (cob.0 & 0x3FFF_FFFF) != (new.0 & 0x3FFF_FFFF) {
                return Err(AbortCode::VALUE_RANGE);
            }
            match new.can_id() {
                None => Err(AbortCode::VALUE_RANGE),
                Some(Id::Standard(raw)) if restricted_id(raw) => Err(AbortCode::VALUE_RANGE),
                Some(_) if rtr_only(ttype) && new.bit30() => Err(AbortCode::VALUE_RANGE),
                Some(_) => Ok(()),
            }
        }
        params::sub::TRANSMISSION_TYPE => {
            let t = v as u8;
            let reserved = match dir {
                Dir::Transmit => (241..=251).contains(&t),
                Dir::Receive => (241..=253).contains(&t),
            };
            if reserved || (valid && rtr_only(t) && cob.bit30()) {
                Err(AbortCode::VALUE_RANGE)
            } else {
                Ok(())
            }
        }
        params::sub::INHIBIT_TIME if dir == Dir::Transmit && valid => Err(AbortCode::VALUE_RANGE),
        params::sub::SYNC_START if dir == Dir::Transmit => {
            if valid || v > 240 {
                Err(AbortCode::VALUE_RANGE)
            } else {
                Ok(())
            }
        }
        _ => Ok(()),
    }
}

pub(super) fn read_cob<D: ObjectDictionary + ?Sized>(od: &D, dir: Dir, slot: u16) -> Option<CobId> {
    od.get_u32(comm_index(dir, slot), params::sub::COB_ID)
        .map(CobId)
}

pub(super) fn read_tpdo<D: ObjectDictionary + ?Sized>(
    od: &D,
    slot: u16,
    max_bits: u32,
) -> TpdoParams {
    let Some(cob) = read_cob(od, Dir::Transmit, slot) else {
        return Tpdo::new().p;
    };
    let c = comm_index(Dir::Transmit, slot);
    let get = |s| od.get_u32(c, s).unwrap_or(0);
    let ttype = od.get_u32(c, params::sub::TRANSMISSION_TYPE).unwrap_or(255) as u8;
    let mut p = TpdoParams {
        id: if cob.is_valid() { cob.can_id() } else { None },
        rtr_allowed: !cob.bit30(),
        ttype,
        inhibit: Duration::from_micros(get(params::sub::INHIBIT_TIME) as u64 * 100),
        event_timer: Duration::from_millis(get(params::sub::EVENT_TIMER) as u64),
        sync_start: get(params::sub::SYNC_START) as u8,
        mapping: Mapping::EMPTY,
        error: None,
        #[cfg(feature = "mpdo")]
        mpdo: mpdo_mode(od, Dir::Transmit, slot),
    };
    // An MPDO's entries are not used (and not checked).
    #[cfg(feature = "mpdo")]
    if p.mpdo.is_none() {
        match Mapping::load(od, Dir::Transmit, map_index(Dir::Transmit, slot), max_bits) {
            Ok(m) => p.mapping = m,
            Err(e) => p.error = Some(e),
        }
    }
    #[cfg(not(feature = "mpdo"))]
    match Mapping::load(od, Dir::Transmit, map_index(Dir::Transmit, slot), max_bits) {
        Ok(m) => p.mapping = m,
        Err(e) => p.error = Some(e),
    }
    if (241..=251).contains(&ttype) {
        p.error = Some(AbortCode::VALUE_RANGE);
    }
    p
}

pub(super) fn read_rpdo<D: ObjectDictionary + ?Sized>(
    od: &D,
    slot: u16,
    max_bits: u32,
) -> RpdoParams {
    let Some(cob) = read_cob(od, Dir::Receive, slot) else {
        return Rpdo::new().p;
    };
    let c = comm_index(Dir::Receive, slot);
    let ttype = od.get_u32(c, params::sub::TRANSMISSION_TYPE).unwrap_or(255) as u8;
    let mut p = RpdoParams {
        id: if cob.is_valid() { cob.can_id() } else { None },
        ttype,
        timeout: Duration::from_millis(od.get_u32(c, params::sub::EVENT_TIMER).unwrap_or(0) as u64),
        mapping: Mapping::EMPTY,
        error: None,
        #[cfg(feature = "mpdo")]
        mpdo: mpdo_mode(od, Dir::Receive, slot),
    };
    #[cfg(feature = "mpdo")]
    if p.mpdo.is_none() {
        match Mapping::load(od, Dir::Receive, map_index(Dir::Receive, slot), max_bits) {
            Ok(m) => p.mapping = m,
            Err(e) => p.error = Some(e),
        }
    }
    #[cfg(not(feature = "mpdo"))]
    match Mapping::load(od, Dir::Receive, map_index(Dir::Receive, slot), max_bits) {
        Ok(m) => p.mapping = m,
        Err(e) => p.error = Some(e),
    }
    if (241..=253).contains(&ttype) {
        p.error = Some(AbortCode::VALUE_RANGE);
    }
    p
}

/// The MPDO mode a PDO's mapping count (0xFE, 0xFF) gives it; `None` for a classic PDO.
#[cfg(feature = "mpdo")]
fn mpdo_mode<D: ObjectDictionary + ?Sized>(
    od: &D,
    dir: Dir,
    slot: u16,
) -> Option<crate::cia301::mpdo::Mode> {
    crate::cia301::mpdo::Mode::from_mapping_count(od.get_u32(map_index(dir, slot), 0)?)
}
