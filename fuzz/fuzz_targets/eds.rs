//! Device descriptions (EDS/DCF): any bytes through the importer, lenient and strict. Never a
//! panic; a file strict mode accepts, lenient mode reads the same without a warning. What
//! imports builds a node's dictionary, whose export as an EDS (its defaults) and as a DCF (its
//! values too) imports again as the same dictionary (warning only of what the first file got wrong and export keeps: missing
//! mandatory objects, values outside their limits).
#![no_main]

use duocan::eds::{
    difference, export_dcf, export_eds, Description, EdsErrorKind, ExportOptions, ImportOptions,
};
use duocan::od::ObjectDictionary;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let strict = Description::parse(data, "fuzz.eds", &ImportOptions::strict());
    let lenient = Description::parse(data, "fuzz.eds", &ImportOptions::lenient());
    if let Ok(s) = &strict {
        assert_eq!(lenient.as_ref().ok(), Some(s), "strict accepted what lenient changed");
    }
    let Ok(d) = lenient else { return };
    let od = d.dictionary(5);
    assert!(od.len() <= duocan::eds::MAX_ENTRIES);
    // An EDS carries no values: its dictionary is the defaults.
    let mut defaults = d.dictionary(5);
    defaults.reset_range(0..=0xFFFF);
    for dcf in [false, true] {
        let od = if dcf { &od } else { &defaults };
        let opts = ExportOptions::default();
        let text = if dcf { export_dcf(od, &opts) } else { export_eds(od, &opts) }
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
