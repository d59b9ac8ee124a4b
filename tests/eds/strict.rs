//! One real-world mistake per file (`files/strict/`): strict mode refuses it with an error that
//! names the file, the line, the section and the key; lenient mode takes a value, warns about
//! it at the same place, and the value taken is the one asserted here.

use crate::path;
use duocan::eds::{Description, EdsErrorKind, ImportOptions, Value};
use duocan::od::DataType;

type Check = fn(&Description);

struct Case {
    file: &'static str,
    line: u32,
    section: Option<&'static str>,
    key: Option<&'static str>,
    kind: fn(&EdsErrorKind) -> bool,
    /// What lenient mode took.
    taken: Check,
}

fn default(d: &Description, index: u16) -> Option<Value> {
    d.entry_at(index, 0).unwrap().default.clone()
}

const CASES: &[Case] = &[
    Case {
        file: "duplicate_key.eds",
        line: 117,
        section: Some("2000"),
        key: Some("DefaultValue"),
        kind: |k| *k == EdsErrorKind::DuplicateKey,
        taken: |d| assert_eq!(default(d, 0x2000), Some(Value::Unsigned(2)), "the last one"),
    },
    Case {
        file: "duplicate_section.eds",
        line: 118,
        section: Some("2000"),
        key: None,
        kind: |k| *k == EdsErrorKind::DuplicateSection,
        taken: |d| {
            assert_eq!(
                d.entry_at(0x2000, 0).unwrap().high,
                Some(Value::Unsigned(10)),
                "merged"
            )
        },
    },
    Case {
        file: "sub_number.eds",
        line: 113,
        section: Some("2000"),
        key: Some("SubNumber"),
        kind: |k| {
            matches!(
                k,
                EdsErrorKind::CountMismatch {
                    stated: 3,
                    found: 2
                }
            )
        },
        taken: |d| assert_eq!(d.object_at(0x2000).unwrap().subs.len(), 2),
    },
    Case {
        file: "no_sub_zero.eds",
        line: 110,
        section: Some("2000"),
        key: None,
        kind: |k| *k == EdsErrorKind::NoSubZero,
        taken: |d| {
            let s0 = d.entry_at(0x2000, 0).unwrap();
            assert_eq!(
                (s0.data_type, s0.default.clone()),
                (DataType::Unsigned8, Some(Value::Unsigned(2)))
            );
        },
    },
    Case {
        file: "octal_digits.eds",
        line: 115,
        section: Some("2000"),
        key: Some("DefaultValue"),
        kind: |k| matches!(k, EdsErrorKind::OctalDigits { .. }),
        taken: |d| {
            assert_eq!(
                default(d, 0x2000),
                Some(Value::Unsigned(189)),
                "read as decimal"
            )
        },
    },
    Case {
        file: "bad_boolean.eds",
        line: 116,
        section: Some("2000"),
        key: Some("PDOMapping"),
        kind: |k| matches!(k, EdsErrorKind::BadValue { value, .. } if value == "yes"),
        taken: |d| assert!(d.entry_at(0x2000, 0).unwrap().pdo_mapping),
    },
    Case {
        file: "out_of_range.eds",
        line: 115,
        section: Some("2000"),
        key: Some("DefaultValue"),
        kind: |k| matches!(k, EdsErrorKind::OutOfRange { .. }),
        taken: |d| {
            assert_eq!(
                default(d, 0x2000),
                Some(Value::Unsigned(300 & 0xFF)),
                "wrapped"
            )
        },
    },
    Case {
        file: "outside_limits.eds",
        line: 115,
        section: Some("2000"),
        key: Some("DefaultValue"),
        kind: |k| matches!(k, EdsErrorKind::OutsideLimits { .. }),
        taken: |d| assert_eq!(default(d, 0x2000), Some(Value::Unsigned(5)), "as it is"),
    },
    Case {
        file: "unknown_access.eds",
        line: 114,
        section: Some("2000"),
        key: Some("AccessType"),
        kind: |k| matches!(k, EdsErrorKind::UnknownAccessType { value } if value == "readwrite"),
        taken: |d| {
            assert_eq!(
                d.entry_at(0x2000, 0).unwrap().access,
                duocan::eds::AccessType::Rw
            )
        },
    },
    Case {
        file: "unknown_type.eds",
        line: 113,
        section: Some("2000"),
        key: Some("DataType"),
        kind: |k| *k == EdsErrorKind::UnknownDataType { code: 0x40 },
        taken: |d| assert_eq!(d.entry_at(0x2000, 0).unwrap().data_type, DataType::Domain),
    },
    Case {
        file: "unlisted.eds",
        line: 118,
        section: Some("2001"),
        key: None,
        kind: |k| matches!(k, EdsErrorKind::ObjectList { index: 0x2001, .. }),
        taken: |d| assert!(d.object_at(0x2001).is_some(), "imported all the same"),
    },
    Case {
        file: "listed_missing.eds",
        line: 48,
        section: Some("ManufacturerObjects"),
        key: Some("2"),
        kind: |k| matches!(k, EdsErrorKind::ObjectList { index: 0x2001, .. }),
        taken: |d| assert!(d.object_at(0x2001).is_none()),
    },
    Case {
        file: "latin1.eds",
        line: 13,
        section: None,
        key: None,
        kind: |k| *k == EdsErrorKind::NotUtf8,
        taken: |d| assert_eq!(d.device_info.vendor_name, "Müller"),
    },
    Case {
        file: "missing_mandatory.eds",
        line: 0,
        section: None,
        key: None,
        kind: |k| *k == EdsErrorKind::MissingMandatory { index: 0x1001 },
        taken: |d| assert!(d.object_at(0x1001).is_none()),
    },
    Case {
        file: "orphan.eds",
        line: 109,
        section: Some("3000sub1"),
        key: None,
        kind: |k| *k == EdsErrorKind::Orphan,
        taken: |d| assert!(d.object_at(0x3000).is_none()),
    },
    Case {
        file: "hash_comment.eds",
        line: 111,
        section: Some("2000"),
        key: None,
        kind: |k| matches!(k, EdsErrorKind::Syntax { .. }),
        taken: |d| assert_eq!(d.entry_at(0x2000, 0).unwrap().name, "Entry 2000"),
    },
    Case {
        file: "missing_datatype.eds",
        line: 110,
        section: Some("2000"),
        key: Some("DataType"),
        kind: |k| *k == EdsErrorKind::MissingKey,
        taken: |d| assert_eq!(d.entry_at(0x2000, 0).unwrap().data_type, DataType::Domain),
    },
    Case {
        file: "comments_count.eds",
        line: 110,
        section: Some("Comments"),
        key: Some("Lines"),
        kind: |k| {
            matches!(
                k,
                EdsErrorKind::CountMismatch {
                    stated: 3,
                    found: 2
                }
            )
        },
        taken: |d| assert_eq!(d.comments, ["one", "two"]),
    },
    Case {
        file: "decimal_comma.eds",
        line: 115,
        section: Some("2000"),
        key: Some("DefaultValue"),
        kind: |k| matches!(k, EdsErrorKind::BadValue { .. }),
        taken: |d| assert_eq!(default(d, 0x2000), Some(Value::Real(1.5))),
    },
    Case {
        file: "compact_and_subnumber.eds",
        line: 110,
        section: Some("2000"),
        key: None,
        kind: |k| matches!(k, EdsErrorKind::Misplaced { .. }),
        taken: |d| {
            assert_eq!(
                d.object_at(0x2000).unwrap().subs.len(),
                3,
                "CompactSubObj=2"
            )
        },
    },
    Case {
        file: "name_too_long.eds",
        line: 111,
        section: Some("2000"),
        key: Some("ParameterName"),
        kind: |k| *k == EdsErrorKind::NameTooLong,
        taken: |d| assert_eq!(d.entry_at(0x2000, 0).unwrap().name, "N".repeat(255)),
    },
    Case {
        file: "commissioning_spelling.dcf",
        line: 109,
        section: Some("DeviceCommissioning"),
        key: None,
        kind: |k| matches!(k, EdsErrorKind::Misplaced { .. }),
        taken: |d| assert_eq!(d.commissioning.as_ref().unwrap().node_id, Some(5)),
    },
    Case {
        file: "bad_value.eds",
        line: 115,
        section: Some("2000"),
        key: Some("DefaultValue"),
        kind: |k| matches!(k, EdsErrorKind::BadValue { value, .. } if value == "abc"),
        taken: |d| assert_eq!(default(d, 0x2000), None, "no default: zero"),
    },
];

