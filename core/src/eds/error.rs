//! What can be wrong in a device description, and where: every error and every lenient warning
//! names the file, the line, the section and the key.

use alloc::boxed::Box;
use alloc::string::String;
use core::fmt;

/// Where in a file something was found: the file's name, the 1-based line (0: the file as a
/// whole), the section and the key, as the file spells them.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Location {
    /// The file's name (or the name given for text read from memory).
    pub file: String,
    /// 1-based line; 0 when the problem is about the file as a whole.
    pub line: u32,
    /// The section, without brackets.
    pub section: Option<String>,
    /// The key.
    pub key: Option<String>,
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file)?;
        if self.line > 0 {
            write!(f, ":{}", self.line)?;
        }
        if let Some(s) = &self.section {
            write!(f, ": [{s}]")?;
        }
        if let Some(k) = &self.key {
            write!(f, " {k}")?;
        }
        Ok(())
    }
}

/// What is wrong. In lenient mode (the default) most of these are warnings: the importer takes
/// a value and goes on; in strict mode each is an error. The few that leave nothing to take
/// ([`Io`](Self::Io), the size caps, a value that is no number at all) are errors in both modes.
#[derive(Clone, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum EdsErrorKind {
    /// The file could not be read.
    Io {
        /// What the operating system said.
        message: String,
    },
    /// The file is larger than [`MAX_FILE_BYTES`](super::MAX_FILE_BYTES).
    FileTooLarge {
        /// The cap.
        max: usize,
    },
    /// A line is longer than [`MAX_LINE_BYTES`](super::MAX_LINE_BYTES).
    LineTooLong {
        /// The cap.
        max: usize,
    },
    /// The file has more than [`MAX_KEYS`](super::MAX_KEYS) sections and keys.
    TooManyKeys {
        /// The cap.
        max: usize,
    },
    /// The file describes more than [`MAX_ENTRIES`](super::MAX_ENTRIES) entries (sub-objects,
    /// counting those a `CompactSubObj` or `CompactPDO` implies).
    TooManyEntries {
        /// The cap.
        max: usize,
    },
    /// The names and values held pass [`MAX_VALUE_BYTES`](super::MAX_VALUE_BYTES).
    ValuesTooLarge {
        /// The cap.
        max: usize,
    },
    /// A line is not valid UTF-8 (lenient: read as Latin-1, as older Windows tools wrote it).
    NotUtf8,
    /// A line is neither a section header, a `key=value` pair, a comment nor blank.
    Syntax {
        /// What the line looked like.
        what: &'static str,
    },
    /// A section appears twice (lenient: its keys are merged, later ones win).
    DuplicateSection,
    /// A key appears twice in a section (lenient: the last one is taken).
    DuplicateKey,
    /// A key the format requires is missing (the location names it).
    MissingKey,
    /// A section the format requires is missing (the location names it).
    MissingSection,
    /// Nothing in the file is a description: no `[FileInfo]`, no `[DeviceInfo]`, no object (an
    /// error in both modes: a file of another kind, or random bytes, given by mistake).
    NotADescription,
    /// A value is not a number, or not one of the forms the key allows.
    BadValue {
        /// The text found.
        value: String,
        /// What was expected.
        expected: &'static str,
    },
    /// A number does not fit the entry's data type or the key's range.
    OutOfRange {
        /// The text found.
        value: String,
        /// The type or range it had to fit.
        range: String,
    },
    /// A number with a leading zero (octal in CiA 306) has the digits 8 or 9.
    OctalDigits {
        /// The text found.
        value: String,
    },
    /// A data type the stack does not know (lenient: DOMAIN).
    UnknownDataType {
        /// The type index.
        code: u32,
    },
    /// An `AccessType` that is none of ro, wo, rw, rwr, rww, const.
    UnknownAccessType {
        /// The text found.
        value: String,
    },
    /// An `ObjectType` that is none of NULL, DOMAIN, DEFTYPE, DEFSTRUCT, VAR, ARRAY, RECORD.
    UnknownObjectType {
        /// The code found.
        code: u32,
    },
    /// A count (`SubNumber`, `SupportedObjects`, `NrOfEntries`, `Lines`, …) that does not match
    /// what the file holds.
    CountMismatch {
        /// The count stated.
        stated: u32,
        /// The count found.
        found: u32,
    },
    /// An object listed in an object list without a section, or a section no list names.
    ObjectList {
        /// The object's index.
        index: u16,
        /// Which of the two.
        what: &'static str,
    },
    /// A sub-object section whose object is not described.
    Orphan,
    /// An array or record without sub-index 0 (lenient: one is made, UNSIGNED8 const, holding
    /// the highest sub-index).
    NoSubZero,
    /// A default or parameter value outside `LowLimit`…`HighLimit`, or limits the wrong way
    /// round.
    OutsideLimits {
        /// The value.
        value: String,
    },
    /// A name longer than [`MAX_NAME_BYTES`](super::MAX_NAME_BYTES) (lenient: cut).
    NameTooLong,
    /// A mandatory object (0x1000, 0x1001, 0x1018) is missing.
    MissingMandatory {
        /// The object's index.
        index: u16,
    },
    /// A key that does not belong where it is (a `$NODEID` in a value that cannot hold one,
    /// limits on a string, `UploadFile` on an entry that is not a DOMAIN, …).
    Misplaced {
        /// Why.
        why: &'static str,
    },
    /// What a generated static dictionary cannot hold (see [`codegen`](super::codegen)): a
    /// node-relative limit, a write hook for an entry the file does not describe, the output
    /// that could not be written.
    NotGenerated {
        /// Why, naming the entry.
        why: String,
    },
}

