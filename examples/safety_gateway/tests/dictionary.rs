//! The dictionary generated at build time from `safety_gateway.eds` is the one the EDS
//! describes: entry by entry the dictionary a dynamic import of the same file builds, with the
//! railway identifiers the gateway's code uses and the stack's write hooks.

use duocan::eds::{difference, Description, ImportOptions};
use duocan::od::ObjectDictionary;
use duocan::{AbortCode, CobId};
use safety_gateway::dictionary::{self, Od, REFRESH_MS, TABLES};
use safety_gateway::{NODE_ID, TRACKS};

const EDS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/safety_gateway.eds");

fn generated() -> Od {
    let mut od = Od::new();
    od.load(NODE_ID.raw(), &TABLES).unwrap();
    od
}

#[test]
fn the_generated_dictionary_is_the_imported_one() {
    let eds = Description::read_with(EDS, &ImportOptions::strict()).unwrap();
    let imported = eds.dictionary(NODE_ID.raw());
    let od = generated();
    assert_eq!(od.len(), imported.len());
    assert_eq!(difference(&od, &imported), None);
}

#[test]
fn the_eds_holds_the_railway_identifiers_and_refresh_time() {
    let od = generated();
    for k in 1..=TRACKS {
        let comm = 0x1800 + k as u16 - 1;
        assert_eq!(
            od.get_value::<u32>(comm, 1),
            Ok(CobId::from_id(dictionary::state_id(k)).0),
            "TPDO {k}"
        );
        assert_eq!(od.get_value::<u16>(comm, 5), Ok(REFRESH_MS), "TPDO {k}");
    }
}

#[test]
fn the_stack_hooks_are_installed() {
    // 0x1019: 1 is reserved (CiA 301), in the generated dictionary as in the imported one.
    let mut od = generated();
    assert_eq!(od.write(0x1019, 0, &[1]), Err(AbortCode::VALUE_RANGE));
    assert_eq!(od.write(0x1019, 0, &[2]), Ok(()));
    let mut imported = Description::read(EDS).unwrap().dictionary(NODE_ID.raw());
    assert_eq!(imported.write(0x1019, 0, &[1]), Err(AbortCode::VALUE_RANGE));
}
