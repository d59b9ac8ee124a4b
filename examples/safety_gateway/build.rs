//! Generates the gateway's static dictionary from its EDS (`safety_gateway.eds`, the one
//! place the dictionary is written down): `OUT_DIR/dictionary.rs`, included by
//! `src/dictionary.rs`. A bad EDS fails the build with the error naming the file, line,
//! section and key.

use duocan::eds::codegen::{build_script, CodegenOptions};

fn main() {
    if let Err(e) = build_script(
        "safety_gateway.eds",
        "dictionary.rs",
        &CodegenOptions::default(),
    ) {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}
