//! The master's object dictionary: `'static` definition tables (flash) loaded into a
//! [`StaticDictionary`] (an index and a value arena in RAM). Nothing is allocated for it.
//!
//! A CiA 302-2 master's dictionary is mostly node-indexed arrays: 0x1F81 (slave assignment),
//! 0x1F82 (request NMT) and the expected identity 0x1F84–0x1F88 have an entry for every
//! node-ID: 897 of the 945 entries here. The tables are the same `const` definitions the
//! run-time master dictionary ([`objects::master_dictionary`]) inserts, so the firmware's
//! master sees exactly the objects the host's does, less what a board without a parameter
//! store or a configuration manager does not use:
//!
//! | index | what |
//! |---|---|
//! | 0x1000–0x1200 | the communication objects ([`comm::communication`]), identity, error history |
//! | 0x1016 | 15 heartbeat consumer entries (the master fills them for the slaves it monitors; pair members are watched by the supervisor's own deadlines) |
//! | 0x1F80, 0x1F89 | NMT startup, boot time |
//! | 0x1F81, 0x1F82, 0x1F84–0x1F88 | slave assignment, request NMT, expected identity: 127 nodes each |
//!
//! Left out: 0x1010/0x1011 (no parameter store on this board), 0x1F22 (concise DCFs: 127
//! DOMAIN entries the master reads only when present), 0x1F26/0x1F27 and 0x1F55 (expected
//! configuration stamp and software: "not checked" when absent).
//!
//! [`objects::master_dictionary`]: duocan::master::objects::master_dictionary

use duocan::master::objects::{
    node_array, request_nmt, startup_and_boot_time, DEVICE_TYPE_ID, PRODUCT_CODE, REVISION_NUMBER,
    SERIAL_NUMBER, SLAVE_ASSIGNMENT, VENDOR_ID,
};
use duocan::od::{comm, BuildError, ObjectDef, StaticDictionary};

/// Entries the dictionary has room for (a power of two, as its index requires).
pub const OD_ENTRIES: usize = 1024;
/// Bytes of values: 4 per UNSIGNED32 entry, 1 per UNSIGNED8, 32 for the device name
/// (3,418 used).
pub const OD_BYTES: usize = 3584;
/// The master's dictionary.
pub type Od = StaticDictionary<OD_ENTRIES, OD_BYTES>;

/// The heartbeat consumer table: sub 0 and 15 entries.
pub const CONSUMERS: usize = 16;

/// Identity of the board (0x1000, 0x1018): a CiA 302 master device, duocan's vendor-ID.
pub const DEVICE_TYPE: u32 = 0x0000_0000;
/// Vendor-ID (0x1018 sub 1).
pub const VENDOR: u32 = 0x00D0_CA00;
/// Product code (0x1018 sub 2).
pub const PRODUCT: u32 = 0x0302;
/// Revision (0x1018 sub 3).
pub const REVISION: u32 = 1;

static COMM: [ObjectDef; comm::COMM_LEN] = comm::communication();
static IDENTITY: [ObjectDef; 6] = comm::identity(DEVICE_TYPE, VENDOR, PRODUCT, REVISION, 0);
static HEARTBEAT_CONSUMERS: [ObjectDef; CONSUMERS] = comm::heartbeat_consumers::<CONSUMERS>();
static ERROR_HISTORY: [ObjectDef; 9] = comm::error_history::<9>();
static STARTUP: [ObjectDef; 2] = startup_and_boot_time(0, 0);
static ASSIGNMENT: [ObjectDef; 128] = node_array(SLAVE_ASSIGNMENT, "NMT slave assignment");
static REQUEST_NMT: [ObjectDef; 129] = request_nmt();
static DEVICE_TYPES: [ObjectDef; 128] = node_array(DEVICE_TYPE_ID, "Device type identification");
static VENDORS: [ObjectDef; 128] = node_array(VENDOR_ID, "Vendor identification");
static PRODUCTS: [ObjectDef; 128] = node_array(PRODUCT_CODE, "Product code");
static REVISIONS: [ObjectDef; 128] = node_array(REVISION_NUMBER, "Revision number");
static SERIALS: [ObjectDef; 128] = node_array(SERIAL_NUMBER, "Serial number");

/// Every table, in load order.
pub static TABLES: [&[ObjectDef]; 12] = [
    &COMM,
    &IDENTITY,
    &HEARTBEAT_CONSUMERS,
    &ERROR_HISTORY,
    &STARTUP,
    &ASSIGNMENT,
    &REQUEST_NMT,
    &DEVICE_TYPES,
    &VENDORS,
    &PRODUCTS,
    &REVISIONS,
    &SERIALS,
];

/// Entries of [`TABLES`].
pub const ENTRIES: usize = comm::COMM_LEN + 6 + CONSUMERS + 9 + 2 + 6 * 128 + 129;

// The tables fit the dictionary they are loaded into.
const _: () = assert!(ENTRIES <= OD_ENTRIES);

/// Loads the tables into `od` (empty: a new [`Od`]) for the master with node-ID `node`. In
/// place: the firmware keeps the dictionary in `main`'s frame and lends it to the master.
pub fn load(od: &mut Od, node: u8) -> Result<(), BuildError> {
    od.load(node, &TABLES)
}
