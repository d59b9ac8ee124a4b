//! Build-time generation: an EDS turned into the Rust source of a `no_std` node's static
//! dictionary, for a `build.rs`.
//!
//! A node without an allocator cannot import a file at run time; it keeps its definitions in
//! `'static` tables (flash) and loads them into a [`StaticDictionary`]. CANopenNode generates
//! such tables in C from its editor's project files; here a build script generates them in
//! Rust from the EDS, so the EDS is the one place the dictionary is written down and the same
//! file goes to the integrator.
//!
//! # The rule
//!
//! The generated table is, entry by entry, the dictionary [`Description::dictionary`] builds
//! from the same file ([`difference`](super::difference) finds nothing between the two):
//!
//! - one [`ObjectDef`] per entry of every VAR, ARRAY and RECORD, by index and sub-index, as a
//!   chain of its `const` builders (`ObjectDef::new(..)` then each one that differs from its
//!   start, a line each): object and data type, access, PDO mappability, default (`$NODEID+…` stays
//!   node-relative: one table serves every node-ID), limits, capacity, name (sub-index 0 of an
//!   array or record carries the object's name); type definitions are not entries;
//! - a DCF's `ParameterValue` becomes the entry's default: the table is that node's
//!   configuration, as in CANopenNode's generated dictionaries;
//! - write hooks are code, not description: the stack's own ([`comm::HOOKS`]: 0x1003 sub 0,
//!   0x1019) are installed where those entries exist, as an import installs them; others are
//!   named with [`CodegenOptions::with_hook`];
//! - the file is read strictly unless told otherwise (a build should not rest on a file a
//!   validator refuses); a lenient read returns its warnings, which [`build_script`] prints as
//!   cargo warnings.
//!
//! What a static table cannot hold is an error naming the entry (file, the line of its
//! section, section, key):
//! a `$NODEID` limit (a [`Limit`](crate::od::Limit) is a number), a hook for an entry the file
//! does not describe.
//!
//! # What the source holds
//!
//! Items only, to be `include!`d into a module of its own: `OBJECTS` (the table, a
//! `static`), `ENTRIES` and `VALUE_BYTES` (the least `N` and `BYTES` a [`StaticDictionary`]
//! needs; `ENTRY_CAPACITY` is `ENTRIES` rounded up to the power of two `N` must be), and a
//! module `index` with a `u16` constant per object named after it (`PRODUCER_HEARTBEAT_TIME`;
//! an index suffix where names repeat). Nothing is allocated; the RAM a node spends is the
//! [`StaticDictionary`]'s, whose parameters stay the application's choice.
//!
//! ```
//! use duocan_core::eds::codegen::{self, CodegenOptions};
//! use duocan_core::eds::{Description, ImportOptions};
//!
//! let text = "\
//! [FileInfo]
//! FileName=sensor.eds
//! [DeviceInfo]
//! VendorName=ACME
//! [MandatoryObjects]
//! SupportedObjects=3
//! 1=0x1000
//! 2=0x1001
//! 3=0x1018
//! [OptionalObjects]
//! SupportedObjects=1
//! 1=0x1017
//! [1000]
//! ParameterName=Device type
//! DataType=0x0007
//! AccessType=const
//! DefaultValue=0x191
//! [1001]
//! ParameterName=Error register
//! DataType=0x0005
//! AccessType=ro
//! PDOMapping=1
//! [1017]
//! ParameterName=Producer heartbeat time
//! DataType=0x0006
//! AccessType=rw
//! DefaultValue=100
//! [1018]
//! ParameterName=Identity object
//! ObjectType=0x9
//! SubNumber=2
//! [1018sub0]
//! ParameterName=Highest sub-index supported
//! DataType=0x0005
//! AccessType=const
//! DefaultValue=1
//! [1018sub1]
//! ParameterName=Vendor-ID
//! DataType=0x0007
//! AccessType=ro
//! DefaultValue=0xD0CA
//! ";
//! let eds = Description::parse(text.as_bytes(), "sensor.eds", &ImportOptions::strict())?;
//! let source = codegen::generate(&eds, &CodegenOptions::default())?;
//! assert!(source.contains("pub const ENTRIES: usize = 5;"));
//! assert!(source.contains("pub const PRODUCER_HEARTBEAT_TIME: u16 = 0x1017;"));
//! assert!(source.contains(".default(DefaultValue::Unsigned(100))"));
//!
//! // A limit that depends on the node-ID has no static form: an error naming the entry.
//! let bad = text.replace("DefaultValue=100", "DefaultValue=100\nHighLimit=$NODEID+0x600");
//! let eds = Description::parse(bad.as_bytes(), "sensor.eds", &ImportOptions::strict())?;
//! let err = codegen::generate(&eds, &CodegenOptions::default()).unwrap_err();
//! assert_eq!(
//!     err.to_string(),
//!     "sensor.eds:23: [1017] HighLimit: cannot generate a static dictionary: \
//!      0x1017sub0 has a $NODEID limit, which a static table cannot hold"
//! );
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! In a build script, [`build_script`] does the rest: it reads the EDS named relative to the
//! package, writes the source to `OUT_DIR` and tells cargo to rebuild when the EDS changes.
//!
//! [`StaticDictionary`]: crate::od::StaticDictionary
//! [`ObjectDef`]: crate::od::ObjectDef
//! [`comm::HOOKS`]: crate::od::comm::HOOKS

