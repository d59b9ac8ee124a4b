//! Definition tables of the CiA 301 communication objects the stack's services use.
//!
//! All `const`, so a no_std node keeps them in flash:
//!
//! ```
//! use duocan_core::od::{comm, ObjectDef, StaticDictionary};
//! static COMM: [ObjectDef; comm::COMM_LEN] = comm::communication();
//! static ID: [ObjectDef; 6] = comm::identity(0x0001_0191, 0x1234, 1, 1, 42);
//! static HB: [ObjectDef; 5] = comm::heartbeat_consumers();
//! static HIST: [ObjectDef; 9] = comm::error_history();
//! // Room for 64 entries and 512 bytes of values.
//! type SlaveDictionary = StaticDictionary<64, 512>;
//! let mut od = SlaveDictionary::new();
//! od.load(5, &[&COMM, &ID, &HB, &HIST]).unwrap();
//! ```

use super::def::{Access, DataType, DefaultValue, ObjectDef, ObjectType, WriteHook};
use crate::od::abort::AbortCode;

/// Device type.
pub const DEVICE_TYPE: u16 = 0x1000;
/// Error register.
pub const ERROR_REGISTER: u16 = 0x1001;
/// Pre-defined error field (EMCY history).
pub const ERROR_HISTORY: u16 = 0x1003;
/// COB-ID SYNC.
pub const SYNC_COB_ID: u16 = 0x1005;
/// Communication cycle period (µs).
pub const SYNC_PERIOD: u16 = 0x1006;
/// Synchronous window length (µs).
pub const SYNC_WINDOW: u16 = 0x1007;
/// Guard time (ms).
pub const GUARD_TIME: u16 = 0x100C;
/// Life time factor.
pub const LIFE_TIME_FACTOR: u16 = 0x100D;
/// COB-ID TIME (bit 31 consumer, bit 30 producer).
pub const TIME_COB_ID: u16 = 0x1012;
/// COB-ID EMCY.
pub const EMCY_COB_ID: u16 = 0x1014;
/// Inhibit time EMCY (100 µs).
pub const EMCY_INHIBIT: u16 = 0x1015;
/// Consumer heartbeat time.
pub const HEARTBEAT_CONSUMER: u16 = 0x1016;
/// Producer heartbeat time (ms).
pub const HEARTBEAT_PRODUCER: u16 = 0x1017;
/// Identity object.
pub const IDENTITY: u16 = 0x1018;
/// Synchronous counter overflow value.
pub const SYNC_OVERFLOW: u16 = 0x1019;
/// First SDO server parameter.
pub const SDO_SERVER: u16 = 0x1200;
/// Store parameters (write `"save"` to store a group).
pub const STORE_PARAMETERS: u16 = 0x1010;
/// Restore default parameters (write `"load"` to restore a group's defaults).
pub const RESTORE_DEFAULTS: u16 = 0x1011;

/// Number of entries [`parameter_storage`] defines.
pub const STORAGE_LEN: usize = 10;

/// Number of entries [`communication`] defines.
pub const COMM_LEN: usize = 15;

/// 0x1001, 0x1005–0x1007, 0x100C/0x100D, 0x1012, 0x1014/0x1015, 0x1017, 0x1019, 0x1200.
pub const fn communication() -> [ObjectDef; COMM_LEN] {
    [
        ObjectDef::u8(ERROR_REGISTER, 0, Access::Ro, 0)
            .mappable()
            .named("Error register"),
        ObjectDef::u32(SYNC_COB_ID, 0, Access::Rw, 0x80).named("COB-ID SYNC"),
        ObjectDef::u32(SYNC_PERIOD, 0, Access::Rw, 0).named("Communication cycle period"),
        ObjectDef::u32(SYNC_WINDOW, 0, Access::Rw, 0).named("Synchronous window length"),
        ObjectDef::u16(GUARD_TIME, 0, Access::Rw, 0).named("Guard time"),
        ObjectDef::u8(LIFE_TIME_FACTOR, 0, Access::Rw, 0).named("Life time factor"),
        ObjectDef::u32(TIME_COB_ID, 0, Access::Rw, 0x100).named("COB-ID TIME"),
        ObjectDef::u32(EMCY_COB_ID, 0, Access::Rw, 0)
            .default(DefaultValue::NodeIdPlus(0x80))
            .named("COB-ID EMCY"),
        ObjectDef::u16(EMCY_INHIBIT, 0, Access::Rw, 0).named("Inhibit time EMCY"),
        ObjectDef::u16(HEARTBEAT_PRODUCER, 0, Access::Rw, 0).named("Producer heartbeat time"),
        ObjectDef::u8(SYNC_OVERFLOW, 0, Access::Rw, 0)
            .hook(sync_overflow_value)
            .named("Synchronous counter overflow value"),
        ObjectDef::u8(SDO_SERVER, 0, Access::Const, 2)
            .object_type(ObjectType::Record)
            .named("SDO server parameter"),
        ObjectDef::u32(SDO_SERVER, 1, Access::Ro, 0)
            .default(DefaultValue::NodeIdPlus(0x600))
            .object_type(ObjectType::Record)
            .named("COB-ID client to server"),
        ObjectDef::u32(SDO_SERVER, 2, Access::Ro, 0)
            .default(DefaultValue::NodeIdPlus(0x580))
            .object_type(ObjectType::Record)
            .named("COB-ID server to client"),
        ObjectDef::bytes(0x1008, 0, DataType::VisibleString, 32)
            .access(Access::Const)
            .default(DefaultValue::Bytes(b"duocan"))
            .named("Manufacturer device name"),
    ]
}

