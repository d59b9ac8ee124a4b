//! Build-time generation: the static dictionary generated from a corpus file is, entry by
//! entry, the one imported dynamically from the same file; the generated sources are kept in
//! `generated/` (compiled here, so they must compile) and must be what the generator writes
//! today (`DUOCAN_BLESS=1` rewrites them); a bad file is an error naming where.

use crate::path;
use duocan::eds::codegen::{self, CodegenOptions};
use duocan::eds::{difference, Description, EdsErrorKind, ImportOptions};
use duocan::od::{ObjectDictionary, StaticDictionary};
use std::path::PathBuf;

/// Each generated source, as a module, with the corpus file it comes from.
macro_rules! generated {
    ($($module:ident = $file:literal;)*) => {
        $(mod $module {
            include!(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/eds/generated/", stringify!($module), ".rs"));
        })*
        const FIXTURES: &[(&str, &str)] = &[$((stringify!($module), $file)),*];
    };
}

generated! {
    data_types = "data_types.eds";
    limits = "limits.eds";
    nodeid = "nodeid.eds";
    compact_subobj = "compact_subobj.eds";
    compact_pdo = "compact_pdo.eds";
    access_types = "access_types.eds";
    commissioning = "commissioning.dcf";
}

fn fixture(module: &str) -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/eds/generated"))
        .join(format!("{module}.rs"))
}

#[test]
fn generated_sources_are_what_the_generator_writes() {
    let bless = std::env::var_os("DUOCAN_BLESS").is_some();
    for (module, file) in FIXTURES {
        let out =
            std::env::temp_dir().join(format!("duocan-codegen-{}-{module}.rs", std::process::id()));
        let g = codegen::generate_file(path(file), &out, &CodegenOptions::default())
            .unwrap_or_else(|e| panic!("{file}: {e}"));
        assert!(g.warnings.is_empty(), "strict: no warnings");
        assert_eq!(std::fs::read_to_string(&out).unwrap(), g.source);
        let _ = std::fs::remove_file(&out);
        if bless {
            std::fs::write(fixture(module), &g.source).unwrap();
        }
        let kept = std::fs::read_to_string(fixture(module)).unwrap();
        assert!(
            kept == g.source,
            "{module}.rs is stale: run with DUOCAN_BLESS=1"
        );
    }
}

/// Loads a generated table into a static dictionary of node `node_id`.
macro_rules! load {
    ($module:ident, $node:expr) => {{
        let mut od =
            StaticDictionary::<{ $module::ENTRY_CAPACITY }, { $module::VALUE_BYTES }>::new();
        od.load($node, &[&$module::OBJECTS]).unwrap();
        assert_eq!(od.len(), $module::ENTRIES);
        assert_eq!(od.storage_used(), $module::VALUE_BYTES);
        od
    }};
}

#[test]
fn generated_dictionary_equals_the_imported_one() {
    // Index, sub-index, object and data type, access, PDO mapping, capacity, default (on two
    // node-IDs), limits, name and value: `difference` compares them all.
    let check = |od: &dyn ObjectDictionary, file: &str, node: u8| {
        let imported = crate::read(file).dictionary(node);
        assert_eq!(imported.len(), od.len(), "{file}");
        assert_eq!(difference(od, &imported), None, "{file}");
    };
    check(&load!(data_types, 5), "data_types.eds", 5);
    check(&load!(limits, 5), "limits.eds", 5);
    check(&load!(nodeid, 9), "nodeid.eds", 9);
    check(&load!(compact_subobj, 5), "compact_subobj.eds", 5);
    check(&load!(compact_pdo, 5), "compact_pdo.eds", 5);
    check(&load!(access_types, 5), "access_types.eds", 5);
}

#[test]
fn a_dcf_configured_value_is_the_generated_default() {
    let od = load!(commissioning, 5);
    let d = crate::read("commissioning.dcf");
    let imported = d.dictionary(5);
    assert!(
        d.parameter_values().count() > 0,
        "the DCF configures something"
    );
    let mut seen = 0;
    od.for_each(&mut |e| {
        let i = imported.get(e.def.index, e.def.sub).unwrap();
        assert_eq!(e.data, i.data, "{:#06x}sub{}", e.def.index, e.def.sub);
        seen += 1;
    });
    assert_eq!(seen, imported.len());
}

