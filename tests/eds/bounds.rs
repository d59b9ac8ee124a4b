//! The caps that bound memory on any input, a generated 2,000-entry file, and mutated files
//! that import or fail but never panic.

use crate::generate;
use duocan::eds::{
    difference, export_eds, Description, EdsErrorKind, ExportOptions, ImportOptions, MAX_ENTRIES,
    MAX_FILE_BYTES, MAX_KEYS, MAX_LINE_BYTES, MAX_VALUE_BYTES, MAX_WARNINGS,
};
use duocan::od::ObjectDictionary;
use proptest::prelude::*;

fn parse(text: &[u8], strict: bool) -> Result<Description, duocan::eds::EdsError> {
    Description::parse(text, "t.eds", &ImportOptions::default().with_strict(strict))
}

#[test]
fn a_generated_file_of_2000_entries_imports_strictly() {
    let text = generate::eds(2000);
    let d = parse(text.as_bytes(), true).unwrap();
    assert_eq!(d.len(), 2000);
    let od = d.dictionary(9);
    assert_eq!(od.len(), 2000);
    let e = d.entry("field 3 of 13").unwrap();
    assert_eq!((e.index, e.sub), (0x200D, 3));
    assert_eq!(
        od.get_value::<u32>(0x2002, 0),
        Ok(0x4009),
        "$NODEID+0x4000 on node 9"
    );
    let back = parse(
        export_eds(&od, &ExportOptions::default())
            .unwrap()
            .as_bytes(),
        true,
    )
    .unwrap();
    assert_eq!(difference(&od, &back.dictionary(9)), None);
}

#[test]
fn a_file_over_the_size_cap_is_refused_unread() {
    let big = vec![b';'; MAX_FILE_BYTES + 1];
    for strict in [false, true] {
        assert_eq!(
            parse(&big, strict).unwrap_err().kind,
            EdsErrorKind::FileTooLarge {
                max: MAX_FILE_BYTES
            }
        );
    }
    let path = std::env::temp_dir().join(format!("duocan-big-{}.eds", std::process::id()));
    std::fs::write(&path, &big).unwrap();
    let e = Description::read(&path).unwrap_err();
    std::fs::remove_file(&path).unwrap();
    assert_eq!(
        e.kind,
        EdsErrorKind::FileTooLarge {
            max: MAX_FILE_BYTES
        }
    );
    assert_eq!(e.at.file, path.display().to_string());
    let missing = Description::read("/nonexistent/device.eds").unwrap_err();
    assert!(matches!(missing.kind, EdsErrorKind::Io { .. }), "{missing}");
    assert!(missing
        .to_string()
        .starts_with("/nonexistent/device.eds: cannot read the file"));
}

#[test]
fn a_line_over_the_cap_is_refused_with_its_number() {
    let text = format!("[FileInfo]\nDescription={}\n", "x".repeat(MAX_LINE_BYTES));
    let e = parse(text.as_bytes(), false).unwrap_err();
    assert_eq!(
        (e.kind, e.at.line),
        (
            EdsErrorKind::LineTooLong {
                max: MAX_LINE_BYTES
            },
            2
        )
    );
}

#[test]
fn sections_and_keys_are_capped() {
    let text = "[Comments]\n".to_string() + &"a=1\n".repeat(MAX_KEYS);
    let e = parse(text.as_bytes(), false).unwrap_err();
    assert_eq!(e.kind, EdsErrorKind::TooManyKeys { max: MAX_KEYS });
    assert_eq!(e.at.line as usize, MAX_KEYS + 1);
}

/// `n` compact arrays of 254 entries each, with `default` as their default.
fn compact_arrays(n: usize, t: u16, default: &str) -> String {
    let mut s = String::from("[ManufacturerObjects]\n");
    s += &format!("SupportedObjects={n}\n");
    for i in 0..n {
        s += &format!("{}=0x{:04X}\n", i + 1, 0x2000 + i);
    }
    for i in 0..n {
        s += &format!(
            "[{:04X}]\nParameterName=A\nObjectType=8\nCompactSubObj=254\nDataType={t}\nAccessType=rw\nDefaultValue={default}\n",
            0x2000 + i
        );
    }
    s
}

