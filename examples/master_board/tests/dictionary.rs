//! The firmware master's static dictionary: it fits the room it is given, and every entry it
//! has is, definition and value, what the host's run-time master dictionary has.

use duocan::master::objects;
use duocan::od::{comm, ObjectDictionary};
use master_board::dictionary::{self, Od, CONSUMERS, ENTRIES, OD_BYTES};

#[test]
fn the_tables_fit_the_dictionary_and_match_the_run_time_master_dictionary() {
    let mut od = Box::new(Od::new());
    dictionary::load(&mut od, 2).expect("the tables fit");
    assert_eq!(od.len(), ENTRIES);
    // The value arena is sized to what the tables use, with little to spare.
    let used = od.storage_used();
    assert!(
        used <= OD_BYTES && OD_BYTES - used < 256,
        "{used} of {OD_BYTES}"
    );

    let host = objects::master_dictionary(2, comm::Identity::default());
    let mut compared = 0;
    od.for_each(&mut |e| {
        let (index, sub) = (e.def.index, e.def.sub);
        // By design the board's own: its identity, and a consumer table of 15 entries.
        if matches!(
            index,
            comm::DEVICE_TYPE | comm::IDENTITY | comm::HEARTBEAT_CONSUMER
        ) {
            return;
        }
        let h = host
            .get(index, sub)
            .unwrap_or_else(|_| panic!("{index:#06X} sub {sub} is not in the host's dictionary"));
        // The same definition, write hook included (its address).
        assert_eq!(
            format!("{:?}", e.def),
            format!("{:?}", h.def),
            "{index:#06X} sub {sub}"
        );
        assert_eq!(e.data, h.data, "{index:#06X} sub {sub}");
        compared += 1;
    });
    assert_eq!(compared, ENTRIES - 6 - CONSUMERS);
    // Every node-indexed array is whole: the master refuses one that stops short of 127.
    for index in [
        objects::SLAVE_ASSIGNMENT,
        objects::DEVICE_TYPE_ID,
        objects::VENDOR_ID,
        objects::PRODUCT_CODE,
        objects::REVISION_NUMBER,
        objects::SERIAL_NUMBER,
    ] {
        assert!(
            (0..=127).all(|sub| od.get(index, sub).is_ok()),
            "{index:#06X}"
        );
    }
    assert!(od.get(objects::REQUEST_NMT, objects::REQUEST_ALL).is_ok());
}
