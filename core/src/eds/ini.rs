//! The INI layer: sections of `key=value` lines, as vendors write them.
//!
//! Hand-written rather than taken from an INI crate: the crates we looked at (rust-ini,
//! configparser) give no line numbers, which every error here must name, and either fold case
//! everywhere or nowhere, or refuse duplicates outright. Here section names and keys compare
//! without regard to ASCII case and keep their spelling for messages; a repeated section is
//! merged and a repeated key keeps its last value (each a warning, an error in strict mode);
//! lines are `;` comments, `[section]` headers or `key=value` pairs, `\r\n` or `\n` ended, and a
//! line that is not UTF-8 is read as Latin-1 (older Windows tools wrote that).
//!
//! Values are kept verbatim (trimmed): inline comments are stripped only where a number is
//! read (see [`super::number`]), so a string default may hold a `;`.

use super::error::{EdsError, EdsErrorKind, Reporter};
use super::{MAX_FILE_BYTES, MAX_KEYS, MAX_LINE_BYTES};
use alloc::borrow::Cow;
use alloc::string::String;
use alloc::vec::Vec;
use std::collections::HashMap;

/// A section's name, classified: the object sections by index, the rest by lower-case name.
#[derive(Clone, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub(crate) enum SectionId {
    /// `[1018]`
    Object(u16),
    /// `[1018sub1]` (sub-index in hex)
    Sub(u16, u8),
    /// `[1003Name]`: names of a `CompactSubObj` array's entries.
    Names(u16),
    /// `[1003Value]`: a DCF's values of a `CompactSubObj` array's entries.
    Values(u16),
    /// `[1003Denotation]`: a DCF's denotations of a `CompactSubObj` array's entries.
    Denotations(u16),
    /// `[6000ObjectLinks]`
    Links(u16),
    /// Anything else (`fileinfo`, `deviceinfo`, `mandatoryobjects`, …), lower case.
    Other(String),
}

impl SectionId {
    fn classify(name: &str) -> SectionId {
        let lower = name.to_ascii_lowercase();
        let hex = |s: &str| -> Option<u16> {
            if s.is_empty() || s.len() > 4 || !s.bytes().all(|b| b.is_ascii_hexdigit()) {
                return None;
            }
            u16::from_str_radix(s, 16).ok()
        };
        for (suffix, make) in [
            ("objectlinks", SectionId::Links as fn(u16) -> SectionId),
            ("denotation", SectionId::Denotations),
            ("value", SectionId::Values),
            ("name", SectionId::Names),
        ] {
            if let Some(i) = lower.strip_suffix(suffix).and_then(hex) {
                return make(i);
            }
        }
        if let Some(i) = hex(&lower) {
            return SectionId::Object(i);
        }
        if let Some(pos) = lower.find("sub") {
            let (i, s) = (&lower[..pos], &lower[pos + 3..]);
            let sub = (!s.is_empty() && s.len() <= 2 && s.bytes().all(|b| b.is_ascii_hexdigit()))
                .then(|| u8::from_str_radix(s, 16).ok())
                .flatten();
            if let (Some(i), Some(s)) = (hex(i), sub) {
                return SectionId::Sub(i, s);
            }
        }
        SectionId::Other(lower)
    }
}

/// One `key=value` line.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Pair<'t> {
    pub key: &'t str,
    pub value: &'t str,
    pub line: u32,
}

/// One section with its pairs, in file order (a repeated key keeps its first place and its last
/// value).
#[derive(Debug)]
pub(crate) struct Section<'t> {
    pub name: &'t str,
    pub id: SectionId,
    pub line: u32,
    pub pairs: Vec<Pair<'t>>,
    /// Lower-case key → position, once a section has many keys (a `[1003Name]` of 254 names):
    /// keeps duplicate detection linear in the file.
    many: Option<HashMap<String, usize>>,
}

/// Sections with more keys than this get a hash index.
const LINEAR_KEYS: usize = 24;

