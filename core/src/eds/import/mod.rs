//! Import: bytes → INI sections → a [`Description`].
//!
//! The sections other than the objects' are read here (`[FileInfo]`, `[DeviceInfo]`,
//! `[DummyUsage]`, `[Comments]`, `[DeviceComissioning]`); the objects in [`objects`], the
//! implied ones (`CompactSubObj`, `CompactPDO`) and `ObjectLinks` in [`compact`].

mod compact;
mod entry;
mod objects;

use super::error::{EdsError, EdsErrorKind, Location, Reporter};
use super::ini::{self, Ini, Pair, Section};
use super::model::{Commissioning, Description, DeviceInfo, FileInfo, FileKind};
use super::number::{self, NumError};
use super::MAX_FILE_BYTES;
use alloc::string::String;
use alloc::vec::Vec;
use std::io::Read;
use std::path::Path;

/// How to import.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[non_exhaustive]
pub struct ImportOptions {
    /// Every quirk a lenient import accepts with a warning is an error instead: for validating
    /// a file. Off by default.
    pub strict: bool,
}

impl ImportOptions {
    /// Lenient (the default): what a real file gets wrong is a warning naming the value taken.
    #[must_use]
    pub const fn lenient() -> Self {
        ImportOptions { strict: false }
    }
    /// Strict: what a lenient import would warn about is an error.
    #[must_use]
    pub const fn strict() -> Self {
        ImportOptions { strict: true }
    }
    /// Sets strict mode.
    #[must_use]
    pub const fn with_strict(mut self, strict: bool) -> Self {
        self.strict = strict;
        self
    }
}

impl Description {
    /// Reads an EDS or DCF file, leniently.
    pub fn read(path: impl AsRef<Path>) -> Result<Description, EdsError> {
        Self::read_with(path, &ImportOptions::lenient())
    }

    /// Reads an EDS or DCF file. Errors and warnings name the file by `path`.
    pub fn read_with(
        path: impl AsRef<Path>,
        opts: &ImportOptions,
    ) -> Result<Description, EdsError> {
        let path = path.as_ref();
        let source = path.display().to_string();
        let io = |e: std::io::Error| EdsError {
            at: alloc::boxed::Box::new(Location {
                file: source.clone(),
                ..Location::default()
            }),
            kind: EdsErrorKind::Io {
                message: e.to_string(),
            },
        };
        let file = std::fs::File::open(path).map_err(io)?;
        // Never more than the cap plus one byte in memory, whatever the file's size.
        let mut bytes = Vec::new();
        file.take(MAX_FILE_BYTES as u64 + 1)
            .read_to_end(&mut bytes)
            .map_err(io)?;
        Self::parse(&bytes, &source, opts)
    }

    /// Imports an EDS or DCF held in memory; errors and warnings name it `source`.
    pub fn parse(
        bytes: &[u8],
        source: &str,
        opts: &ImportOptions,
    ) -> Result<Description, EdsError> {
        let mut rep = Reporter::new(source, opts.strict);
        let text = ini::decode(bytes, &mut rep)?;
        let ini = ini::parse(&text, &mut rep)?;
        let mut imp = Importer {
            ini: &ini,
            rep: &mut rep,
            entries: 0,
            value_bytes: 0,
        };
        let file_info = imp.file_info()?;
        let device_info = imp.device_info()?;
        let dummy_usage = imp.dummy_usage()?;
        let comments = imp.comments()?;
        let commissioning = imp.commissioning()?;
        let mut objects = imp.objects()?;
        if objects.is_empty()
            && ini.named("fileinfo").is_none()
            && ini.named("deviceinfo").is_none()
        {
            let at = imp.rep.at(0, None, None);
            return Err(imp.rep.error(at, EdsErrorKind::NotADescription));
        }
        imp.compact_pdo(&device_info, &mut objects)?;
        imp.links(&mut objects)?;
        for index in [0x1000, 0x1001, 0x1018] {
            if !objects.contains_key(&index) {
                let at = imp.rep.at(0, None, None);
                imp.rep.problem(
                    at,
                    EdsErrorKind::MissingMandatory { index },
                    "the file as it is",
                )?;
            }
        }
        let dcf = commissioning.is_some()
            || objects
                .values()
                .any(|o| o.subs.values().any(|s| s.value.is_some()));
        Ok(Description {
            source: source.into(),
            kind: if dcf { FileKind::Dcf } else { FileKind::Eds },
            file_info,
            device_info,
            dummy_usage,
            comments,
            commissioning,
            objects,
            warnings: core::mem::take(&mut rep.warnings),
            warnings_dropped: rep.dropped,
        })
    }
}

