//! Device descriptions (EDS/DCF): any bytes through the importer, lenient and strict. Never a
//! panic; a file strict mode accepts, lenient mode reads the same without a warning. What
//! imports builds a node's dictionary, whose export as an EDS (its defaults) and as a DCF (its
//! values too) imports again as the same dictionary (warning only of what the first file got wrong and export keeps: missing
//! mandatory objects, values outside their limits). What imports also configures a slave
//! (the master's configuration manager): every write names a writable entry of the file, and
//! a PDO's mapping entries are written only after its mapping count was set to 0; and it
//! generates a static dictionary's source with one definition per entry.
#![no_main]

use duocan::eds::codegen::{self, CodegenOptions};
use duocan::eds::{
    difference, export_dcf, export_eds, AccessType, Description, EdsErrorKind, ExportOptions,
    ImportOptions,
};
use duocan::master::{ConfigStep, SlaveConfig};
use duocan::od::ObjectDictionary;
use duocan::NodeId;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let strict = Description::parse(data, "fuzz.eds", &ImportOptions::strict());
    let lenient = Description::parse(data, "fuzz.eds", &ImportOptions::lenient());
    if let Ok(s) = &strict {
        assert_eq!(lenient.as_ref().ok(), Some(s), "strict accepted what lenient changed");
    }
    let Ok(d) = lenient else { return };
    let cfg = SlaveConfig::from_dcf(NodeId::must(5), &d);
    let mut zeroed = std::collections::BTreeSet::new();
    for step in &cfg.steps {
        let ConfigStep::Write { index, sub, data } = step else {
            panic!("a DCF gives writes only: {step:?}");
        };
        let e = d
            .entry_at(*index, *sub)
            .expect("a write names an entry of the file");
        assert!(
            !matches!(e.access, AccessType::Ro | AccessType::Const),
            "{index:04X} {sub}"
        );
        if (0x1600..=0x17FF).contains(index) || (0x1A00..=0x1BFF).contains(index) {
            if *sub == 0 && data.iter().all(|b| *b == 0) {
                zeroed.insert(*index);
            }
            assert!(
                zeroed.contains(index),
                "mapping {index:04X} written while its count is not 0"
            );
        }
    }
    let od = d.dictionary(5);
    assert!(od.len() <= duocan::eds::MAX_ENTRIES);
    // What imports generates a static table of the same entries, or names the limit that
    // depends on the node-ID.
    match codegen::generate(&d, &CodegenOptions::default()) {
        Ok(src) => assert_eq!(src.matches("\n    ObjectDef::new(").count(), od.len()),
        Err(e) => assert!(matches!(e.kind, EdsErrorKind::NotGenerated { .. }), "{e}"),
    }
    // An EDS carries no values: its dictionary is the defaults.
    let mut defaults = d.dictionary(5);
    defaults.reset_range(0..=0xFFFF);
    for dcf in [false, true] {
        let od = if dcf { &od } else { &defaults };
        let opts = ExportOptions::default();
        let text = if dcf {
            export_dcf(od, &opts)
        } else {
            export_eds(od, &opts)
        }
        .unwrap_or_else(|e| panic!("an imported dictionary exports: {e}"));
        let back = Description::parse(text.as_bytes(), "exported.eds", &ImportOptions::lenient())
            .unwrap_or_else(|e| panic!("an export imports: {e}\n{text}"));
        for w in &back.warnings {
            assert!(
                matches!(
                    w.kind,
                    EdsErrorKind::MissingMandatory { .. } | EdsErrorKind::OutsideLimits { .. }
                ),
                "{w}\n{text}"
            );
        }
        if let Some(diff) = difference(od, &back.dictionary(5)) {
            panic!("{diff}\n{text}");
        }
    }
});