impl fmt::Display for EdsErrorKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        use EdsErrorKind::*;
        match self {
            Io { message } => write!(f, "cannot read the file: {message}"),
            FileTooLarge { max } => write!(f, "the file is larger than {max} bytes"),
            LineTooLong { max } => write!(f, "the line is longer than {max} bytes"),
            TooManyKeys { max } => write!(f, "the file has more than {max} sections and keys"),
            TooManyEntries { max } => write!(f, "the file describes more than {max} entries"),
            ValuesTooLarge { max } => {
                write!(f, "the names and values described pass {max} bytes")
            }
            NotUtf8 => write!(f, "the line is not UTF-8"),
            Syntax { what } => write!(f, "not a section, a key=value pair or a comment: {what}"),
            DuplicateSection => write!(f, "the section appears twice"),
            DuplicateKey => write!(f, "the key appears twice"),
            MissingKey => write!(f, "the key is missing"),
            MissingSection => write!(f, "the section is missing"),
            NotADescription => write!(
                f,
                "not a device description: no [FileInfo], no [DeviceInfo], no object section"
            ),
            BadValue { value, expected } => write!(f, "{value:?} is not {expected}"),
            OutOfRange { value, range } => write!(f, "{value:?} does not fit {range}"),
            OctalDigits { value } => write!(
                f,
                "{value:?} has a leading zero (octal) but the digit 8 or 9"
            ),
            UnknownDataType { code } => write!(f, "unknown data type {code:#06x}"),
            UnknownAccessType { value } => write!(
                f,
                "unknown access type {value:?} (ro, wo, rw, rwr, rww or const)"
            ),
            UnknownObjectType { code } => write!(f, "unknown object type {code:#x}"),
            CountMismatch { stated, found } => {
                write!(f, "the count says {stated} but the file holds {found}")
            }
            ObjectList { index, what } => write!(f, "object {index:#06x} {what}"),
            Orphan => write!(f, "sub-object section of an object that is not described"),
            NoSubZero => write!(f, "array or record without sub-index 0"),
            OutsideLimits { value } => write!(f, "{value:?} is outside LowLimit..HighLimit"),
            NameTooLong => write!(f, "the name is longer than {} bytes", super::MAX_NAME_BYTES),
            MissingMandatory { index } => write!(f, "mandatory object {index:#06x} is missing"),
            Misplaced { why } => write!(f, "{why}"),
            NotGenerated { why } => write!(f, "cannot generate a static dictionary: {why}"),
        }
    }
}

