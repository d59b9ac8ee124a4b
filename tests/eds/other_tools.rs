//! Descriptions written by other tools and by hand: what other readers accept is read the same
//! way (and strict mode keeps refusing what is really wrong), what is ambiguous is read as lely
//! reads it with a warning, and what is no description at all is an error.

use crate::path;
use crate::warnings::traced;
use duocan::eds::{export_eds, Description, EdsErrorKind, ExportOptions, ImportOptions, Value};
use duocan::od::{comm, Access, DataType, DynamicDictionary, Limit, ObjectDef};

/// A valid EDS whose only manufacturer object is `[2000]` as given (`section`: its keys).
fn eds_with(section: &str) -> String {
    let base = std::fs::read_to_string(path("access_types.eds")).unwrap();
    let head = &base[..base.find("[ManufacturerObjects]").unwrap()];
    let mandatory = &base[base.find("[1000]").unwrap()..base.find("[2000]").unwrap()];
    format!(
        "{head}[ManufacturerObjects]\nSupportedObjects=1\n1=0x2000\n\n{mandatory}[2000]\n{section}\n"
    )
}

fn strict(text: &str) -> Result<Description, duocan::eds::EdsError> {
    Description::parse(text.as_bytes(), "other.eds", &ImportOptions::strict())
}

fn lenient(text: &str) -> Description {
    Description::parse(text.as_bytes(), "other.eds", &ImportOptions::lenient())
        .unwrap_or_else(|e| panic!("{e}\n{text}"))
}

const U16_ENTRY: &str = "ParameterName=Speed\nObjectType=0x7\nDataType=0x0006\nAccessType=rw";
const TEXT_ENTRY: &str = "ParameterName=Label\nObjectType=0x7\nDataType=0x0009\nAccessType=rw";

#[test]
fn the_base_file_is_clean() {
    let d = strict(&eds_with(&format!(
        "{U16_ENTRY}\nDefaultValue=5\nPDOMapping=0"
    )))
    .unwrap();
    assert!(d.warnings.is_empty());
    assert_eq!(
        d.entry_at(0x2000, 0).unwrap().default,
        Some(Value::Unsigned(5))
    );
}

#[test]
fn an_entry_with_limits_and_no_default_exports_a_file_strict_mode_takes() {
    let mut od = comm::standard_dictionary(5, comm::Identity::default());
    od.insert_all(&[ObjectDef::new(0x2000, 0, DataType::Unsigned16)
        .access(Access::Rw)
        .limits(Limit::Unsigned(10), Limit::Unsigned(20))
        .named("Speed")])
        .unwrap();
    let text = export_eds(&od, &ExportOptions::default()).unwrap();
    let section = &text[text.find("[2000]").unwrap()..];
    let section = &section[..section.find("\n\n").unwrap_or(section.len())];
    assert!(!section.contains("DefaultValue"), "{section}");
    let d = strict(&text).unwrap_or_else(|e| panic!("{e}\n{section}"));
    let e = d.entry_at(0x2000, 0).unwrap();
    assert_eq!(
        (e.default.clone(), e.low.clone()),
        (None, Some(Value::Unsigned(10)))
    );
    // Zero within the limits (or no limits): written as before.
    let mut od: DynamicDictionary = comm::standard_dictionary(5, comm::Identity::default());
    od.insert_all(&[ObjectDef::new(0x2000, 0, DataType::Integer16)
        .limits(Limit::Signed(-10), Limit::Signed(10))
        .named("Offset")])
        .unwrap();
    let text = export_eds(&od, &ExportOptions::default()).unwrap();
    assert!(text[text.find("[2000]").unwrap()..].contains("DefaultValue=0\n"));
    strict(&text).unwrap();
}

#[test]
fn pdo_mapping_written_in_hex_is_a_boolean() {
    for (text, mappable) in [("0x0", false), ("0x1", true), ("00", false), ("0x01", true)] {
        let d = strict(&eds_with(&format!(
            "{U16_ENTRY}\nDefaultValue=5\nPDOMapping={text}"
        )))
        .unwrap_or_else(|e| panic!("PDOMapping={text}: {e}"));
        assert_eq!(
            d.entry_at(0x2000, 0).unwrap().pdo_mapping,
            mappable,
            "{text}"
        );
    }
    // A number that is no boolean stays a problem.
    let e = strict(&eds_with(&format!(
        "{U16_ENTRY}\nDefaultValue=5\nPDOMapping=2"
    )))
    .unwrap_err();
    assert!(matches!(e.kind, EdsErrorKind::BadValue { .. }), "{e}");
}

