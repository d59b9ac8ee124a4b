//! Are two dictionaries the same device? What a round trip through a file must keep.

use super::value::canonical_limit;
use crate::od::{default_vec, DataType, Entry, Limit, ObjectDef, ObjectDictionary};
use alloc::collections::BTreeMap;
use alloc::format;
use alloc::string::String;
use alloc::vec::Vec;
use core::fmt;

/// The first place (by index and sub-index) where two dictionaries differ.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Difference {
    /// Index.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// What differs: `"entry"` (present in one only), `"name"`, `"object type"`, `"data type"`,
    /// `"access"`, `"PDO mapping"`, `"capacity"`, `"default"`, `"low limit"`, `"high limit"`,
    /// `"value"`.
    pub what: &'static str,
    /// The first dictionary's, in words.
    pub left: String,
    /// The second dictionary's, in words.
    pub right: String,
}

impl fmt::Display for Difference {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{:#06x}sub{}: {} differs: {} against {}",
            self.index, self.sub, self.what, self.left, self.right
        )
    }
}

/// One entry, copied out for comparing.
struct Seen {
    def: ObjectDef,
    name: String,
    data: Vec<u8>,
    /// The default on node-IDs 1 and 127: a node-relative default differs between them.
    defaults: [Vec<u8>; 2],
}

fn seen<D: ObjectDictionary + ?Sized>(od: &D) -> BTreeMap<(u16, u8), Seen> {
    let mut out = BTreeMap::new();
    od.for_each(&mut |e: Entry<'_>| {
        let default = |n: u8| match e.default_bytes {
            Some(d) => d.to_vec(),
            None => default_vec(e.def, n),
        };
        out.insert(
            (e.def.index, e.def.sub),
            Seen {
                def: *e.def,
                name: e.name.into(),
                data: e.data.to_vec(),
                defaults: [default(1), default(127)],
            },
        );
    });
    out
}

fn limit_text(t: DataType, l: Option<Limit>) -> String {
    match l.and_then(|l| canonical_limit(t, l)) {
        None => "none".into(),
        // Every NaN compares alike.
        Some(Limit::Real(x)) if x.is_nan() => "NaN".into(),
        Some(Limit::Real(x)) => format!("{:#x} ({x:?})", x.to_bits()),
        Some(l) => format!("{l:?}"),
    }
}

/// The first difference between `a` and `b` as a device description sees them: the same
/// entries, each with the same name, object type, data type, access, PDO mappability, capacity
/// (strings and domains), default (compared on two node-IDs, so a node-relative default must
/// be node-relative in both), limits (as the entry's type compares them) and current value.
/// Write hooks are code, not description, and are not compared. `None`: the same.
pub fn difference<A, B>(a: &A, b: &B) -> Option<Difference>
where
    A: ObjectDictionary + ?Sized,
    B: ObjectDictionary + ?Sized,
{
    let (l, r) = (seen(a), seen(b));
    let keys: alloc::collections::BTreeSet<(u16, u8)> = l.keys().chain(r.keys()).copied().collect();
    for (index, sub) in keys {
        let d = |what, left: String, right: String| {
            Some(Difference {
                index,
                sub,
                what,
                left,
                right,
            })
        };
        let (x, y) = match (l.get(&(index, sub)), r.get(&(index, sub))) {
            (Some(x), Some(y)) => (x, y),
            (x, _) => {
                let has = |v: bool| String::from(if v { "present" } else { "absent" });
                return d("entry", has(x.is_some()), has(x.is_none()));
            }
        };
        let (p, q) = (&x.def, &y.def);
        let t = p.data_type;
        let fields: [(&'static str, String, String); 10] = [
            ("name", format!("{:?}", x.name), format!("{:?}", y.name)),
            (
                "object type",
                format!("{:?}", p.object_type),
                format!("{:?}", q.object_type),
            ),
            (
                "data type",
                format!("{:?}", t),
                format!("{:?}", q.data_type),
            ),
            (
                "access",
                format!("{:?}", p.access),
                format!("{:?}", q.access),
            ),
            (
                "PDO mapping",
                format!("{}", p.pdo_mappable),
                format!("{}", q.pdo_mappable),
            ),
            (
                "capacity",
                format!("{}", t.fixed_size().map_or(p.capacity, |_| 0)),
                format!("{}", q.data_type.fixed_size().map_or(q.capacity, |_| 0)),
            ),
            (
                "default",
                format!("{:02x?}", x.defaults),
                format!("{:02x?}", y.defaults),
            ),
            (
                "low limit",
                limit_text(t, p.low()),
                limit_text(q.data_type, q.low()),
            ),
            (
                "high limit",
                limit_text(t, p.high()),
                limit_text(q.data_type, q.high()),
            ),
            (
                "value",
                format!("{:02x?}", x.data),
                format!("{:02x?}", y.data),
            ),
        ];
        for (what, left, right) in fields {
            if left != right {
                return d(what, left, right);
            }
        }
    }
    None
}