/// A device description that could not be read, and where.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct EdsError {
    /// Where (boxed: errors travel through every `?` of the importer).
    pub at: Box<Location>,
    /// What.
    pub kind: EdsErrorKind,
}

impl fmt::Display for EdsError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.at, self.kind)
    }
}

impl core::error::Error for EdsError {}

/// What a lenient import accepted although the file got it wrong, and the value it took
/// instead. Each is also reported through `tracing` at the `warn` level.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Warning {
    /// Where.
    pub at: Location,
    /// What was wrong (the error strict mode would have given).
    pub kind: EdsErrorKind,
    /// What was taken instead, in words.
    pub taken: String,
}

impl fmt::Display for Warning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}; taken: {}", self.at, self.kind, self.taken)
    }
}

/// Why a dictionary could not be written as a device description: a value the text format
/// cannot carry.
#[derive(Clone, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum ExportError {
    /// The entry's default or current value cannot be written so that it reads back the same.
    Unrepresentable {
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// Why.
        why: &'static str,
    },
}

impl fmt::Display for ExportError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ExportError::Unrepresentable { index, sub, why } => {
                write!(f, "entry {index:#06x}sub{sub} cannot be written: {why}")
            }
        }
    }
}

impl core::error::Error for ExportError {}

/// A name that does not name exactly one object or entry.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LookupError {
    /// The name asked for.
    pub name: String,
    /// Why it failed.
    pub kind: LookupErrorKind,
}

/// Why a name lookup failed.
#[derive(Clone, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum LookupErrorKind {
    /// Nothing has that name or address.
    NotFound,
    /// Several objects or entries have that name: each candidate, as `0x1800sub1 (COB-ID used
    /// by TPDO)`.
    Ambiguous {
        /// The candidates.
        candidates: alloc::vec::Vec<String>,
    },
    /// The name is an array's or record's: name one of its entries.
    NotAnEntry {
        /// The object's index.
        index: u16,
    },
}

impl fmt::Display for LookupError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.kind {
            LookupErrorKind::NotFound => write!(f, "no object or entry is named {:?}", self.name),
            LookupErrorKind::Ambiguous { candidates } => write!(
                f,
                "{:?} is ambiguous; it names {}",
                self.name,
                candidates.join(", ")
            ),
            LookupErrorKind::NotAnEntry { index } => write!(
                f,
                "{:?} names the array or record {index:#06x}: name one of its entries (\"{index:04X}sub1\")",
                self.name
            ),
        }
    }
}

impl core::error::Error for LookupError {}

/// Collects what a lenient import accepts and turns it into errors in strict mode.
pub(crate) struct Reporter {
    file: String,
    strict: bool,
    pub(crate) warnings: alloc::vec::Vec<Warning>,
    pub(crate) dropped: usize,
}

impl Reporter {
    pub(crate) fn new(file: &str, strict: bool) -> Reporter {
        Reporter {
            file: file.into(),
            strict,
            warnings: alloc::vec::Vec::new(),
            dropped: 0,
        }
    }

    pub(crate) fn at(&self, line: u32, section: Option<&str>, key: Option<&str>) -> Location {
        Location {
            file: self.file.clone(),
            line,
            section: section.map(Into::into),
            key: key.map(Into::into),
        }
    }

    pub(crate) fn error(&self, at: Location, kind: EdsErrorKind) -> EdsError {
        EdsError {
            at: Box::new(at),
            kind,
        }
    }

    /// Something a real file gets wrong: an error in strict mode; in lenient mode a warning
    /// (traced and kept, up to [`MAX_WARNINGS`](super::MAX_WARNINGS)) and `Ok`.
    pub(crate) fn problem(
        &mut self,
        at: Location,
        kind: EdsErrorKind,
        taken: impl fmt::Display,
    ) -> Result<(), EdsError> {
        if self.strict {
            return Err(self.error(at, kind));
        }
        if self.warnings.len() >= super::MAX_WARNINGS {
            self.dropped += 1;
            return Ok(());
        }
        let w = Warning {
            at,
            kind,
            taken: alloc::format!("{taken}"),
        };
        tracing::warn!(target: "duocan::eds", "{w}");
        self.warnings.push(w);
        Ok(())
    }
}