#[test]
fn every_mistake_is_a_strict_error_naming_file_line_section_and_key() {
    for c in CASES {
        let p = path(&format!("strict/{}", c.file));
        let e = Description::read_with(&p, &ImportOptions::strict()).expect_err(c.file);
        assert_eq!(e.at.file, p.display().to_string(), "{}", c.file);
        assert_eq!(
            (e.at.line, e.at.section.as_deref(), e.at.key.as_deref()),
            (c.line, c.section, c.key),
            "{}: {e}",
            c.file
        );
        assert!((c.kind)(&e.kind), "{}: {e}", c.file);
        // The message says all of it.
        let msg = e.to_string();
        assert!(msg.starts_with(&p.display().to_string()), "{msg}");
        if let Some(k) = c.key {
            assert!(msg.contains(k), "{msg}");
        }
    }
}

#[test]
fn every_mistake_is_a_lenient_warning_at_the_same_place_naming_the_value_taken() {
    for c in CASES {
        let p = path(&format!("strict/{}", c.file));
        let d = Description::read(&p).unwrap_or_else(|e| panic!("{}: {e}", c.file));
        let w = d
            .warnings
            .first()
            .unwrap_or_else(|| panic!("{}: no warning", c.file));
        assert_eq!(
            (w.at.line, w.at.section.as_deref(), w.at.key.as_deref()),
            (c.line, c.section, c.key),
            "{}: {w}",
            c.file
        );
        assert!((c.kind)(&w.kind), "{}: {w}", c.file);
        assert!(!w.taken.is_empty());
        assert!(w.to_string().contains("taken: "), "{w}");
        (c.taken)(&d);
    }
}

#[test]
fn the_corpus_of_mistakes_is_complete() {
    let mut files: Vec<String> = std::fs::read_dir(path("strict"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    files.sort();
    let mut cases: Vec<String> = CASES.iter().map(|c| c.file.to_string()).collect();
    cases.sort();
    assert_eq!(files, cases, "every file in files/strict has its case");
}
