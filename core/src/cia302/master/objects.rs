//! Definition tables of the CiA 302-2 master objects: 0x1F80 NMT startup, 0x1F81 slave
//! assignment, 0x1F82 request NMT, 0x1F84–0x1F88 expected identity, 0x1F89 boot time, and
//! the configuration manager's 0x1F22 concise DCF and 0x1F26/0x1F27 expected configuration date
//! and time, and 0x1F55 expected software identification (program download).
//!
//! All `const`, like [`crate::od::comm`]. Arrays have sub 0 = 127 (128 for 0x1F82, whose sub 128
//! addresses all nodes) and one entry per node-ID.

use crate::od::abort::AbortCode;
use crate::od::{comm, Access, DataType, DynamicDictionary, ObjectDef, ObjectType};

/// NMT startup.
pub const NMT_STARTUP: u16 = 0x1F80;
/// NMT slave assignment.
pub const SLAVE_ASSIGNMENT: u16 = 0x1F81;
/// Request NMT: writing sub n asks the master to send an NMT command to node n (128: all);
/// reading gives node n's state as the master knows it.
pub const REQUEST_NMT: u16 = 0x1F82;
/// Device type identification (expected 0x1000).
pub const DEVICE_TYPE_ID: u16 = 0x1F84;
/// Vendor identification (expected 0x1018 sub 1).
pub const VENDOR_ID: u16 = 0x1F85;
/// Product code (expected 0x1018 sub 2).
pub const PRODUCT_CODE: u16 = 0x1F86;
/// Revision number (expected 0x1018 sub 3).
pub const REVISION_NUMBER: u16 = 0x1F87;
/// Serial number (expected 0x1018 sub 4).
pub const SERIAL_NUMBER: u16 = 0x1F88;
/// Boot time in ms.
pub const BOOT_TIME: u16 = 0x1F89;
/// Concise DCF (CiA 302-3): sub n, node n's configuration as a concise DCF
/// ([`super::ConciseDcf`]), applied by its boot process; empty: none. A malformed one is
/// refused with [`AbortCode::VALUE_RANGE`].
pub const CONCISE_DCF: u16 = 0x1F22;
/// Expected software identification (CiA 302-3): sub n, the 0x1F56 sub 1 node n must report
/// after a program download (0: not checked).
pub const EXPECTED_SOFTWARE: u16 = 0x1F55;
/// Expected configuration date (CiA 302-3): sub n, the date node n's 0x1020 sub 1 must hold
/// for its configuration to count as written already (0: not checked).
pub const EXPECTED_CONFIG_DATE: u16 = 0x1F26;
/// Expected configuration time (CiA 302-3): sub n, for node n's 0x1020 sub 2.
pub const EXPECTED_CONFIG_TIME: u16 = 0x1F27;
/// A slave's verify configuration object (CiA 301): sub 1 configuration date (days since
/// 1984-01-01), sub 2 configuration time (ms after midnight).
pub const VERIFY_CONFIGURATION: u16 = 0x1020;
/// The signature written to 0x1010 sub 1 to have a slave store all its parameters.
pub const SAVE: [u8; 4] = *b"save";

/// The sub-index of 0x1F82 that addresses all nodes.
pub const REQUEST_ALL: u8 = 128;

/// 0x1F82 values: what a request asks for, and what a read reports.
pub mod request {
    /// Read: the state is unknown.
    pub const UNKNOWN: u8 = 0;
    /// Read: the node is missing (not heard, heartbeat lost).
    pub const MISSING: u8 = 1;
    /// Stop (write) / stopped (read).
    pub const STOP: u8 = 4;
    /// Start (write) / operational (read).
    pub const START: u8 = 5;
    /// Write: reset node.
    pub const RESET_NODE: u8 = 6;
    /// Write: reset communication.
    pub const RESET_COMMUNICATION: u8 = 7;
    /// Enter pre-operational (write) / pre-operational (read).
    pub const PRE_OPERATIONAL: u8 = 127;
}

