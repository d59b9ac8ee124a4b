//! Definition tables of the PDO parameter objects: communication (0x1400–0x15FF receive,
//! 0x1800–0x19FF transmit) and mapping (0x1600–0x17FF, 0x1A00–0x1BFF). All `const`, like
//! [`crate::od::comm`], so a no_std node keeps them in flash:
//!
//! ```
//! use duocan_core::od::{Access, DefaultValue, ObjectDef, StaticDictionary};
//! use duocan_core::pdo::params;
//! static APP: [ObjectDef; 1] = [ObjectDef::u16(0x6000, 1, Access::Rw, 0).mappable()];
//! static T1: [ObjectDef; params::TPDO_COMM_LEN] =
//!     params::tpdo_comm(1, params::predefined_tpdo_cob(1), 255, 0, 100);
//! static T1_MAP: [ObjectDef; 3] = params::tpdo_mapping(1, &[0x6000_0110]);
//! // Room for 16 entries and 128 bytes of values.
//! type AppDictionary = StaticDictionary<16, 128>;
//! let mut od = AppDictionary::new();
//! od.load(5, &[&APP, &T1, &T1_MAP]).unwrap();
//! ```

use crate::od::{Access, DefaultValue, ObjectDef, ObjectType};

/// First RPDO communication parameter (RPDO1).
pub const RPDO_COMM: u16 = 0x1400;
/// First RPDO mapping parameter (RPDO1).
pub const RPDO_MAPPING: u16 = 0x1600;
/// First TPDO communication parameter (TPDO1).
pub const TPDO_COMM: u16 = 0x1800;
/// First TPDO mapping parameter (TPDO1).
pub const TPDO_MAPPING: u16 = 0x1A00;
/// PDOs per direction CiA 301 can address (0x1400–0x15FF).
pub const MAX_PDOS: u16 = 512;

/// Sub-indices of the communication parameter records.
pub mod sub {
    /// COB-ID (bit 31 invalid, bit 30 no RTR, bit 29 29-bit frame).
    pub const COB_ID: u8 = 1;
    /// Transmission type.
    pub const TRANSMISSION_TYPE: u8 = 2;
    /// Inhibit time, 100 µs (TPDO).
    pub const INHIBIT_TIME: u8 = 3;
    /// Event timer, ms (TPDO: period of event-driven transmission; RPDO: reception timeout).
    pub const EVENT_TIMER: u8 = 5;
    /// SYNC start value (TPDO).
    pub const SYNC_START: u8 = 6;
}

/// Entries [`rpdo_comm`] defines: subs 0, 1, 2, 5.
pub const RPDO_COMM_LEN: usize = 4;
/// Entries [`tpdo_comm`] defines: subs 0, 1, 2, 3, 5, 6.
pub const TPDO_COMM_LEN: usize = 6;

const fn index(base: u16, pdo: u16) -> u16 {
    assert!(pdo >= 1 && pdo <= MAX_PDOS, "PDO number must be 1..=512");
    base + (pdo - 1)
}

/// The default COB-ID CiA 301 gives RPDO `pdo` (1–4: `0x200 + (pdo−1)·0x100 + node-ID`, valid);
/// higher numbers have none and start invalid.
pub const fn predefined_rpdo_cob(pdo: u16) -> DefaultValue {
    if pdo >= 1 && pdo <= 4 {
        DefaultValue::NodeIdPlus(0x200 + (pdo as u32 - 1) * 0x100)
    } else {
        DefaultValue::Unsigned(0x8000_0000)
    }
}

/// The default COB-ID CiA 301 gives TPDO `pdo` (1–4: `0x180 + (pdo−1)·0x100 + node-ID`, valid);
/// higher numbers have none and start invalid.
pub const fn predefined_tpdo_cob(pdo: u16) -> DefaultValue {
    if pdo >= 1 && pdo <= 4 {
        DefaultValue::NodeIdPlus(0x180 + (pdo as u32 - 1) * 0x100)
    } else {
        DefaultValue::Unsigned(0x8000_0000)
    }
}

const fn rec(d: ObjectDef, name: &'static str) -> ObjectDef {
    d.object_type(ObjectType::Record).named(name)
}

/// RPDO `pdo` (1–512) communication parameter: COB-ID, transmission type (0–240 synchronous,
/// 254/255 asynchronous) and event timer (reception timeout in ms, 0 = none).
///
/// Panics (at compile time in a const context) if `pdo` is not 1–512.
pub const fn rpdo_comm(
    pdo: u16,
    cob_id: DefaultValue,
    transmission_type: u8,
    timeout_ms: u16,
) -> [ObjectDef; RPDO_COMM_LEN] {
    let i = index(RPDO_COMM, pdo);
    [
        rec(
            ObjectDef::u8(i, 0, Access::Const, 5),
            "RPDO communication parameter",
        ),
        rec(
            ObjectDef::u32(i, sub::COB_ID, Access::Rw, 0).default(cob_id),
            "COB-ID used by RPDO",
        ),
        rec(
            ObjectDef::u8(i, sub::TRANSMISSION_TYPE, Access::Rw, transmission_type),
            "Transmission type",
        ),
        rec(
            ObjectDef::u16(i, sub::EVENT_TIMER, Access::Rw, timeout_ms),
            "Event timer",
        ),
    ]
}

