//! Device descriptions (CiA 306): the corpus of small EDS/DCF files in `files/` (one quirk
//! each, and in `files/strict/` one mistake each), name lookup, round trips through export,
//! random dictionaries, a generated 2,000-entry file, the memory caps, the `tracing`
//! warnings, and the static dictionaries generated from corpus files at build time
//! (`generated/`).

mod bounds;
mod codegen;
mod corpus;
pub mod generate;
mod lookup;
mod other_tools;
mod properties;
mod roundtrip;
mod strict;
pub mod warnings;

use duocan::eds::{Description, ImportOptions};
use std::path::PathBuf;

/// The path of a corpus file.
pub fn path(name: &str) -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/eds/files")).join(name)
}

/// A corpus file imported leniently; fails the test on an error.
pub fn read(name: &str) -> Description {
    Description::read(path(name)).unwrap_or_else(|e| panic!("{name}: {e}"))
}

/// A corpus file that must import in strict mode too, without a warning in lenient mode.
pub fn clean(name: &str) -> Description {
    let d = read(name);
    assert!(d.warnings.is_empty(), "{name}: {:#?}", d.warnings);
    let strict = Description::read_with(path(name), &ImportOptions::strict())
        .unwrap_or_else(|e| panic!("{name} (strict): {e}"));
    assert_eq!(strict, d, "{name}: strict and lenient read the same");
    d
}
