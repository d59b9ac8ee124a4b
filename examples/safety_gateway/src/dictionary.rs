//! The gateway's object dictionary: `const` definition tables (flash) loaded into a
//! [`StaticDictionary`] (a fixed arena in RAM). Nothing here is built at run time.
//!
//! | index | what |
//! |---|---|
//! | 0x1000–0x1200 | communication objects, with the railway identifiers as defaults (SYNC, fault report, SDO server) and a [`HEARTBEAT_MS`] heartbeat |
//! | 0x1018 | identity |
//! | 0x1800–0x1803, 0x1A00–0x1A03 | TPDO *k* = state change of track circuit *k* on I/O port *k*: event-driven, refreshed every [`REFRESH_MS`] |
//! | 0x2001 | field timeout (ms): a track circuit not reported for this long is occupied |
//! | 0x2100 sub *k* | the railway payload TPDO *k* sends (index, sub, code, CRC) |
//! | 0x6000 sub *k* | the mirrored code of track circuit *k* (0x55 clear, 0xAA occupied) |

use crate::{ADDRESS, TRACKS};
use duocan::od::{comm, Access, DataType, DefaultValue, ObjectDef, ObjectType, StaticDictionary};
use duocan::pdo::params;
use duocan::profile::railway::safety::{objects, TrackCircuit};
use duocan::profile::railway::{self, RailFunction, RailwayProfile};
use duocan::CobId;

/// Entries the dictionary has room for (a power of two).
pub const OD_ENTRIES: usize = 128;
/// Bytes of values.
pub const OD_BYTES: usize = 512;
/// The gateway's dictionary.
pub type Od = StaticDictionary<OD_ENTRIES, OD_BYTES>;

/// Heartbeat producer time (ms), the default of 0x1017.
pub const HEARTBEAT_MS: u16 = 50;
/// Cyclic refresh of every track state on the interlocking side (TPDO event timer, ms).
pub const REFRESH_MS: u16 = 100;
/// Default of 0x2001: a track circuit the field board has not reported for this long is
/// mirrored as occupied (3 of the field board's 100 ms cycles).
pub const FIELD_TIMEOUT_MS: u16 = 300;

/// Field timeout (u16, ms, read-write).
pub const FIELD_TIMEOUT: u16 = 0x2001;
/// TPDO images: sub *k* holds the encoded railway payload of track circuit *k*.
pub const IMAGE: u16 = 0x2100;
/// Bytes of one image: index, sub-index, one code byte, CRC.
pub const IMAGE_LEN: usize = 6;
/// Mirrored track-circuit codes, sub *k* = track circuit *k* (the railway object index).
pub const TRACK_STATES: u16 = objects::TRACK_CIRCUIT;

/// The identity the gateway reports in 0x1018.
pub const VENDOR: u32 = 0x0000_D0CA;
/// Product code (0x1018 sub 2).
pub const PRODUCT: u32 = 0x5A6E;
/// Device type (0x1000): a generic I/O profile device.
pub const DEVICE_TYPE: u32 = 0x0000_0191;

/// The 29-bit identifier TPDO `track` uses by default: a state change on the gateway's I/O
/// port `track`.
pub const fn state_id(track: u8) -> duocan::Id {
    railway::id(RailFunction::StateChange, ADDRESS.with_port(track))
}

/// [`comm::communication`] with what differs on this board: the railway identifiers of
/// [`RailwayProfile::comm_objects`] and the heartbeat time.
const fn communication() -> [ObjectDef; comm::COMM_LEN] {
    let mut table = comm::communication();
    let railway = RailwayProfile::comm_objects(ADDRESS);
    let heartbeat = ObjectDef::u16(comm::HEARTBEAT_PRODUCER, 0, Access::Rw, HEARTBEAT_MS)
        .named("Producer heartbeat time");
    let mut i = 0;
    while i < table.len() {
        let (index, sub) = (table[i].index, table[i].sub);
        let mut j = 0;
        while j < railway.len() {
            if railway[j].index == index && railway[j].sub == sub {
                table[i] = railway[j];
            }
            j += 1;
        }
        if index == comm::HEARTBEAT_PRODUCER {
            table[i] = heartbeat;
        }
        i += 1;
    }
    table
}