/// Entries of one node-indexed array: sub 0 = 127, subs 1–127 rw UNSIGNED32 = 0.
pub const fn node_array(index: u16, name: &'static str) -> [ObjectDef; 128] {
    let mut out = [ObjectDef::u32(index, 0, Access::Rw, 0); 128];
    out[0] = ObjectDef::u8(index, 0, Access::Const, 127)
        .object_type(ObjectType::Array)
        .named(name);
    let mut i = 1;
    while i < 128 {
        out[i] = ObjectDef::u32(index, i as u8, Access::Rw, 0)
            .object_type(ObjectType::Array)
            .named(name);
        i += 1;
    }
    out
}

/// 0x1F22: sub 0 = 127, subs 1–127 rw DOMAIN of at most [`super::MAX_CONCISE_BYTES`], empty,
/// that accept only a well-formed concise DCF (or nothing).
pub const fn concise_dcf() -> [ObjectDef; 128] {
    let mut out = [ObjectDef::u8(CONCISE_DCF, 0, Access::Const, 127); 128];
    out[0] = out[0].object_type(ObjectType::Array).named("Concise DCF");
    let mut i = 1;
    while i < 128 {
        out[i] = ObjectDef::bytes(
            CONCISE_DCF,
            i as u8,
            DataType::Domain,
            super::MAX_CONCISE_BYTES as u32,
        )
        .object_type(ObjectType::Array)
        .hook(concise_value)
        .named("Concise DCF");
        i += 1;
    }
    out
}

/// A 0x1F22 write must be a well-formed concise DCF (or empty: no concise DCF), so that the
/// dictionary never holds one the boot process would have to refuse halfway.
fn concise_value(_: u16, _: u8, data: &[u8]) -> Result<(), AbortCode> {
    if data.is_empty() {
        return Ok(());
    }
    super::validate_concise(data)
        .map(|_| ())
        .map_err(|_| AbortCode::VALUE_RANGE)
}

/// 0x1F80 and 0x1F89.
pub const fn startup_and_boot_time(startup: u32, boot_time_ms: u32) -> [ObjectDef; 2] {
    [
        ObjectDef::u32(NMT_STARTUP, 0, Access::Rw, startup).named("NMT startup"),
        ObjectDef::u32(BOOT_TIME, 0, Access::Rw, boot_time_ms).named("Boot time"),
    ]
}

/// 0x1F82: sub 0 = 128, subs 1–128 rw UNSIGNED8 that accept only the request values.
pub const fn request_nmt() -> [ObjectDef; 129] {
    let mut out = [ObjectDef::u8(REQUEST_NMT, 0, Access::Rw, 0); 129];
    out[0] = ObjectDef::u8(REQUEST_NMT, 0, Access::Const, 128)
        .object_type(ObjectType::Array)
        .named("Request NMT");
    let mut i = 1;
    while i < 129 {
        out[i] = ObjectDef::u8(REQUEST_NMT, i as u8, Access::Rw, 0)
            .object_type(ObjectType::Array)
            .hook(request_value)
            .named("Request NMT");
        i += 1;
    }
    out
}

/// A 0x1F82 write must name a command CiA 302-2 defines.
fn request_value(_: u16, _: u8, data: &[u8]) -> Result<(), AbortCode> {
    match data.first() {
        Some(
            &(request::STOP
            | request::START
            | request::RESET_NODE
            | request::RESET_COMMUNICATION
            | request::PRE_OPERATIONAL),
        ) => Ok(()),
        _ => Err(AbortCode::VALUE_RANGE),
    }
}