#[test]
fn a_bad_file_is_an_error_naming_file_line_section_and_key() {
    let out = std::env::temp_dir().join(format!("duocan-codegen-bad-{}.rs", std::process::id()));
    let bad = path("strict/unknown_access.eds");
    let e = codegen::generate_file(&bad, &out, &CodegenOptions::default()).unwrap_err();
    assert_eq!(
        (e.at.line, e.at.section.as_deref(), e.at.key.as_deref()),
        (114, Some("2000"), Some("AccessType"))
    );
    assert!(
        e.to_string()
            .starts_with(&format!("{}:114: [2000] AccessType: ", bad.display())),
        "{e}"
    );
    assert!(!out.exists(), "nothing written");
    // Lenient, the same file generates, with the warning returned.
    let lenient = CodegenOptions::default().with_import(ImportOptions::lenient());
    let g = codegen::generate_file(&bad, &out, &lenient).unwrap();
    assert_eq!(g.warnings.len(), 1);
    assert_eq!(g.warnings[0].at.line, 114);
    std::fs::remove_file(&out).unwrap();
}

#[test]
fn hooks_are_installed_and_must_name_an_entry() {
    let d = Description::read_with(path("data_types.eds"), &ImportOptions::strict()).unwrap();
    let opts = CodegenOptions::default().with_hook(0x2001, 0, "crate::hooks::check");
    let src = codegen::generate(&d, &opts).unwrap();
    assert_eq!(src.matches(".hook(crate::hooks::check)").count(), 1);
    let e = codegen::generate(&d, &opts.with_hook(0x2FFF, 3, "crate::hooks::none")).unwrap_err();
    assert!(matches!(e.kind, EdsErrorKind::NotGenerated { .. }));
    assert!(e.to_string().contains("0x2fffsub3"), "{e}");
    // The stack's own, where the entries exist (the gateway has 0x1019, not 0x1003); an
    // import installs the same.
    let gateway = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/examples/safety_gateway/safety_gateway.eds"
    );
    let d = Description::read(gateway).unwrap();
    let src = codegen::generate(&d, &CodegenOptions::default()).unwrap();
    assert_eq!(src.matches(".hook(").count(), 1);
    assert_eq!(
        src.matches(".hook(::duocan::od::comm::sync_overflow_value)")
            .count(),
        1
    );
    // Names: the file's, or none at all (a small target's flash).
    assert_eq!(
        src.matches(".named(\"Producer heartbeat time\")").count(),
        1
    );
    let nameless = codegen::generate(&d, &CodegenOptions::default().with_names(false)).unwrap();
    assert_eq!(nameless.matches(".named(").count(), 0);
    assert_eq!(
        nameless.lines().count(),
        src.lines().count() - src.matches(".named(").count()
    );
    let none = CodegenOptions::default().with_standard_hooks(false);
    assert_eq!(
        codegen::generate(&d, &none)
            .unwrap()
            .matches(".hook(")
            .count(),
        0
    );
    let mut od = d.dictionary(20);
    assert_eq!(
        od.write(0x1019, 0, &[1]),
        Err(duocan::AbortCode::VALUE_RANGE)
    );
    assert_eq!(od.write(0x1019, 0, &[2]), Ok(()));
}

#[test]
fn names_become_index_constants() {
    assert_eq!(nodeid::index::IDENTITY_OBJECT, 0x1018);
    assert_eq!(data_types::index::DEVICE_TYPE, 0x1000);
}

#[test]
fn index_constant_names_are_unique() {
    let var = |index: u16, name: &str| {
        format!(
            "[{index:04X}]\nParameterName={name}\nDataType=0x0005\nAccessType=rw\nDefaultValue=0\n"
        )
    };
    let text = format!(
        "[OptionalObjects]\nSupportedObjects=4\n1=0x2000\n2=0x2001\n3=0x2002\n4=0x2003\n{}{}{}{}",
        var(0x2000, "A"),
        var(0x2001, "A"),
        var(0x2002, "A 2000"),
        var(0x2003, "2nd (spare)"),
    );
    let d = Description::parse(text.as_bytes(), "names.eds", &ImportOptions::lenient()).unwrap();
    let src = codegen::generate(&d, &CodegenOptions::default()).unwrap();
    for line in [
        "pub const A_2000: u16 = 0x2000;",
        "pub const A_2001: u16 = 0x2001;",
        "pub const A_2000_2002: u16 = 0x2002;",
        "pub const OBJECT_2ND_SPARE: u16 = 0x2003;",
    ] {
        assert!(src.contains(line), "{line}\n{src}");
    }
}