#[test]
fn an_empty_limit_on_a_string_is_none() {
    let d = strict(&eds_with(&format!(
        "{TEXT_ENTRY}\nDefaultValue=left\nPDOMapping=0\nLowLimit=\nHighLimit="
    )))
    .unwrap();
    let e = d.entry_at(0x2000, 0).unwrap();
    assert_eq!((e.low.clone(), e.high.clone()), (None, None));
    // A limit that says something is still misplaced on a string.
    let e = strict(&eds_with(&format!(
        "{TEXT_ENTRY}\nDefaultValue=left\nPDOMapping=0\nLowLimit=3"
    )))
    .unwrap_err();
    assert!(matches!(e.kind, EdsErrorKind::Misplaced { .. }), "{e}");
}

#[test]
fn an_access_type_with_a_trailing_semicolon_is_read_as_written_with_a_warning() {
    let text = eds_with("ParameterName=Speed\nObjectType=0x7\nDataType=0x0006\nAccessType=rw;\nDefaultValue=5\nPDOMapping=0");
    let d = lenient(&text);
    assert_eq!(
        d.entry_at(0x2000, 0).unwrap().access,
        duocan::eds::AccessType::Rw
    );
    assert_eq!(d.warnings.len(), 1, "{:?}", d.warnings);
    assert_eq!(d.warnings[0].at.key.as_deref(), Some("AccessType"));
    assert!(strict(&text).is_err(), "strict mode names it");
}

#[test]
fn an_empty_parameter_value_over_a_default_is_the_empty_string_and_the_log_says_so() {
    let text = eds_with(&format!(
        "{TEXT_ENTRY}\nDefaultValue=left\nPDOMapping=0\nParameterValue="
    ));
    let (d, seen) = traced(|| strict(&text).unwrap());
    let e = d.entry_at(0x2000, 0).unwrap();
    assert_eq!(
        e.value,
        Some(Value::Bytes(vec![])),
        "what duocan's export of \"\" writes"
    );
    assert_eq!(seen.len(), 1, "{seen:?}");
    assert!(
        seen[0]
            .2
            .contains("[2000] ParameterValue: empty over a non-empty default")
            && seen[0].2.contains("lely keeps the default"),
        "{seen:?}"
    );
    // Over an empty default there is no question.
    let (_, seen) = traced(|| {
        strict(&eds_with(&format!(
            "{TEXT_ENTRY}\nDefaultValue=\nPDOMapping=0\nParameterValue="
        )))
        .unwrap()
    });
    assert!(seen.is_empty(), "{seen:?}");
}

#[test]
fn a_dcf_for_node_0_has_no_node_id_and_says_so() {
    let base = std::fs::read_to_string(path("commissioning.dcf")).unwrap();
    let line = base.lines().find(|l| l.starts_with("NodeID=")).unwrap();
    let text = base.replace(line, "NodeID=0");
    let d = lenient(&text);
    assert_eq!(d.commissioning.as_ref().unwrap().node_id, None);
    assert!(
        d.warnings
            .iter()
            .any(|w| w.at.key.as_deref() == Some("NodeID")),
        "{:?}",
        d.warnings
    );
    let e = strict(&text).unwrap_err();
    assert!(matches!(e.kind, EdsErrorKind::OutOfRange { .. }), "{e}");
}

#[test]
fn a_file_that_is_no_description_is_an_error_in_both_modes() {
    let noise: Vec<u8> = (0..4096u32)
        .map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8)
        .collect();
    for bytes in [&noise[..], b"hello\nworld\n", b"[Section]\nKey=1\n", b""] {
        let e = Description::parse(bytes, "noise.bin", &ImportOptions::lenient()).unwrap_err();
        assert_eq!(e.kind, EdsErrorKind::NotADescription, "{e}");
        assert!(Description::parse(bytes, "noise.bin", &ImportOptions::strict()).is_err());
    }
}