impl<'t> Section<'t> {
    /// The pair with `key` (ASCII case ignored).
    pub fn get(&self, key: &str) -> Option<&Pair<'t>> {
        match &self.many {
            Some(m) => m.get(&key.to_ascii_lowercase()).map(|&i| &self.pairs[i]),
            None => self.pairs.iter().find(|p| p.key.eq_ignore_ascii_case(key)),
        }
    }

    fn position(&self, key: &str) -> Option<usize> {
        match &self.many {
            Some(m) => m.get(&key.to_ascii_lowercase()).copied(),
            None => self
                .pairs
                .iter()
                .position(|p| p.key.eq_ignore_ascii_case(key)),
        }
    }

    fn push(&mut self, p: Pair<'t>) {
        if let Some(m) = &mut self.many {
            m.insert(p.key.to_ascii_lowercase(), self.pairs.len());
        }
        self.pairs.push(p);
        if self.many.is_none() && self.pairs.len() > LINEAR_KEYS {
            let m = self
                .pairs
                .iter()
                .enumerate()
                .map(|(i, p)| (p.key.to_ascii_lowercase(), i))
                .collect();
            self.many = Some(m);
        }
    }
}

/// A parsed INI file.
#[derive(Debug, Default)]
pub(crate) struct Ini<'t> {
    pub sections: Vec<Section<'t>>,
    index: HashMap<SectionId, usize>,
}

impl<'t> Ini<'t> {
    /// The section `id`, if the file has it.
    pub fn get(&self, id: &SectionId) -> Option<&Section<'t>> {
        self.index.get(id).map(|&i| &self.sections[i])
    }

    /// The section named `name` (lower case), if the file has it.
    pub fn named(&self, name: &str) -> Option<&Section<'t>> {
        self.get(&SectionId::Other(name.into()))
    }
}

/// The file's bytes as text: UTF-8 as it is (a byte-order mark dropped); a line that is not
/// UTF-8 read as Latin-1, a warning.
pub(crate) fn decode<'b>(bytes: &'b [u8], rep: &mut Reporter) -> Result<Cow<'b, str>, EdsError> {
    if bytes.len() > MAX_FILE_BYTES {
        return Err(rep.error(
            rep.at(0, None, None),
            EdsErrorKind::FileTooLarge {
                max: MAX_FILE_BYTES,
            },
        ));
    }
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    if let Ok(s) = core::str::from_utf8(bytes) {
        return Ok(Cow::Borrowed(s));
    }
    let mut out = String::with_capacity(bytes.len() + bytes.len() / 8);
    for (n, line) in bytes.split_inclusive(|&b| b == b'\n').enumerate() {
        match core::str::from_utf8(line) {
            Ok(s) => out.push_str(s),
            Err(_) => {
                rep.problem(
                    rep.at(n as u32 + 1, None, None),
                    EdsErrorKind::NotUtf8,
                    "the line read as Latin-1",
                )?;
                out.extend(line.iter().map(|&b| b as char));
            }
        }
    }
    Ok(Cow::Owned(out))
}

/// Splits `text` into sections.
pub(crate) fn parse<'t>(text: &'t str, rep: &mut Reporter) -> Result<Ini<'t>, EdsError> {
    let mut ini = Ini::default();
    let mut current: Option<usize> = None;
    let mut items = 0usize;
    for (n, raw) in text.split('\n').enumerate() {
        let line = n as u32 + 1;
        if raw.len() > MAX_LINE_BYTES {
            return Err(rep.error(
                rep.at(line, None, None),
                EdsErrorKind::LineTooLong {
                    max: MAX_LINE_BYTES,
                },
            ));
        }
        let l = raw.trim();
        if l.is_empty() || l.starts_with(';') {
            continue;
        }
        let section_name = current.map(|i| ini.sections[i].name);
        if l.starts_with('#') {
            ignored(
                rep,
                rep.at(line, section_name, None),
                "a '#' comment (CiA 306 comments start with ';')",
            )?;
            continue;
        }
        items += 1;
        if items > MAX_KEYS {
            return Err(rep.error(
                rep.at(line, section_name, None),
                EdsErrorKind::TooManyKeys { max: MAX_KEYS },
            ));
        }
        if let Some(rest) = l.strip_prefix('[') {
            current = section(&mut ini, rest, line, rep)?;
            continue;
        }
        let Some((k, v)) = l.split_once('=') else {
            ignored(rep, rep.at(line, section_name, None), "a line without '='")?;
            continue;
        };
        let (key, value) = (k.trim(), v.trim());
        let Some(s) = current else {
            rep.problem(
                rep.at(line, None, Some(key)),
                EdsErrorKind::Syntax {
                    what: "a key before the first section",
                },
                "the line ignored",
            )?;
            continue;
        };
        if key.is_empty() {
            ignored(
                rep,
                rep.at(line, section_name, None),
                "a line with nothing before '='",
            )?;
            continue;
        }
        let sec = &mut ini.sections[s];
        let pair = Pair { key, value, line };
        match sec.position(key) {
            Some(i) => {
                let first = sec.pairs[i].line;
                rep.problem(
                    rep.at(line, Some(sec.name), Some(key)),
                    EdsErrorKind::DuplicateKey,
                    format_args!("{value:?}, the last one (the first is on line {first})"),
                )?;
                sec.pairs[i].value = value;
                sec.pairs[i].line = line;
            }
            None => sec.push(pair),
        }
    }
    Ok(ini)
}

