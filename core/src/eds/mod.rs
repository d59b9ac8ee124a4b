//! Device descriptions (CiA 306): EDS and DCF files in and out.
//!
//! Every CANopen device ships with an electronic data sheet (EDS) that lists its dictionary;
//! a device configuration file (DCF) is an EDS plus one node's configuration. This module reads
//! both into a [`Description`] — names, types, limits, access, defaults, PDO mappability, the
//! configured values — with name lookup, and builds a duocan node's [`DynamicDictionary`] from
//! it; and it writes any duocan dictionary, static or dynamic, as an EDS or a DCF.
//!
//! # The rule
//!
//! Import reads the file as vendors really write it and keeps what it says:
//!
//! - sections and keys compare without regard to case; `;` starts a comment line, and a `;`
//!   after a number starts a comment too; numbers are decimal, hex (`0x`) or octal (a leading
//!   `0`); integer values may be `$NODEID` expressions (`$NODEID+0x180`, `0x180+$NODEID`),
//!   kept node-relative until a dictionary is built for a node;
//! - the objects are those the object lists (`[MandatoryObjects]`, `[OptionalObjects]`,
//!   `[ManufacturerObjects]`) name, each from its section: a VAR from `[xxxx]`, an ARRAY or
//!   RECORD from `[xxxxsubN]` sections or from `CompactSubObj` (entries named by `[xxxxName]`,
//!   a DCF's values in `[xxxxValue]`, denotations in `[xxxxDenotation]`); `CompactPDO` implies
//!   the PDOs `NrOfRXPDO`/`NrOfTXPDO` count that the file does not describe;
//! - every access type (`ro`, `wo`, `rw`, `rwr`, `rww`, `const`), every CiA 301 data type (see
//!   [`type_name`]), `DefaultValue`, `LowLimit`/`HighLimit`, `PDOMapping`, `ObjFlags`, a DCF's
//!   `ParameterValue` and `Denotation`, `UploadFile`/`DownloadFile` (the names; the files are
//!   not read), `[xxxxObjectLinks]`, `[FileInfo]`, `[DeviceInfo]` (bit rates, PDO counts,
//!   granularity, LSS), `[DummyUsage]`, `[Comments]` and `[DeviceComissioning]`.
//!
//! The INI layer is our own (`ini.rs`): the INI crates give no line numbers, which every error
//! here names, and fold case and refuse duplicates differently from what vendors' files need.
//!
//! Export writes what import reads back as the same dictionary ([`difference`] finds none):
//! names, object and data types, access, PDO mappability, defaults (`$NODEID+…` where
//! node-relative), limits, capacities and, in a DCF, every current value. What no text file
//! can carry (a string with a line break or surrounding spaces, bytes that are not text) is an
//! [`ExportError`] naming the entry, not a silent change.
//!
//! # Lenient and strict
//!
//! By default an import is lenient: what a real file gets wrong — a duplicate key (the last
//! one is taken), a `SubNumber` that miscounts, a missing sub-index 0, an octal number with an
//! 8 in it (read as decimal), `true` for 1, a value outside its type (wrapped, as a C tool
//! would) or its limits, a line in Latin-1, an object no list names, … — is a
//! [`Warning`] that names the file, line, section and key and the value taken, reported through
//! `tracing` (`warn`, target `duocan::eds`) and kept in [`Description::warnings`]. With
//! [`ImportOptions::strict`] each of these is an [`EdsError`] instead: for validating a file.
//! Either way bad input is an error or a warning, never a panic.
//!
//! Where other readers agree, so does this one, in both modes: a boolean (`PDOMapping`) written
//! as any number 0 or 1 (`0x1`), an empty `LowLimit=`/`HighLimit=` (no limit, on a string as on
//! a number). A `;` after an access type is a comment (`rw;` is `rw`, with a warning). A DCF for
//! `NodeID=0` names no node (a warning; strict: an error). An empty `ParameterValue=` on a
//! string whose default is not empty is the empty string (what an export of an empty string
//! writes), where lely keeps the default: a `tracing` warning says so, and strict mode takes
//! it. A file with no `[FileInfo]`, no `[DeviceInfo]` and no object is no description at all
//! ([`EdsErrorKind::NotADescription`], in both modes). Export leaves out `DefaultValue` for an
//! entry with no default whose limits exclude zero.
//!
//! # Memory
//!
//! Bounded on any input, by constants: the file is read up to [`MAX_FILE_BYTES`] (a larger one
//! is refused without being read further), a line up to [`MAX_LINE_BYTES`], at most
//! [`MAX_KEYS`] sections and keys, [`MAX_ENTRIES`] entries (those `CompactSubObj` and
//! `CompactPDO` imply included), names cut at [`MAX_NAME_BYTES`], [`MAX_VALUE_BYTES`] of names
//! and values in all, [`MAX_WARNINGS`] warnings kept (the rest counted). String and domain
//! capacities are at most [`MAX_CAPACITY`], and a dictionary entry holds only its value, not
//! its capacity.
//!
//! ```
//! use duocan_core::eds::{self, Description, ImportOptions};
//! use duocan_core::od::ObjectDictionary;
//!
//! let text = "\
//! [FileInfo]
//! FileName=sensor.eds
//! [DeviceInfo]
//! VendorName=ACME
//! [MandatoryObjects]
//! SupportedObjects=1
//! 1=0x1017
//! [1017]
//! ParameterName=Producer heartbeat time
//! DataType=0x0006
//! AccessType=rw
//! DefaultValue=1000
//! ";
//! // Lenient: the missing 0x1000, 0x1001 and 0x1018 are warnings.
//! let eds = Description::parse(text.as_bytes(), "sensor.eds", &ImportOptions::lenient())?;
//! assert_eq!(eds.warnings.len(), 3);
//! let hb = eds.entry("producer HEARTBEAT time")?;
//! assert_eq!((hb.index, hb.sub), (0x1017, 0));
//! let od = eds.dictionary(5);
//! assert_eq!(od.get_value::<u16>(0x1017, 0), Ok(1000));
//! assert_eq!(eds::find(&od, "0x1017sub0"), Ok((0x1017, 0)));
//!
//! // Strict: the first of them is an error that says where.
//! let err = Description::parse(text.as_bytes(), "sensor.eds", &ImportOptions::strict())
//!     .unwrap_err();
//! assert_eq!(err.to_string(), "sensor.eds: mandatory object 0x1000 is missing");
//!
//! // Out and back in: the same dictionary.
//! let back = Description::parse(
//!     eds::export_eds(&od, &eds::ExportOptions::default())?.as_bytes(),
//!     "exported.eds",
//!     &ImportOptions::lenient(),
//! )?;
//! assert_eq!(eds::difference(&od, &back.dictionary(5)), None);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! A `no_std` node's static dictionary comes from an EDS at build time: [`codegen`] writes
//! its definition tables as Rust source for a `build.rs`.
//!
//! Not yet: concise DCFs (0x1F22) and program download; they build on this module.
//!
//! [`DynamicDictionary`]: crate::od::DynamicDictionary

