//! The gateway's object dictionary: `const` definition tables (flash) loaded into a
//! [`StaticDictionary`] (a fixed arena in RAM). Nothing here is built at run time.
//!
//! The tables are generated at build time from the gateway's EDS, `safety_gateway.eds` (the
//! one place the dictionary is written down, and the file an integrator gets): `build.rs` runs
//! [`duocan::eds::codegen`] and this module includes what it wrote. The figures the code needs
//! (heartbeat and refresh times, the field timeout, the identity) are read from the generated
//! table at compile time, so they cannot drift from the EDS.
//!
//! | index | what |
//! |---|---|
//! | 0x1000–0x1200 | communication objects, with the railway identifiers as defaults (SYNC, fault report, SDO server) and a [`HEARTBEAT_MS`] heartbeat |
//! | 0x1018 | identity |
//! | 0x1800–0x1803, 0x1A00–0x1A03 | TPDO *k* = state change of track circuit *k* on I/O port *k*: event-driven, refreshed every [`REFRESH_MS`] |
//! | 0x2001 | field timeout (ms): the SCT of the field board's SRDO; no intact pair for this long makes every track circuit occupied |
//! | 0x2100 sub *k* | the railway payload TPDO *k* sends (index, sub, code, CRC) |
//! | 0x6000 sub *k* | the mirrored code of track circuit *k* (0x55 clear, 0xAA occupied) |
//! | 0x6001 sub *k* | its bitwise inverse, the inverted half of the SRDO |
//! | 0x1301, 0x1381, 0x13FE, 0x13FF | SRDO 1 (CiA 304): the four codes and their inverses every [`SRDO_REFRESH_MS`] on 0x127/0x128, configuration valid, checksum |

use crate::{ADDRESS, TRACKS};
use duocan::od::{comm, DefaultValue, ObjectDef, StaticDictionary};
use duocan::profile::railway::safety::objects;
use duocan::profile::railway::{self, RailFunction};

/// What `build.rs` generated from `safety_gateway.eds`: `OBJECTS`, its sizes, and the
/// objects' indices by name (`index::FIELD_TIMEOUT`).
mod generated {
    include!(concat!(env!("OUT_DIR"), "/dictionary.rs"));
}

pub use generated::index;

/// Entries the dictionary has room for (a power of two).
pub const OD_ENTRIES: usize = 128;
/// Bytes of values.
pub const OD_BYTES: usize = 512;
/// The gateway's dictionary.
pub type Od = StaticDictionary<OD_ENTRIES, OD_BYTES>;

// The EDS fits the dictionary the RAM budget was measured with.
const _: () = assert!(generated::ENTRIES <= OD_ENTRIES && generated::VALUE_BYTES <= OD_BYTES);

/// The generated definition of (`index`, `sub`), at compile time; a build error if the EDS
/// does not have it.
const fn def(index: u16, sub: u8) -> &'static ObjectDef {
    let t = &generated::OBJECTS;
    let mut i = 0;
    while i < t.len() {
        if t[i].index == index && t[i].sub == sub {
            return &t[i];
        }
        i += 1;
    }
    panic!("safety_gateway.eds does not describe an entry the gateway uses")
}

/// The default of an unsigned entry, at compile time.
const fn unsigned(index: u16, sub: u8) -> u64 {
    match def(index, sub).default_value() {
        DefaultValue::Unsigned(v) => v,
        DefaultValue::Zero => 0,
        _ => panic!("safety_gateway.eds: a figure the gateway uses is not an unsigned number"),
    }
}

/// Heartbeat producer time (ms), the default of 0x1017.
pub const HEARTBEAT_MS: u16 = unsigned(comm::HEARTBEAT_PRODUCER, 0) as u16;
/// Cyclic refresh of every track state on the interlocking side (TPDO event timer, ms).
pub const REFRESH_MS: u16 = unsigned(0x1800, 5) as u16;
/// Default of 0x2001, the SCT of the field board's SRDO: no intact pair for this long makes
/// every track circuit occupied (3 of the field board's 100 ms cycles). A new value applies
/// from the next intact pair on.
pub const FIELD_TIMEOUT_MS: u16 = unsigned(FIELD_TIMEOUT, 0) as u16;

/// Field timeout (u16, ms, read-write).
pub const FIELD_TIMEOUT: u16 = index::FIELD_TIMEOUT;
/// TPDO images: sub *k* holds the encoded railway payload of track circuit *k*.
pub const IMAGE: u16 = index::STATE_CHANGE_IMAGES;
/// Bytes of one image: index, sub-index, one code byte, CRC.
pub const IMAGE_LEN: usize = def(IMAGE, 1).capacity as usize;
/// Mirrored track-circuit codes, sub *k* = track circuit *k* (the railway object index).
pub const TRACK_STATES: u16 = index::TRACK_CIRCUITS;
/// Their bitwise inverses, sub *k* = track circuit *k*: the inverted half of SRDO 1.
pub const TRACK_STATES_INVERTED: u16 = index::TRACK_CIRCUITS_INVERTED;
/// Refresh time of SRDO 1 (ms), the default of 0x1301 sub 2.
pub const SRDO_REFRESH_MS: u16 = unsigned(0x1301, 2) as u16;
/// SRVT of SRDO 1 (ms), the default of 0x1301 sub 3.
pub const SRDO_SRVT_MS: u8 = unsigned(0x1301, 3) as u8;
/// COB-ID of SRDO 1's normal frame (0x1301 sub 5): node 20's default, 0xFF + 2 × 20.
pub const SRDO_NORMAL: u16 = unsigned(0x1301, 5) as u16;

// The EDS agrees with the railway profile and the number of mirrors.
const _: () = {
    assert!(TRACK_STATES == objects::TRACK_CIRCUIT);
    assert!(unsigned(TRACK_STATES, 0) == TRACKS as u64);
    assert!(unsigned(IMAGE, 0) == TRACKS as u64);
    assert!(IMAGE_LEN == 6);
    assert!(unsigned(TRACK_STATES_INVERTED, 0) == TRACKS as u64);
    assert!(SRDO_NORMAL == 0xFF + 2 * crate::NODE_ID.raw() as u16);
    // The inverse of the power-on code (occupied) is the power-on inverse.
    assert!(unsigned(TRACK_STATES_INVERTED, 1) == !(unsigned(TRACK_STATES, 1) as u8) as u64);
};

/// The identity the gateway reports in 0x1018.
pub const VENDOR: u32 = unsigned(comm::IDENTITY, 1) as u32;
/// Product code (0x1018 sub 2).
pub const PRODUCT: u32 = unsigned(comm::IDENTITY, 2) as u32;
/// Device type (0x1000): a generic I/O profile device.
pub const DEVICE_TYPE: u32 = unsigned(comm::DEVICE_TYPE, 0) as u32;

/// The 29-bit identifier TPDO `track` uses by default: a state change on the gateway's I/O
/// port `track` (the EDS's 0x1800 + `track` − 1 sub 1 says the same; a test checks it).
pub const fn state_id(track: u8) -> duocan::Id {
    railway::id(RailFunction::StateChange, ADDRESS.with_port(track))
}

/// Every table of the gateway's dictionary, in load order.
pub static TABLES: [&[ObjectDef]; 1] = [&generated::OBJECTS];