/// A line that is no section, pair or comment: a warning, and the line is ignored.
fn ignored(
    rep: &mut Reporter,
    at: super::error::Location,
    what: &'static str,
) -> Result<(), EdsError> {
    rep.problem(at, EdsErrorKind::Syntax { what }, "the line ignored")
}

/// Opens the section of header line `[rest`; returns the section that keys now go to.
fn section<'t>(
    ini: &mut Ini<'t>,
    rest: &'t str,
    line: u32,
    rep: &mut Reporter,
) -> Result<Option<usize>, EdsError> {
    let Some((name, after)) = rest.split_once(']') else {
        rep.problem(
            rep.at(line, None, None),
            EdsErrorKind::Syntax {
                what: "a section header without ']'",
            },
            "the line and the keys after it ignored",
        )?;
        return Ok(None);
    };
    let name = name.trim();
    let after = after.trim();
    if !after.is_empty() && !after.starts_with(';') {
        rep.problem(
            rep.at(line, Some(name), None),
            EdsErrorKind::Syntax {
                what: "text after a section header",
            },
            "the text ignored",
        )?;
    }
    let id = SectionId::classify(name);
    if let Some(&i) = ini.index.get(&id) {
        let first = ini.sections[i].line;
        rep.problem(
            rep.at(line, Some(name), None),
            EdsErrorKind::DuplicateSection,
            format_args!("its keys merged into the section of line {first}, later values win"),
        )?;
        return Ok(Some(i));
    }
    ini.index.insert(id.clone(), ini.sections.len());
    ini.sections.push(Section {
        name,
        id,
        line,
        pairs: Vec::new(),
        many: None,
    });
    Ok(Some(ini.sections.len() - 1))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn section_names_are_classified_without_regard_to_case() {
        use SectionId::*;
        assert_eq!(SectionId::classify("1018"), Object(0x1018));
        assert_eq!(SectionId::classify("1a00"), Object(0x1A00));
        assert_eq!(SectionId::classify("1018SUB1"), Sub(0x1018, 1));
        assert_eq!(SectionId::classify("1600sub1F"), Sub(0x1600, 0x1F));
        assert_eq!(SectionId::classify("1003Name"), Names(0x1003));
        assert_eq!(SectionId::classify("100AValue"), Values(0x100A));
        assert_eq!(SectionId::classify("1000Denotation"), Denotations(0x1000));
        assert_eq!(SectionId::classify("6000objectlinks"), Links(0x6000));
        assert_eq!(
            SectionId::classify("DeviceInfo"),
            Other("deviceinfo".into())
        );
        assert_eq!(
            SectionId::classify("1018sub100"),
            Other("1018sub100".into())
        );
    }

    #[test]
    fn keys_compare_without_case_and_the_last_duplicate_wins() {
        let text = "[FileInfo]\nFileName=a.eds\n[fileinfo]\nfilename = b.eds\n";
        let mut rep = Reporter::new("t.eds", false);
        let ini = parse(text, &mut rep).unwrap();
        let s = ini.named("fileinfo").unwrap();
        assert_eq!(s.get("FILENAME").unwrap().value, "b.eds");
        assert_eq!(s.get("FileName").unwrap().line, 4);
        assert_eq!(rep.warnings.len(), 2);
        let mut strict = Reporter::new("t.eds", true);
        let e = parse(text, &mut strict).unwrap_err();
        assert_eq!(e.kind, EdsErrorKind::DuplicateSection);
        assert_eq!(e.at.line, 3);
    }

    #[test]
    fn many_keys_get_an_index_and_keep_their_order() {
        let mut text = String::from("[1003Name]\n");
        for i in 1..=100 {
            text.push_str(&alloc::format!("{i}=entry {i}\n"));
        }
        text.push_str("50=again\n");
        let mut rep = Reporter::new("t.eds", false);
        let ini = parse(&text, &mut rep).unwrap();
        let s = ini.get(&SectionId::Names(0x1003)).unwrap();
        assert_eq!(s.pairs.len(), 100);
        assert_eq!(s.get("50").unwrap().value, "again");
        assert_eq!(s.pairs[0].key, "1");
    }
}