/// The state of one import.
struct Importer<'i, 't> {
    ini: &'i Ini<'t>,
    rep: &'i mut Reporter,
    /// Entries made so far, against [`MAX_ENTRIES`](super::MAX_ENTRIES).
    entries: usize,
    /// Bytes of names and values held, against [`MAX_VALUE_BYTES`](super::MAX_VALUE_BYTES).
    value_bytes: usize,
}

impl<'t> Importer<'_, 't> {
    fn at(&self, sec: &Section<'_>, pair: Option<&Pair<'_>>) -> Location {
        match pair {
            Some(p) => self.rep.at(p.line, Some(sec.name), Some(p.key)),
            None => self.rep.at(sec.line, Some(sec.name), None),
        }
    }

    fn problem(
        &mut self,
        sec: &Section<'_>,
        pair: Option<&Pair<'_>>,
        kind: EdsErrorKind,
        taken: impl core::fmt::Display,
    ) -> Result<(), EdsError> {
        let at = self.at(sec, pair);
        self.rep.problem(at, kind, taken)
    }

    /// A key the section lacks: the location names the section's line and the key.
    fn missing(
        &mut self,
        sec: &Section<'_>,
        key: &str,
        taken: impl core::fmt::Display,
    ) -> Result<(), EdsError> {
        let at = self.rep.at(sec.line, Some(sec.name), Some(key));
        self.rep.problem(at, EdsErrorKind::MissingKey, taken)
    }

    /// A string key; empty when absent.
    fn text(&self, sec: Option<&Section<'t>>, key: &str) -> String {
        sec.and_then(|s| s.get(key))
            .map(|p| p.value.into())
            .unwrap_or_default()
    }

    /// A number key within `0..=max`: `None` when absent; a bad or out-of-range number is a
    /// problem (lenient: the key ignored, or the number clamped).
    fn number(
        &mut self,
        sec: Option<&Section<'t>>,
        key: &str,
        max: u64,
    ) -> Result<Option<u64>, EdsError> {
        let Some(sec) = sec else { return Ok(None) };
        let Some(p) = sec.get(key).copied() else {
            return Ok(None);
        };
        if p.value.is_empty() {
            return Ok(None);
        }
        let v = match number::literal(number::strip_comment(p.value)) {
            Ok(l) => l.value,
            Err(NumError::OctalDigits(v)) => {
                self.problem(
                    sec,
                    Some(&p),
                    EdsErrorKind::OctalDigits {
                        value: p.value.into(),
                    },
                    format_args!("{v} (decimal)"),
                )?;
                v
            }
            Err(_) => {
                let kind = EdsErrorKind::BadValue {
                    value: p.value.into(),
                    expected: "a number",
                };
                self.problem(sec, Some(&p), kind, "nothing: the key ignored")?;
                return Ok(None);
            }
        };
        if v < 0 || v > max as i128 {
            let taken = v.clamp(0, max as i128) as u64;
            let kind = EdsErrorKind::OutOfRange {
                value: p.value.into(),
                range: alloc::format!("0..={max}"),
            };
            self.problem(sec, Some(&p), kind, taken)?;
            return Ok(Some(taken));
        }
        Ok(Some(v as u64))
    }

    /// A boolean key (`0`/`1`; `true`/`false`, `yes`/`no` with a warning); false when absent.
    fn flag(&mut self, sec: Option<&Section<'t>>, key: &str) -> Result<bool, EdsError> {
        let Some(sec) = sec else { return Ok(false) };
        let Some(p) = sec.get(key).copied() else {
            return Ok(false);
        };
        let v = number::strip_comment(p.value);
        match v {
            "" | "0" => Ok(false),
            "1" => Ok(true),
            // 0x0, 0x1, 01: other readers take a boolean written as any number 0 or 1.
            _ if matches!(number::literal(v).map(|l| l.value), Ok(0 | 1)) => {
                Ok(number::literal(v).is_ok_and(|l| l.value == 1))
            }
            _ => {
                let b = match v.to_ascii_lowercase().as_str() {
                    "true" | "yes" => Some(true),
                    "false" | "no" => Some(false),
                    _ => number::literal(v).ok().map(|l| l.value != 0),
                };
                let kind = EdsErrorKind::BadValue {
                    value: p.value.into(),
                    expected: "0 or 1",
                };
                let taken = b.unwrap_or(false);
                self.problem(sec, Some(&p), kind, taken as u8)?;
                Ok(taken)
            }
        }
    }

    fn file_info(&mut self) -> Result<FileInfo, EdsError> {
        let s = self.ini.named("fileinfo");
        if s.is_none() {
            let at = self.rep.at(0, Some("FileInfo"), None);
            self.rep
                .problem(at, EdsErrorKind::MissingSection, "an empty [FileInfo]")?;
        }
        Ok(FileInfo {
            file_name: self.text(s, "FileName"),
            file_version: self.number(s, "FileVersion", 255)?.unwrap_or(0) as u8,
            file_revision: self.number(s, "FileRevision", 255)?.unwrap_or(0) as u8,
            eds_version: self.text(s, "EDSVersion"),
            description: self.text(s, "Description"),
            creation_time: self.text(s, "CreationTime"),
            creation_date: self.text(s, "CreationDate"),
            created_by: self.text(s, "CreatedBy"),
            modification_time: self.text(s, "ModificationTime"),
            modification_date: self.text(s, "ModificationDate"),
            modified_by: self.text(s, "ModifiedBy"),
            last_eds: self.text(s, "LastEDS"),
        })
    }

    fn device_info(&mut self) -> Result<DeviceInfo, EdsError> {
        let s = self.ini.named("deviceinfo");
        if s.is_none() {
            let at = self.rep.at(0, Some("DeviceInfo"), None);
            self.rep
                .problem(at, EdsErrorKind::MissingSection, "an empty [DeviceInfo]")?;
        }
        let mut baud_rates = Vec::new();
        for rate in [10u16, 20, 50, 125, 250, 500, 800, 1000] {
            if self.flag(s, &alloc::format!("BaudRate_{rate}"))? {
                baud_rates.push(rate);
            }
        }
        Ok(DeviceInfo {
            vendor_name: self.text(s, "VendorName"),
            vendor_number: self
                .number(s, "VendorNumber", u32::MAX as u64)?
                .map(|v| v as u32),
            product_name: self.text(s, "ProductName"),
            product_number: self
                .number(s, "ProductNumber", u32::MAX as u64)?
                .map(|v| v as u32),
            revision_number: self
                .number(s, "RevisionNumber", u32::MAX as u64)?
                .map(|v| v as u32),
            order_code: self.text(s, "OrderCode"),
            baud_rates,
            simple_boot_up_master: self.flag(s, "SimpleBootUpMaster")?,
            simple_boot_up_slave: self.flag(s, "SimpleBootUpSlave")?,
            granularity: self.number(s, "Granularity", 64)?.unwrap_or(8) as u8,
            dynamic_channels_supported: self
                .number(s, "DynamicChannelsSupported", 255)?
                .unwrap_or(0) as u8,
            group_messaging: self.flag(s, "GroupMessaging")?,
            nr_of_rx_pdo: self.number(s, "NrOfRXPDO", 512)?.unwrap_or(0) as u16,
            nr_of_tx_pdo: self.number(s, "NrOfTXPDO", 512)?.unwrap_or(0) as u16,
            lss_supported: self.flag(s, "LSS_Supported")?,
            compact_pdo: self.number(s, "CompactPDO", 0x3F)?.unwrap_or(0) as u8,
        })
    }

    fn dummy_usage(&mut self) -> Result<u32, EdsError> {
        let s = self.ini.named("dummyusage");
        let mut mask = 0u32;
        for code in 1..32u32 {
            if self.flag(s, &alloc::format!("Dummy{code:04X}"))? {
                mask |= 1 << code;
            }
        }
        Ok(mask)
    }

    fn comments(&mut self) -> Result<Vec<String>, EdsError> {
        let Some(s) = self.ini.named("comments") else {
            return Ok(Vec::new());
        };
        let stated = self.number(Some(s), "Lines", 0xFFFF)?;
        let mut lines = Vec::new();
        let mut n = 1u32;
        while let Some(p) = s.get(&alloc::format!("Line{n}")) {
            lines.push(String::from(p.value));
            n += 1;
        }
        let found = lines.len() as u32;
        match stated {
            Some(st) if st as u32 != found => {
                let p = s.get("Lines").copied();
                self.problem(
                    s,
                    p.as_ref(),
                    EdsErrorKind::CountMismatch {
                        stated: st as u32,
                        found,
                    },
                    format_args!("the {found} lines Line1..Line{found}"),
                )?;
            }
            None => self.missing(s, "Lines", format_args!("Lines={found}"))?,
            _ => {}
        }
        Ok(lines)
    }

    fn commissioning(&mut self) -> Result<Option<Commissioning>, EdsError> {
        let s = match self.ini.named("devicecomissioning") {
            Some(s) => s,
            None => match self.ini.named("devicecommissioning") {
                Some(s) => {
                    self.problem(
                        s,
                        None,
                        EdsErrorKind::Misplaced {
                            why: "CiA 306 spells the section [DeviceComissioning]",
                        },
                        "it as [DeviceComissioning]",
                    )?;
                    s
                }
                None => return Ok(None),
            },
        };
        let s = Some(s);
        let node_id = match self.number(s, "NodeID", 127)? {
            Some(0) => {
                // A configuration for "node 0" configures nothing: say so rather than attach
                // it to the broadcast address.
                let p = s.and_then(|s| s.get("NodeID").copied());
                let kind = EdsErrorKind::OutOfRange {
                    value: "0".into(),
                    range: "a node-ID, 1 to 127".into(),
                };
                if let Some(sec) = s {
                    self.problem(sec, p.as_ref(), kind, "no node-ID")?;
                }
                None
            }
            n => n.map(|v| v as u8),
        };
        Ok(Some(Commissioning {
            node_id,
            node_name: self.text(s, "NodeName"),
            baud_rate: self.number(s, "Baudrate", 1000)?.map(|v| v as u16),
            net_number: self
                .number(s, "NetNumber", u32::MAX as u64)?
                .map(|v| v as u32),
            network_name: self.text(s, "NetworkName"),
            canopen_manager: self.flag(s, "CANopenManager")?,
            lss_serial_number: self
                .number(s, "LSS_SerialNumber", u32::MAX as u64)?
                .map(|v| v as u32),
        }))
    }

    /// Counts an entry's names and values against the cap.
    fn hold(&mut self, e: &super::model::SubObject) -> Result<(), EdsError> {
        let bytes = |v: &Option<super::value::Value>| match v {
            Some(super::value::Value::Bytes(b)) => b.len(),
            _ => 0,
        };
        self.value_bytes += e.name.len()
            + e.denotation.as_ref().map_or(0, String::len)
            + bytes(&e.default)
            + bytes(&e.value);
        if self.value_bytes > super::MAX_VALUE_BYTES {
            let at = self.rep.at(e.line, None, None);
            return Err(self.rep.error(
                at,
                EdsErrorKind::ValuesTooLarge {
                    max: super::MAX_VALUE_BYTES,
                },
            ));
        }
        Ok(())
    }

    /// Counts one more entry against the cap.
    fn count_entry(&mut self, line: u32, section: &str) -> Result<(), EdsError> {
        self.entries += 1;
        if self.entries > super::MAX_ENTRIES {
            let at = self.rep.at(line, Some(section), None);
            return Err(self.rep.error(
                at,
                EdsErrorKind::TooManyEntries {
                    max: super::MAX_ENTRIES,
                },
            ));
        }
        Ok(())
    }
}