#[test]
fn implied_entries_count_against_the_entry_cap() {
    // 300 arrays of 255 entries: a 40 KiB file that would describe 76,500 entries.
    let text = compact_arrays(300, 5, "0");
    assert!(text.len() < 64 << 10);
    let e = parse(text.as_bytes(), false).unwrap_err();
    assert_eq!(e.kind, EdsErrorKind::TooManyEntries { max: MAX_ENTRIES });
}

#[test]
fn repeated_values_count_against_the_value_cap() {
    // A 4 KiB domain default repeated in 254 entries, 40 times: 40 MiB from 330 KiB.
    let text = compact_arrays(40, 0xF, &"AB".repeat(4000));
    let e = parse(text.as_bytes(), false).unwrap_err();
    assert_eq!(
        e.kind,
        EdsErrorKind::ValuesTooLarge {
            max: MAX_VALUE_BYTES
        }
    );
}

#[test]
fn warnings_beyond_the_cap_are_counted() {
    let text = "[FileInfo]\n".to_string() + &"# not a comment\n".repeat(MAX_WARNINGS + 500);
    let d = parse(text.as_bytes(), false).unwrap();
    assert_eq!(d.warnings.len(), MAX_WARNINGS);
    // The file's own mistakes, plus the missing sections and objects of an almost empty file.
    assert!(d.warnings_dropped >= 500, "{}", d.warnings_dropped);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    /// Corpus files with bytes replaced, inserted and cut: an import or an error, never a
    /// panic; what imports builds a dictionary.
    #[test]
    fn mutated_files_never_panic(
        file in 0usize..6,
        edits in proptest::collection::vec((any::<prop::sample::Index>(), any::<u8>(), 0u8..3), 1..20),
    ) {
        let names = ["nodeid.eds", "compact_subobj.eds", "commissioning.dcf", "data_types.eds", "compact_pdo.eds", "limits.eds"];
        let mut bytes = std::fs::read(crate::path(names[file])).unwrap();
        for (at, b, op) in edits {
            let i = at.index(bytes.len().max(1)).min(bytes.len());
            match op {
                0 if i < bytes.len() => bytes[i] = b,
                1 => bytes.insert(i, b),
                _ => bytes.truncate(i.max(bytes.len() / 2)),
            }
        }
        for strict in [false, true] {
            if let Ok(d) = parse(&bytes, strict) {
                let od = d.dictionary(1);
                prop_assert_eq!(od.len(), d.entries().filter(|s| d.object_at(s.index).unwrap().code.object_type().is_some()).count());
            }
        }
    }
}

/// A small file can describe a large dictionary (`CompactPDO` with 512 PDOs, each with 64
/// mapping entries): its export is megabytes, and still within the bounds, so it imports again
/// (found by the `eds` fuzz target when the bounds were 4 MiB and 2^18 keys).
#[test]
fn the_export_of_a_description_at_the_bounds_imports_again() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/fuzz/seeds/eds/compact_pdo_512.eds"
    );
    let d = Description::parse(
        &std::fs::read(path).unwrap(),
        "compact_pdo_512.eds",
        &duocan::eds::ImportOptions::lenient(),
    )
    .unwrap();
    let od = d.dictionary(5);
    let text = duocan::eds::export_dcf(&od, &duocan::eds::ExportOptions::default()).unwrap();
    assert!(text.len() > 4 << 20, "{} bytes", text.len());
    assert!(text.len() < MAX_FILE_BYTES);
    let back = parse(text.as_bytes(), false).unwrap();
    assert_eq!(back.entries().count(), d.entries().count());
}