const TPDO_COMM_LEN: usize = 6;
const TPDO_MAPPING_LEN: usize = 2;
const TPDO_LEN: usize = TRACKS as usize * (TPDO_COMM_LEN + TPDO_MAPPING_LEN);

/// TPDO *k*: COB-ID [`state_id`]`(k)`, asynchronous (254), refreshed every [`REFRESH_MS`],
/// mapping the 48-bit image 0x2100 sub *k*.
const fn tpdos() -> [ObjectDef; TPDO_LEN] {
    let mut out = [ObjectDef::u8(0, 0, Access::Const, 0); TPDO_LEN];
    let mut k = 1u8;
    let mut at = 0;
    while k <= TRACKS {
        let cob = CobId::from_id(state_id(k)).0 as u64;
        let c = params::tpdo_comm(k as u16, DefaultValue::Unsigned(cob), 254, 0, REFRESH_MS);
        let m = params::tpdo_mapping::<TPDO_MAPPING_LEN>(
            k as u16,
            &[(IMAGE as u32) << 16 | (k as u32) << 8 | (IMAGE_LEN as u32 * 8)],
        );
        let mut i = 0;
        while i < c.len() {
            out[at] = c[i];
            at += 1;
            i += 1;
        }
        i = 0;
        while i < m.len() {
            out[at] = m[i];
            at += 1;
            i += 1;
        }
        k += 1;
    }
    out
}

const APP_LEN: usize = 1 + 2 * (1 + TRACKS as usize);

/// 0x2001, 0x2100 and 0x6000.
const fn application() -> [ObjectDef; APP_LEN] {
    let mut out = [ObjectDef::u16(FIELD_TIMEOUT, 0, Access::Rw, FIELD_TIMEOUT_MS)
        .named("Field timeout"); APP_LEN];
    out[1] = ObjectDef::u8(IMAGE, 0, Access::Const, TRACKS)
        .object_type(ObjectType::Record)
        .named("State change images");
    out[2 + TRACKS as usize] = ObjectDef::u8(TRACK_STATES, 0, Access::Const, TRACKS)
        .object_type(ObjectType::Array)
        .named("Track circuits");
    let mut k = 1;
    while k <= TRACKS as usize {
        out[1 + k] = ObjectDef::bytes(IMAGE, k as u8, DataType::OctetString, IMAGE_LEN as u32)
            .access(Access::Ro)
            .mappable()
            .object_type(ObjectType::Record)
            .named("State change image");
        // Until the field board says otherwise, every track circuit is occupied (the safe side).
        out[2 + TRACKS as usize + k] = ObjectDef::u8(
            TRACK_STATES,
            k as u8,
            Access::Ro,
            TrackCircuit::Occupied as u8,
        )
        .mappable()
        .object_type(ObjectType::Array)
        .named("Track circuit state");
        k += 1;
    }
    out
}

static COMM: [ObjectDef; comm::COMM_LEN] = communication();
static IDENTITY: [ObjectDef; 6] = comm::identity(DEVICE_TYPE, VENDOR, PRODUCT, 1, 1);
static CONSUMERS: [ObjectDef; 3] = comm::heartbeat_consumers::<3>();
static TPDOS: [ObjectDef; TPDO_LEN] = tpdos();
static APPLICATION: [ObjectDef; APP_LEN] = application();

/// Every table of the gateway's dictionary, in load order.
pub static TABLES: [&[ObjectDef]; 5] = [&COMM, &IDENTITY, &CONSUMERS, &TPDOS, &APPLICATION];