/// TPDO `pdo` (1–512) communication parameter: COB-ID, transmission type, inhibit time
/// (100 µs), event timer (ms) and SYNC start value 0.
///
/// Panics (at compile time in a const context) if `pdo` is not 1–512.
pub const fn tpdo_comm(
    pdo: u16,
    cob_id: DefaultValue,
    transmission_type: u8,
    inhibit_100us: u16,
    event_timer_ms: u16,
) -> [ObjectDef; TPDO_COMM_LEN] {
    let i = index(TPDO_COMM, pdo);
    [
        rec(
            ObjectDef::u8(i, 0, Access::Const, 6),
            "TPDO communication parameter",
        ),
        rec(
            ObjectDef::u32(i, sub::COB_ID, Access::Rw, 0).default(cob_id),
            "COB-ID used by TPDO",
        ),
        rec(
            ObjectDef::u8(i, sub::TRANSMISSION_TYPE, Access::Rw, transmission_type),
            "Transmission type",
        ),
        rec(
            ObjectDef::u16(i, sub::INHIBIT_TIME, Access::Rw, inhibit_100us),
            "Inhibit time",
        ),
        rec(
            ObjectDef::u16(i, sub::EVENT_TIMER, Access::Rw, event_timer_ms),
            "Event timer",
        ),
        rec(
            ObjectDef::u8(i, sub::SYNC_START, Access::Rw, 0),
            "SYNC start value",
        ),
    ]
}

const fn mapping<const M: usize>(i: u16, defaults: &[u32], name: &'static str) -> [ObjectDef; M] {
    assert!(
        M >= 1 && M <= 65,
        "a mapping has 0..=64 entries: M is 1..=65"
    );
    assert!(
        defaults.len() < M,
        "more default entries than the mapping holds"
    );
    let mut out = [ObjectDef::u32(i, 0, Access::Rw, 0); M];
    out[0] = ObjectDef::u8(i, 0, Access::Rw, defaults.len() as u8)
        .object_type(ObjectType::Record)
        .named(name);
    let mut k = 1;
    while k < M {
        let v = if k - 1 < defaults.len() {
            defaults[k - 1]
        } else {
            0
        };
        out[k] = rec(
            ObjectDef::u32(i, k as u8, Access::Rw, v),
            "Application object",
        );
        k += 1;
    }
    out
}

/// RPDO `pdo` mapping parameter with `M − 1` entries, the first ones set to `defaults`
/// (`index << 16 | sub << 8 | bits`) and sub 0 to their number.
///
/// Panics (at compile time in a const context) if `pdo` is not 1–512 or `M` not 1–65.
pub const fn rpdo_mapping<const M: usize>(pdo: u16, defaults: &[u32]) -> [ObjectDef; M] {
    mapping(index(RPDO_MAPPING, pdo), defaults, "RPDO mapping parameter")
}

/// TPDO `pdo` mapping parameter with `M − 1` entries, the first ones set to `defaults`.
///
/// Panics (at compile time in a const context) if `pdo` is not 1–512 or `M` not 1–65.
pub const fn tpdo_mapping<const M: usize>(pdo: u16, defaults: &[u32]) -> [ObjectDef; M] {
    mapping(index(TPDO_MAPPING, pdo), defaults, "TPDO mapping parameter")
}

#[cfg(all(test, feature = "alloc"))]
mod tests {
    use super::*;
    use crate::od::{DynamicDictionary, ObjectDictionary};

    #[test]
    fn tables_hold_the_cia_layout() {
        let od = DynamicDictionary::from_tables(
            7,
            &[
                &rpdo_comm(2, predefined_rpdo_cob(2), 1, 50),
                &tpdo_comm(5, predefined_tpdo_cob(5), 254, 10, 0),
                &tpdo_mapping::<9>(5, &[0x6000_0108, 0x6401_0110]),
            ],
        )
        .unwrap();
        assert_eq!(od.get_value::<u32>(0x1401, 1), Ok(0x307));
        assert_eq!(od.get_value::<u8>(0x1401, 2), Ok(1));
        assert_eq!(od.get_value::<u16>(0x1401, 5), Ok(50));
        assert_eq!(od.get_value::<u32>(0x1804, 1), Ok(0x8000_0000));
        assert_eq!(od.get_value::<u16>(0x1804, 3), Ok(10));
        assert_eq!(od.get_value::<u8>(0x1A04, 0), Ok(2));
        assert_eq!(od.get_value::<u32>(0x1A04, 2), Ok(0x6401_0110));
        assert_eq!(od.get_value::<u32>(0x1A04, 8), Ok(0));
    }
}