/// The write hooks of the communication objects whose values CiA 301 restricts beyond their
/// type: (index, sub-index, hook, the hook's name in this module). Dictionaries made from a
/// device description (imported or generated at build time) install them as these tables do.
pub const HOOKS: [(u16, u8, WriteHook, &str); 2] = [
    (ERROR_HISTORY, 0, error_history_clear, "error_history_clear"),
    (SYNC_OVERFLOW, 0, sync_overflow_value, "sync_overflow_value"),
];

/// The hook [`HOOKS`] gives (`index`, `sub`), if any.
#[must_use]
pub fn hook(index: u16, sub: u8) -> Option<WriteHook> {
    HOOKS
        .iter()
        .find(|(i, s, _, _)| (*i, *s) == (index, sub))
        .map(|h| h.2)
}

/// The write hook of 0x1019: it accepts 0 (no counter) or 2–240 (CiA 301: 1 and 241–255 are
/// reserved).
pub fn sync_overflow_value(_: u16, _: u8, data: &[u8]) -> Result<(), AbortCode> {
    match data.first() {
        Some(0) | Some(2..=240) => Ok(()),
        _ => Err(AbortCode::VALUE_RANGE),
    }
}

/// 0x1010 store parameters and 0x1011 restore default parameters, sub-indices 1–4 (all,
/// communication, application, manufacturer; see [`parameters`](super::parameters)). The read value
/// of each sub-index is set by the node at boot from what the dictionary's medium can do.
pub const fn parameter_storage() -> [ObjectDef; STORAGE_LEN] {
    const fn command(index: u16, sub: u8, name: &'static str) -> ObjectDef {
        ObjectDef::u32(index, sub, Access::Rw, 0)
            .object_type(ObjectType::Array)
            .named(name)
    }
    const fn highest(index: u16, name: &'static str) -> ObjectDef {
        ObjectDef::u8(index, 0, Access::Const, 4)
            .object_type(ObjectType::Array)
            .named(name)
    }
    [
        highest(STORE_PARAMETERS, "Store parameters"),
        command(STORE_PARAMETERS, 1, "Save all parameters"),
        command(STORE_PARAMETERS, 2, "Save communication parameters"),
        command(STORE_PARAMETERS, 3, "Save application parameters"),
        command(STORE_PARAMETERS, 4, "Save manufacturer defined parameters"),
        highest(RESTORE_DEFAULTS, "Restore default parameters"),
        command(RESTORE_DEFAULTS, 1, "Restore all default parameters"),
        command(
            RESTORE_DEFAULTS,
            2,
            "Restore communication default parameters",
        ),
        command(
            RESTORE_DEFAULTS,
            3,
            "Restore application default parameters",
        ),
        command(
            RESTORE_DEFAULTS,
            4,
            "Restore manufacturer defined default parameters",
        ),
    ]
}

/// What a device says it is: 0x1000 and 0x1018.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Identity {
    /// 0x1000 device type.
    pub device_type: u32,
    /// 0x1018 sub 1.
    pub vendor: u32,
    /// 0x1018 sub 2.
    pub product: u32,
    /// 0x1018 sub 3.
    pub revision: u32,
    /// 0x1018 sub 4.
    pub serial: u32,
}

impl Identity {
    /// The six definitions of 0x1000 and 0x1018.
    pub const fn defs(&self) -> [ObjectDef; 6] {
        identity(
            self.device_type,
            self.vendor,
            self.product,
            self.revision,
            self.serial,
        )
    }
}