pub mod codegen;
mod compare;
mod error;
mod export;
mod import;
mod ini;
mod lookup;
mod model;
mod number;
mod value;

pub use compare::{difference, Difference};
pub use error::{
    EdsError, EdsErrorKind, ExportError, Location, LookupError, LookupErrorKind, Warning,
};
pub use export::{export_dcf, export_eds, ExportOptions};
pub use import::ImportOptions;
pub use lookup::find;
pub use model::{
    AccessType, Commissioning, Description, DeviceInfo, FileInfo, FileKind, Object, ObjectCode,
    SubObject,
};
pub use value::{canonical_limit, type_name, Value};

/// The largest file read (16 MiB): a 2,000-entry EDS is about 0.2 MiB, and what duocan exports
/// for the largest description it takes ([`MAX_ENTRIES`] entries, e.g. 512 PDOs fully mapped
/// through `CompactPDO`) stays below it, so whatever imports exports and imports again.
pub const MAX_FILE_BYTES: usize = 16 << 20;
/// The longest line (8 KiB): room for a 4 KiB domain default in hex.
pub const MAX_LINE_BYTES: usize = 8 << 10;
/// The most sections and keys in a file (room for the export of [`MAX_ENTRIES`] entries, about
/// eight keys each).
pub const MAX_KEYS: usize = 1 << 20;
/// The most entries (sub-objects) a description holds, implied ones included.
pub const MAX_ENTRIES: usize = 1 << 16;
/// The longest name kept (CiA 306 allows 241 characters); longer ones are cut.
pub const MAX_NAME_BYTES: usize = 255;
/// The most bytes of names and values a description holds in all (a `CompactSubObj` array
/// repeats its default in every entry).
pub const MAX_VALUE_BYTES: usize = 32 << 20;
/// The most warnings kept; further ones are counted in [`Description::warnings_dropped`].
pub const MAX_WARNINGS: usize = 1000;
/// The largest `MaxLength` taken (1 MiB).
pub const MAX_CAPACITY: u32 = 1 << 20;
/// The capacity of a string entry whose description gives none, unless its default is longer.
pub const STRING_CAPACITY: u32 = 256;
/// The capacity of a DOMAIN entry whose description gives none, unless its default is longer.
pub const DOMAIN_CAPACITY: u32 = 4096;
