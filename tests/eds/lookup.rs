//! Name lookup: addresses and names, any case, ambiguity reported with its candidates; in a
//! description and in any dictionary.

use crate::clean;
use duocan::eds::{find, LookupErrorKind};
use duocan::od::{comm, Access, DynamicDictionary, ObjectDef};

#[test]
fn addresses_and_names_without_regard_to_case() {
    let d = clean("commissioning.dcf");
    for name in [
        "Producer heartbeat time",
        "producer HEARTBEAT time",
        "0x1017",
        "1017",
        "1017sub0",
        "0x1017SUB0",
        "Heartbeat of the left turnout",
    ] {
        let e = d.entry(name).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!((e.index, e.sub), (0x1017, 0), "{name}");
    }
    for name in [
        "0x1018sub1",
        "1018sub1",
        "1018SUB0x1",
        "vendor-id",
        "Identity object.Vendor-ID",
    ] {
        let e = d.entry(name).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!((e.index, e.sub), (0x1018, 1), "{name}");
    }
    assert_eq!(d.object("Identity object").unwrap().index, 0x1018);
    assert_eq!(
        d.object("vendor-ID").unwrap().index,
        0x1018,
        "an entry's name finds its object"
    );
    assert_eq!(d.object("0x2000").unwrap().name, "Point position");
}

#[test]
fn an_array_or_record_is_not_an_entry() {
    let d = clean("commissioning.dcf");
    for name in ["Identity object", "0x1018"] {
        let e = d.entry(name).unwrap_err();
        assert_eq!(
            e.kind,
            LookupErrorKind::NotAnEntry { index: 0x1018 },
            "{name}"
        );
        assert!(e.to_string().contains("1018sub1"), "{e}");
    }
}

#[test]
fn a_shared_name_is_ambiguous_and_lists_the_candidates() {
    let d = clean("commissioning.dcf");
    let e = d.entry("highest SUB-INDEX supported").unwrap_err();
    assert_eq!(
        e.kind,
        LookupErrorKind::Ambiguous {
            candidates: vec![
                "0x1018sub0 (Identity object / Highest sub-index supported)".into(),
                "0x1800sub0 (TPDO communication parameter / Highest sub-index supported)".into(),
            ]
        }
    );
    assert_eq!(
        e.to_string(),
        "\"highest SUB-INDEX supported\" is ambiguous; it names 0x1018sub0 (Identity object / Highest sub-index supported), 0x1800sub0 (TPDO communication parameter / Highest sub-index supported)"
    );
    // Named within its object, it is one.
    let s = d
        .entry("TPDO communication parameter.Highest sub-index supported")
        .unwrap();
    assert_eq!((s.index, s.sub), (0x1800, 0));
}

#[test]
fn unknown_names_and_addresses() {
    let d = clean("commissioning.dcf");
    for name in ["Nothing like it", "0x9999", "1017sub1", "1018sub100", ""] {
        assert_eq!(
            d.entry(name).unwrap_err().kind,
            LookupErrorKind::NotFound,
            "{name:?}"
        );
    }
}

#[test]
fn names_in_a_dictionary() {
    let od = comm::standard_dictionary(5, comm::Identity::default());
    assert_eq!(find(&od, "Producer heartbeat time"), Ok((0x1017, 0)));
    assert_eq!(find(&od, "0x1017"), Ok((0x1017, 0)));
    assert_eq!(find(&od, "1018sub2"), Ok((0x1018, 2)));
    assert_eq!(find(&od, "product CODE"), Ok((0x1018, 2)));
    assert_eq!(find(&od, "Identity object.Serial number"), Ok((0x1018, 4)));
    assert_eq!(find(&od, "Save all parameters"), Ok((0x1010, 1)));
    // Every entry of 0x1016 carries the array's name: the name is the array's.
    assert_eq!(
        find(&od, "Consumer heartbeat time").unwrap_err().kind,
        LookupErrorKind::NotAnEntry { index: 0x1016 }
    );
    assert_eq!(find(&od, "0x1016sub7F"), Ok((0x1016, 0x7F)));
    assert_eq!(
        find(&od, "Nothing").unwrap_err().kind,
        LookupErrorKind::NotFound
    );
}

#[test]
fn a_shared_name_in_a_dictionary_is_ambiguous() {
    let mut od = DynamicDictionary::new(1);
    od.insert(ObjectDef::u8(0x2000, 0, Access::Rw, 0).named("Speed"))
        .unwrap();
    od.insert(ObjectDef::u8(0x2100, 0, Access::Rw, 0).named("speed"))
        .unwrap();
    od.insert_owned(ObjectDef::u8(0x2200, 0, Access::Rw, 0), "Torque", None)
        .unwrap();
    assert_eq!(
        find(&od, "SPEED").unwrap_err().kind,
        LookupErrorKind::Ambiguous {
            candidates: vec!["0x2000sub0 (Speed)".into(), "0x2100sub0 (speed)".into()]
        }
    );
    assert_eq!(
        find(&od, "torque"),
        Ok((0x2200, 0)),
        "a name held by the dictionary"
    );
}
