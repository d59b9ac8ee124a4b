//! Generates the gateway's static dictionary from its EDS (`safety_gateway.eds`, the one
//! place the dictionary is written down): `OUT_DIR/dictionary.rs`, included by
//! `src/dictionary.rs`. A bad EDS fails the build with the error naming the file, line,
//! section and key.

use duocan::eds::codegen::{build_script, CodegenOptions};

fn main() {
    // The objects' names only with the feature `names` (default): the firmware image, which
    // never shows them, leaves them out of its flash.
    let names = std::env::var_os("CARGO_FEATURE_NAMES").is_some();
    if let Err(e) = build_script(
        "safety_gateway.eds",
        "dictionary.rs",
        &CodegenOptions::default().with_names(names),
    ) {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}