/// Inserts every master object into a dynamic dictionary (0x1F80/0x1F89 with the given values);
/// entries that exist already are kept.
pub fn insert_master_objects(od: &mut DynamicDictionary, startup: u32, boot_time_ms: u32) {
    let arrays = [
        node_array(SLAVE_ASSIGNMENT, "NMT slave assignment"),
        node_array(DEVICE_TYPE_ID, "Device type identification"),
        node_array(VENDOR_ID, "Vendor identification"),
        node_array(PRODUCT_CODE, "Product code"),
        node_array(REVISION_NUMBER, "Revision number"),
        node_array(SERIAL_NUMBER, "Serial number"),
        node_array(EXPECTED_CONFIG_DATE, "Expected configuration date"),
        node_array(EXPECTED_CONFIG_TIME, "Expected configuration time"),
        node_array(EXPECTED_SOFTWARE, "Expected software identification"),
    ];
    let singles = startup_and_boot_time(startup, boot_time_ms);
    let requests = request_nmt();
    let concise = concise_dcf();
    let tables: [&[ObjectDef]; 12] = [
        &arrays[0], &arrays[1], &arrays[2], &arrays[3], &arrays[4], &arrays[5], &arrays[6],
        &arrays[7], &arrays[8], &singles, &requests, &concise,
    ];
    for t in tables {
        for d in t {
            // A duplicate is an entry the caller defined already: theirs wins.
            let _ = od.insert(*d);
        }
    }
}

/// A master's dictionary: the standard communication objects
/// ([`comm::standard_dictionary`]) plus every master object. Its slave-related values are
/// written by [`super::Master::new`] from the [`super::MasterConfig`].
pub fn master_dictionary(node_id: u8, identity: comm::Identity) -> DynamicDictionary {
    let mut od = comm::standard_dictionary(node_id, identity);
    insert_master_objects(&mut od, 0, 0);
    od
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::od::ObjectDictionary;

    #[test]
    fn master_dictionary_has_every_object() {
        let od = master_dictionary(1, Default::default());
        for index in [
            SLAVE_ASSIGNMENT,
            DEVICE_TYPE_ID,
            VENDOR_ID,
            PRODUCT_CODE,
            REVISION_NUMBER,
            SERIAL_NUMBER,
            EXPECTED_CONFIG_DATE,
            EXPECTED_CONFIG_TIME,
            EXPECTED_SOFTWARE,
        ] {
            assert_eq!(od.get_value::<u8>(index, 0), Ok(127));
            assert_eq!(od.get_value::<u32>(index, 127), Ok(0));
            assert!(od.get(index, 128).is_err());
        }
        assert_eq!(od.get_value::<u8>(REQUEST_NMT, 0), Ok(128));
        assert_eq!(od.get_value::<u8>(CONCISE_DCF, 0), Ok(127));
        assert_eq!(od.read(CONCISE_DCF, 127), Ok(&[][..]));
        assert_eq!(od.get_value::<u8>(REQUEST_NMT, REQUEST_ALL), Ok(0));
        assert_eq!(od.get_value::<u32>(NMT_STARTUP, 0), Ok(0));
        assert_eq!(od.get_value::<u32>(BOOT_TIME, 0), Ok(0));
    }

    #[test]
    fn request_nmt_accepts_only_commands() {
        let mut od = master_dictionary(1, Default::default());
        for v in [4u8, 5, 6, 7, 127] {
            assert_eq!(od.write(REQUEST_NMT, 3, &[v]), Ok(()));
        }
        for v in [0u8, 1, 2, 3, 8, 126, 128, 255] {
            assert_eq!(
                od.write(REQUEST_NMT, 3, &[v]),
                Err(AbortCode::VALUE_RANGE),
                "{v}"
            );
        }
        assert_eq!(od.write(REQUEST_NMT, 0, &[5]), Err(AbortCode::READ_ONLY));
    }

    #[test]
    fn concise_dcf_accepts_only_well_formed_ones() {
        let mut od = master_dictionary(1, Default::default());
        let one = [1, 0, 0, 0, 0x00, 0x20, 1, 1, 0, 0, 0, 7];
        assert_eq!(od.write(CONCISE_DCF, 9, &one), Ok(()));
        for bad in [&one[..11], &[1, 0, 0][..], &[0, 0, 0, 0, 1][..]] {
            assert_eq!(od.write(CONCISE_DCF, 9, bad), Err(AbortCode::VALUE_RANGE));
        }
        // Refused: the well-formed one stays.
        assert_eq!(od.read(CONCISE_DCF, 9), Ok(&one[..]));
        assert_eq!(od.write(CONCISE_DCF, 9, &[]), Ok(()));
    }
}
