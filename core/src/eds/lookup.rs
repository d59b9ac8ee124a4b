//! Name lookup, in a description or in any dictionary.
//!
//! A name is an address or a `ParameterName` (or a DCF's `Denotation`), without regard to case:
//!
//! - `"0x1017"`, `"1017"`: the object; for a VAR, its entry (sub-index 0);
//! - `"1017sub0"`, `"0x1018sub1"`, `"1018SUB0x1"`: the entry (sub-index in hex, as section
//!   names write it);
//! - `"Producer heartbeat time"`: the object or entry so named;
//! - `"Identity object.Vendor-ID"`: an entry of an array or record, by both names, where the
//!   entry's name alone is not unique.
//!
//! A name that several objects or entries share is [`LookupErrorKind::Ambiguous`], listing
//! them; the entries of an array that carry the array's own name do not count against it.
//! Lookups scan the description (or dictionary): they are for configuration, not the frame
//! path.

use super::error::{LookupError, LookupErrorKind};
use super::model::{Description, Object, SubObject};
use crate::od::{ObjectDictionary, ObjectType};
use alloc::format;
use alloc::string::String;
use alloc::vec::Vec;

/// Most candidates an ambiguity error lists.
const SHOWN: usize = 16;

/// `"0x1018sub1"` → (0x1018, Some(1)); `"1017"` → (0x1017, None).
fn address(name: &str) -> Option<(u16, Option<u8>)> {
    let l = name.trim().to_ascii_lowercase();
    let l = l.strip_prefix("0x").unwrap_or(&l);
    let hex = |s: &str, max: usize| {
        (!s.is_empty() && s.len() <= max && s.bytes().all(|b| b.is_ascii_hexdigit()))
            .then(|| u16::from_str_radix(s, 16).ok())
            .flatten()
    };
    match l.split_once("sub") {
        None => Some((hex(l, 4)?, None)),
        Some((i, s)) => {
            let s = s.strip_prefix("0x").unwrap_or(s);
            Some((hex(i, 4)?, Some(hex(s, 2)? as u8)))
        }
    }
}

/// Names equal without regard to case (ASCII cheaply, the rest by Unicode lower case).
fn same(a: &str, b: &str) -> bool {
    a.eq_ignore_ascii_case(b)
        || (!a.is_ascii()
            && a.chars()
                .flat_map(char::to_lowercase)
                .eq(b.chars().flat_map(char::to_lowercase)))
}

/// A match: an object (`sub: None`) or an entry.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord)]
struct Hit {
    index: u16,
    sub: Option<u8>,
    label: String,
}

#[derive(Clone)]
/// One named thing to match against: an object's name (arrays and records, or a VAR as its
/// entry) or an entry's.
struct Named<'a> {
    index: u16,
    sub: Option<u8>,
    names: [Option<&'a str>; 2],
    object_name: &'a str,
}

/// The single hit among `items` for `name`, after the same-name rule.
fn resolve<'a>(
    name: &str,
    items: impl Iterator<Item = Named<'a>> + Clone,
) -> Result<Hit, LookupError> {
    let err = |kind| LookupError {
        name: name.into(),
        kind,
    };
    let label = |n: &Named<'_>, own: &str| match n.sub {
        None => format!("0x{:04X} ({own})", n.index),
        Some(s) if own == n.object_name => format!("0x{:04X}sub{s:X} ({own})", n.index),
        Some(s) => format!("0x{:04X}sub{s:X} ({} / {own})", n.index, n.object_name),
    };
    let hit = |n: &Named<'_>, own: &str| Hit {
        index: n.index,
        sub: n.sub,
        label: label(n, own),
    };
    let target = name.trim();
    let mut hits: Vec<Hit> = items
        .clone()
        .filter_map(|n| {
            let own = n.names.iter().flatten().find(|x| same(x, target))?;
            Some(hit(&n, own))
        })
        .collect();
    if hits.is_empty() {
        // "Object.Entry": an entry named within its object.
        for (i, _) in target.match_indices('.') {
            let (o, e) = (&target[..i], &target[i + 1..]);
            hits.extend(items.clone().filter_map(|n| {
                let own = n.names.iter().flatten().find(|x| same(x, e))?;
                (n.sub.is_some() && same(n.object_name, o)).then(|| hit(&n, own))
            }));
        }
    }
    // The entries of an object that carry the object's own name are the object.
    let objects: Vec<u16> = hits
        .iter()
        .filter(|h| h.sub.is_none())
        .map(|h| h.index)
        .collect();
    if hits.len() > 1 {
        hits.retain(|h| h.sub.is_none() || !objects.contains(&h.index));
    }
    hits.sort();
    hits.dedup_by(|a, b| a.index == b.index && a.sub == b.sub);
    match hits.len() {
        0 => Err(err(LookupErrorKind::NotFound)),
        1 => Ok(hits.remove(0)),
        n => {
            let mut candidates: Vec<String> =
                hits.into_iter().take(SHOWN).map(|h| h.label).collect();
            if n > SHOWN {
                candidates.push(format!("{} more", n - SHOWN));
            }
            Err(err(LookupErrorKind::Ambiguous { candidates }))
        }
    }
}

