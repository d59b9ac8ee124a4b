//! Definition tables of the CiA 304 objects, `const` like [`crate::od::comm`], so a `no_std`
//! node keeps them in flash: one SRDO's communication parameters and mapping, and the objects
//! all SRDOs share (0x1300 GFC, 0x13FE configuration valid, 0x13FF checksums).
//!
//! ```
//! use duocan_core::cia304::srdo::objects;
//! use duocan_core::od::{ObjectDef, StaticDictionary};
//! static SRDO1: [ObjectDef; objects::SRDO_LEN] = objects::srdo(1, 0x101);
//! static SHARED: [ObjectDef; 4] = objects::shared::<4>(); // 0x13FF with one checksum
//! let mut od = StaticDictionary::<32, 128>::new();
//! od.load(1, &[&SRDO1, &SHARED]).unwrap();
//! ```

use super::config::TRANSMISSION_TYPE;
use super::config::{sub, CHECKSUMS, COMM, CONFIG_VALID, GFC_PARAMETER, MAPPING, MAX_MAPPED};
use crate::od::{Access, ObjectDef, ObjectType};

/// Entries [`srdo`] defines: 7 communication, 17 mapping.
pub const SRDO_LEN: usize = 7 + 1 + MAX_MAPPED as usize;

/// SRDO `n`'s communication parameters and mapping, unused (direction 0) and unmapped, on the
/// COB-IDs `normal` and `normal + 1` ([`default_cob_ids`](super::config::default_cob_ids)
/// gives a node's defaults).
#[must_use]
pub const fn srdo(n: u16, normal: u16) -> [ObjectDef; SRDO_LEN] {
    let comm = COMM + n - 1;
    let map = MAPPING + n - 1;
    const fn rec(d: ObjectDef) -> ObjectDef {
        d.object_type(ObjectType::Record)
    }
    let mut t = [rec(ObjectDef::u8(comm, 0, Access::Const, 6)); SRDO_LEN];
    t[1] = rec(ObjectDef::u8(comm, sub::DIRECTION, Access::Rw, 0)).named("Direction");
    t[2] = rec(ObjectDef::u16(comm, sub::SCT, Access::Rw, 25)).named("Refresh time / SCT");
    t[3] = rec(ObjectDef::u8(comm, sub::SRVT, Access::Rw, 20)).named("SRVT");
    t[4] = rec(ObjectDef::u8(
        comm,
        sub::TRANSMISSION_TYPE,
        Access::Rw,
        TRANSMISSION_TYPE,
    ))
    .named("Transmission type");
    t[5] = rec(ObjectDef::u32(
        comm,
        sub::COB_NORMAL,
        Access::Rw,
        normal as u32,
    ))
    .named("COB-ID 1");
    t[6] = rec(ObjectDef::u32(
        comm,
        sub::COB_INVERTED,
        Access::Rw,
        normal as u32 + 1,
    ))
    .named("COB-ID 2");
    t[7] = ObjectDef::u8(map, 0, Access::Rw, 0)
        .object_type(ObjectType::Array)
        .named("Number of mapped objects");
    let mut s = 1;
    while s <= MAX_MAPPED {
        t[7 + s as usize] = ObjectDef::u32(map, s, Access::Rw, 0).object_type(ObjectType::Array);
        s += 1;
    }
    t[0] = t[0].named("SRDO communication parameter");
    t
}

/// 0x1300 (GFC parameter, 0), 0x13FE (configuration valid, 0) and 0x13FF with one checksum
/// per SRDO: `K` is the number of SRDOs plus 3 (at least 4, at most 67).
#[must_use]
pub const fn shared<const K: usize>() -> [ObjectDef; K] {
    let mut t = [ObjectDef::u8(GFC_PARAMETER, 0, Access::Rw, 0).named("GFC parameter"); K];
    t[1] = ObjectDef::u8(CONFIG_VALID, 0, Access::Rw, 0).named("Configuration valid");
    t[2] = ObjectDef::u8(CHECKSUMS, 0, Access::Const, (K - 3) as u8)
        .object_type(ObjectType::Array)
        .named("Safety configuration checksum");
    let mut s = 1;
    while s + 2 < K {
        t[2 + s] = ObjectDef::u16(CHECKSUMS, s as u8, Access::Rw, 0).object_type(ObjectType::Array);
        s += 1;
    }
    t
}