mod emit;

use super::error::{EdsError, EdsErrorKind, Location, Warning};
use super::import::ImportOptions;
use super::model::Description;
use alloc::boxed::Box;
use alloc::string::String;
use alloc::vec::Vec;
use std::path::{Path, PathBuf};

/// How to generate: how to read the file, and the write hooks to install.
#[derive(Clone, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub struct CodegenOptions {
    /// How the file is read (default: strict).
    pub import: ImportOptions,
    /// Install the stack's own hooks on 0x1003 sub 0 and 0x1019 where the file has them
    /// (default: yes).
    pub standard_hooks: bool,
    /// Further hooks: (index, sub-index, the path of a
    /// [`WriteHook`](crate::od::WriteHook) function as the generated code names it).
    pub hooks: Vec<(u16, u8, String)>,
    /// Give each definition the file's `ParameterName` (default: yes). Without, every name is
    /// empty: a small target that never shows them (its tools read the names from the EDS)
    /// keeps their bytes out of its flash.
    pub names: bool,
}

impl Default for CodegenOptions {
    fn default() -> Self {
        CodegenOptions {
            import: ImportOptions::strict(),
            standard_hooks: true,
            hooks: Vec::new(),
            names: true,
        }
    }
}

impl CodegenOptions {
    /// Sets how the file is read.
    #[must_use]
    pub fn with_import(mut self, import: ImportOptions) -> Self {
        self.import = import;
        self
    }
    /// Installs the function at `path` (`crate::hooks::check_speed`) as the write hook of
    /// (`index`, `sub`); the entry must be in the file.
    #[must_use]
    pub fn with_hook(mut self, index: u16, sub: u8, path: &str) -> Self {
        self.hooks.push((index, sub, path.into()));
        self
    }
    /// Sets whether the stack's own hooks are installed.
    #[must_use]
    pub fn with_standard_hooks(mut self, on: bool) -> Self {
        self.standard_hooks = on;
        self
    }
    /// Sets whether the definitions carry the objects' names.
    #[must_use]
    pub fn with_names(mut self, on: bool) -> Self {
        self.names = on;
        self
    }
}

/// What a generation made.
#[derive(Clone, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub struct Generated {
    /// The Rust source.
    pub source: String,
    /// Entries in the table.
    pub entries: usize,
    /// Bytes of values the table needs in a static dictionary.
    pub value_bytes: usize,
    /// What a lenient read accepted (empty when strict).
    pub warnings: Vec<Warning>,
}

/// The Rust source of the static dictionary `description` describes (see the module
/// documentation for what it holds).
pub fn generate(description: &Description, options: &CodegenOptions) -> Result<String, EdsError> {
    Ok(emit::source(description, options)?.source)
}

/// Reads the EDS or DCF at `eds`, generates its static dictionary and writes the source to
/// `out`. Errors name the file, line, section and key.
pub fn generate_file(
    eds: impl AsRef<Path>,
    out: impl AsRef<Path>,
    options: &CodegenOptions,
) -> Result<Generated, EdsError> {
    let description = Description::read_with(eds.as_ref(), &options.import)?;
    let mut generated = emit::source(&description, options)?;
    generated.warnings = description.warnings;
    let out = out.as_ref();
    std::fs::write(out, &generated.source).map_err(|e| {
        not_generated(
            &out.display().to_string(),
            alloc::format!("cannot write the source: {e}"),
        )
    })?;
    Ok(generated)
}

/// For a `build.rs`: generates the static dictionary of the EDS at `eds` (relative to the
/// package's directory) into `OUT_DIR/out_name`, tells cargo to run the script again when the
/// EDS changes and prints the warnings of a lenient read as cargo warnings. The crate then
/// includes it in a module of its own, as `examples/safety_gateway` does (shown as text, not
/// compiled here: `OUT_DIR` exists only in a crate with a build script):
///
/// ```text
/// mod generated {
///     include!(concat!(env!("OUT_DIR"), "/dictionary.rs"));
/// }
/// ```
///
/// A build script fails the build with the error (it names the file, line, section and key):
///
/// ```no_run
/// use duocan_core::eds::codegen::{build_script, CodegenOptions};
/// if let Err(e) = build_script("gateway.eds", "dictionary.rs", &CodegenOptions::default()) {
///     eprintln!("error: {e}");
///     std::process::exit(1);
/// }
/// ```
pub fn build_script(
    eds: &str,
    out_name: &str,
    options: &CodegenOptions,
) -> Result<Generated, EdsError> {
    let env = |name: &str| {
        std::env::var_os(name).map(PathBuf::from).ok_or_else(|| {
            not_generated(
                eds,
                alloc::format!("{name} is not set: call this from a build script"),
            )
        })
    };
    let path = env("CARGO_MANIFEST_DIR")?.join(eds);
    let out = env("OUT_DIR")?.join(out_name);
    println!("cargo:rerun-if-changed={}", path.display());
    let generated = generate_file(&path, &out, options)?;
    for w in &generated.warnings {
        println!("cargo:warning={w}");
    }
    Ok(generated)
}

/// An error about `file` as a whole.
fn not_generated(file: &str, why: String) -> EdsError {
    EdsError {
        at: Box::new(Location {
            file: file.into(),
            ..Location::default()
        }),
        kind: EdsErrorKind::NotGenerated { why },
    }
}