impl Description {
    fn named(&self) -> impl Iterator<Item = Named<'_>> + Clone {
        self.objects.values().flat_map(|o| {
            let var = !o.code.has_subs();
            let object = Named {
                index: o.index,
                sub: var.then_some(0),
                names: [Some(o.name.as_str()), o.denotation.as_deref()],
                object_name: &o.name,
            };
            let subs = o.subs.values().filter(move |_| !var).map(move |s| Named {
                index: o.index,
                sub: Some(s.sub),
                names: [Some(s.name.as_str()), s.denotation.as_deref()],
                object_name: &o.name,
            });
            core::iter::once(object).chain(subs)
        })
    }

    /// The entry `name` names. A name is an address or a `ParameterName` (or a DCF's
    /// `Denotation`), without regard to case:
    ///
    /// - `"0x1017"`, `"1017"`: the object; for a VAR, its entry (sub-index 0);
    /// - `"1017sub0"`, `"0x1018sub1"`, `"1018SUB0x1"`: the entry (sub-index in hex, as section
    ///   names write it);
    /// - `"Producer heartbeat time"`: the object or entry so named;
    /// - `"Identity object.Vendor-ID"`: an entry of an array or record, by both names, where
    ///   the entry's name alone is not unique.
    ///
    /// A name several objects or entries share is [`LookupErrorKind::Ambiguous`], listing them
    /// (the entries of an array that carry the array's own name do not count against it); an
    /// array's or record's own name is [`LookupErrorKind::NotAnEntry`]. The lookup scans the
    /// description: it is for configuration, not the frame path.
    pub fn entry(&self, name: &str) -> Result<&SubObject, LookupError> {
        let not_found = || LookupError {
            name: name.into(),
            kind: LookupErrorKind::NotFound,
        };
        let (index, sub) = match address(name) {
            Some((i, Some(s))) => return self.entry_at(i, s).ok_or_else(not_found),
            Some((i, None)) => (i, None),
            None => {
                let h = resolve(name, self.named())?;
                (h.index, h.sub)
            }
        };
        let o = self.object_at(index).ok_or_else(not_found)?;
        match sub {
            Some(s) => o.subs.get(&s).ok_or_else(not_found),
            None if !o.code.has_subs() => o.subs.get(&0).ok_or_else(not_found),
            None => Err(LookupError {
                name: name.into(),
                kind: LookupErrorKind::NotAnEntry { index },
            }),
        }
    }

    /// The object `name` names: its address, its name, or the name of its entry.
    pub fn object(&self, name: &str) -> Result<&Object, LookupError> {
        let index = match address(name) {
            Some((i, _)) => i,
            None => resolve(name, self.named())?.index,
        };
        self.object_at(index).ok_or_else(|| LookupError {
            name: name.into(),
            kind: LookupErrorKind::NotFound,
        })
    }
}

/// The entry of `od` that `name` names, as (index, sub-index), by the rules of
/// [`Description::entry`]: entry names as the dictionary holds them (sub-index 0 of an array or
/// record names the object).
pub fn find<D: ObjectDictionary + ?Sized>(od: &D, name: &str) -> Result<(u16, u8), LookupError> {
    let err = |kind| LookupError {
        name: name.into(),
        kind,
    };
    let whole = |index: u16| match od.get(index, 0) {
        Ok(e) if e.def.object_type == ObjectType::Var => Ok((index, 0)),
        Ok(_) => Err(err(LookupErrorKind::NotAnEntry { index })),
        Err(_) => Err(err(LookupErrorKind::NotFound)),
    };
    match address(name) {
        Some((i, Some(s))) => od
            .get(i, s)
            .map(|_| (i, s))
            .map_err(|_| err(LookupErrorKind::NotFound)),
        Some((i, None)) => whole(i),
        None => {
            // Copied out once: a dictionary lends its entries only inside `for_each`.
            let mut all: Vec<(u16, u8, bool, String)> = Vec::new();
            od.for_each(&mut |e| {
                all.push((
                    e.def.index,
                    e.def.sub,
                    e.def.object_type == ObjectType::Var,
                    e.name.into(),
                ));
            });
            all.sort_by_key(|a| (a.0, a.1));
            let objects: alloc::collections::BTreeMap<u16, &str> = all
                .iter()
                .filter(|a| a.1 == 0)
                .map(|a| (a.0, a.3.as_str()))
                .collect();
            let object_name = |index: u16| -> &str { objects.get(&index).copied().unwrap_or("") };
            let items = all.iter().map(|(index, sub, var, n)| {
                let object = *sub == 0 && !*var;
                Named {
                    index: *index,
                    sub: (!object).then_some(*sub),
                    names: [Some(n.as_str()), None],
                    object_name: object_name(*index),
                }
            });
            let h = resolve(name, items)?;
            match h.sub {
                Some(s) => Ok((h.index, s)),
                None => whole(h.index),
            }
        }
    }
}