/// 0x1000 device type and the 0x1018 identity record.
pub const fn identity(
    device_type: u32,
    vendor: u32,
    product: u32,
    revision: u32,
    serial: u32,
) -> [ObjectDef; 6] {
    const fn sub(sub: u8, v: u32, name: &'static str) -> ObjectDef {
        ObjectDef::u32(IDENTITY, sub, Access::Const, v)
            .object_type(ObjectType::Record)
            .named(name)
    }
    [
        ObjectDef::u32(DEVICE_TYPE, 0, Access::Const, device_type).named("Device type"),
        ObjectDef::u8(IDENTITY, 0, Access::Const, 4)
            .object_type(ObjectType::Record)
            .named("Identity object"),
        sub(1, vendor, "Vendor-ID"),
        sub(2, product, "Product code"),
        sub(3, revision, "Revision number"),
        sub(4, serial, "Serial number"),
    ]
}

/// 0x1016 with `M − 1` consumer entries (sub 0 holds `M − 1`), all disabled.
pub const fn heartbeat_consumers<const M: usize>() -> [ObjectDef; M] {
    let mut out = [ObjectDef::u32(HEARTBEAT_CONSUMER, 0, Access::Rw, 0); M];
    out[0] = ObjectDef::u8(HEARTBEAT_CONSUMER, 0, Access::Const, (M - 1) as u8)
        .object_type(ObjectType::Array)
        .named("Consumer heartbeat time");
    let mut i = 1;
    while i < M {
        out[i] = ObjectDef::u32(HEARTBEAT_CONSUMER, i as u8, Access::Rw, 0)
            .object_type(ObjectType::Array)
            .named("Consumer heartbeat time");
        i += 1;
    }
    out
}

/// 0x1003 with `M − 1` history slots. Sub 0 counts the recorded errors; only 0 may be written
/// (it clears the history), other values give 0x06090030 as CiA 301 requires.
pub const fn error_history<const M: usize>() -> [ObjectDef; M] {
    let mut out = [ObjectDef::u32(ERROR_HISTORY, 0, Access::Ro, 0); M];
    out[0] = ObjectDef::u8(ERROR_HISTORY, 0, Access::Rw, 0)
        .hook(error_history_clear)
        .object_type(ObjectType::Array)
        .named("Pre-defined error field");
    let mut i = 1;
    while i < M {
        out[i] = ObjectDef::u32(ERROR_HISTORY, i as u8, Access::Ro, 0)
            .object_type(ObjectType::Array)
            .named("Standard error field");
        i += 1;
    }
    out
}

/// The write hook of 0x1003 sub-index 0: only 0 may be written (it clears the history).
pub fn error_history_clear(_: u16, _: u8, data: &[u8]) -> Result<(), AbortCode> {
    if data.iter().all(|b| *b == 0) {
        Ok(())
    } else {
        Err(AbortCode::VALUE_RANGE)
    }
}

/// A complete dynamic dictionary of the communication objects: [`communication`], the identity,
/// a 127-entry heartbeat consumer table, an 8-slot error history and 0x1010/0x1011
/// ([`parameter_storage`]; they store once the dictionary has a medium). Application entries
/// are inserted on top of it.
#[cfg(feature = "alloc")]
pub fn standard_dictionary(node_id: u8, id: Identity) -> super::DynamicDictionary {
    let mut od = super::DynamicDictionary::new(node_id);
    // Every key in these tables is distinct, so the inserts cannot fail.
    let _ = od.insert_all(&communication());
    let _ = od.insert_all(&id.defs());
    let _ = od.insert_all(&heartbeat_consumers::<128>());
    let _ = od.insert_all(&error_history::<9>());
    let _ = od.insert_all(&parameter_storage());
    od
}

#[cfg(all(test, feature = "alloc"))]
mod tests {
    use super::*;
    use crate::od::ObjectDictionary;

    #[test]
    fn standard_dictionary_is_complete() {
        let od = standard_dictionary(
            5,
            Identity {
                vendor: 7,
                ..Identity::default()
            },
        );
        assert_eq!(od.len(), COMM_LEN + 6 + 128 + 9 + STORAGE_LEN);
        assert_eq!(od.get_value::<u32>(EMCY_COB_ID, 0), Ok(0x85));
        assert_eq!(od.get_value::<u32>(SDO_SERVER, 1), Ok(0x605));
        assert_eq!(od.get_value::<u32>(IDENTITY, 1), Ok(7));
        assert_eq!(od.get_value::<u8>(HEARTBEAT_CONSUMER, 0), Ok(127));
    }
}
