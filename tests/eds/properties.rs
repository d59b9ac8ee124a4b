//! Random dictionaries → export → import → the same dictionary: every data type, access,
//! mappability, default (node-relative ones included), limits, capacity and name; through an
//! EDS (strict import, no warning) and, with random current values, through a DCF.

use duocan::eds::{difference, export_dcf, export_eds, Description, ExportOptions, ImportOptions};
use duocan::od::{
    comm, Access, DataType, DefaultValue, DynamicDictionary, Limit, ObjectDef, ObjectDictionary,
    ObjectType,
};
use proptest::prelude::*;

/// The raw material of one entry; [`build`] makes a valid entry of it.
#[derive(Clone, Debug)]
struct Raw {
    t: usize,
    access: u8,
    mappable: bool,
    /// Number bits of the default, and of the value.
    bits: (u64, u64),
    /// 0: no limits; else the spread of the limits around the default.
    spread: u16,
    node_relative: bool,
    name: String,
    text: (String, String),
    bytes: (Vec<u8>, Vec<u8>),
    extra: u16,
}

fn text() -> impl Strategy<Value = String> {
    "[A-Za-z0-9äöü€ _.;=#\\[\\]-]{0,24}".prop_map(|s| s.trim().to_string())
}

fn raw() -> impl Strategy<Value = Raw> {
    (
        (0..DataType::ALL.len(), 0u8..4, any::<bool>()),
        (any::<u64>(), any::<u64>()),
        (prop_oneof![Just(0u16), 1u16..1000], any::<bool>()),
        "[A-Za-z][A-Za-z0-9 _./()ü-]{0,30}",
        (text(), text()),
        (
            proptest::collection::vec(any::<u8>(), 0..12),
            proptest::collection::vec(any::<u8>(), 0..12),
        ),
        0u16..300,
    )
        .prop_map(
            |((t, access, mappable), bits, (spread, node_relative), name, text, bytes, extra)| {
                Raw {
                    t,
                    access,
                    mappable,
                    bits,
                    spread,
                    node_relative,
                    name: name.trim().to_string(),
                    text,
                    bytes,
                    extra,
                }
            },
        )
}

/// An object: its index offset (from 0x2000), a shape (0 VAR, 1 ARRAY, 2 RECORD) and entries
/// by sub-index.
type Spec = (u16, u8, Vec<(u8, Raw)>);

fn objects() -> impl Strategy<Value = Vec<Spec>> {
    proptest::collection::vec(
        (
            0u16..0xC000,
            0u8..3,
            proptest::collection::vec((1u8..=254, raw()), 1..6),
        ),
        1..12,
    )
}

/// The bytes of a number of type `t` from raw bits (booleans 0 or 1, reals finite).
fn number(t: DataType, bits: u64) -> Vec<u8> {
    let size = t.fixed_size().unwrap();
    match t {
        DataType::Boolean => vec![(bits & 1) as u8],
        DataType::Real32 => {
            let v = f32::from_bits(bits as u32);
            let v = if v.is_finite() {
                v
            } else {
                bits as u16 as f32 / 7.0
            };
            v.to_le_bytes().to_vec()
        }
        DataType::Real64 => {
            let v = f64::from_bits(bits);
            let v = if v.is_finite() {
                v
            } else {
                bits as u32 as f64 / 7.0
            };
            v.to_le_bytes().to_vec()
        }
        _ => bits.to_le_bytes()[..size].to_vec(),
    }
}

/// The value of a number's bytes, widened (signed types sign-extended).
fn widen(t: DataType, b: &[u8]) -> i128 {
    let mut buf = [0u8; 8];
    buf[..b.len()].copy_from_slice(b);
    let raw = u64::from_le_bytes(buf);
    if t.is_signed() {
        let shift = 64 - 8 * b.len() as u32;
        (((raw << shift) as i64) >> shift) as i128
    } else {
        raw as i128
    }
}

/// A string or domain value from raw text or bytes.
fn var_bytes(t: DataType, text: &str, bytes: &[u8]) -> Vec<u8> {
    match t {
        DataType::VisibleString => text.as_bytes().to_vec(),
        DataType::UnicodeString => text.encode_utf16().flat_map(u16::to_le_bytes).collect(),
        _ => bytes.to_vec(),
    }
}

/// One valid entry of `raw`, with the value to store (a DCF's `ParameterValue`).
fn build(
    index: u16,
    sub: u8,
    ot: ObjectType,
    r: &Raw,
) -> (ObjectDef, String, Option<Vec<u8>>, Vec<u8>) {
    let t = DataType::ALL[r.t];
    let access = [Access::Ro, Access::Wo, Access::Rw, Access::Const][r.access as usize];
    let mut def = ObjectDef::new(index, sub, t).access(access).object_type(ot);
    def.pdo_mappable = r.mappable;
    let Some(_) = t.fixed_size() else {
        let default = var_bytes(t, &r.text.0, &r.bytes.0);
        let value = var_bytes(t, &r.text.1, &r.bytes.1);
        def.capacity = (default.len().max(value.len()) + r.extra as usize) as u32;
        return (def, r.name.clone(), Some(default), value);
    };
    let default = number(t, r.bits.0);
    let mut value = number(t, r.bits.1);
    let integer = !t.is_real() && t != DataType::Boolean;
    if integer && r.node_relative {
        // A node-relative default (what CiA 301 COB-IDs are); a sum beyond the type wraps
        // alike on both sides.
        def = def.default(DefaultValue::NodeIdPlus(r.bits.0 as u32));
        return (def, r.name.clone(), None, value);
    }
    def = def.default(match t {
        DataType::Real32 => {
            DefaultValue::Real(f32::from_le_bytes(default[..].try_into().unwrap()) as f64)
        }
        DataType::Real64 => DefaultValue::Real(f64::from_le_bytes(default[..].try_into().unwrap())),
        _ if t.is_signed() => DefaultValue::Signed(widen(t, &default) as i64),
        _ => DefaultValue::Unsigned(widen(t, &default) as u64),
    });
    if r.spread > 0 && t != DataType::Boolean {
        // Limits around the default; the value is the default, within them.
        let low = Some(match def.default_value() {
            DefaultValue::Real(x) => Limit::Real(x - r.spread as f64),
            DefaultValue::Signed(x) => Limit::Signed(x.saturating_sub(r.spread as i64)),
            DefaultValue::Unsigned(x) => Limit::Unsigned(x.saturating_sub(r.spread as u64)),
            _ => unreachable!(),
        });
        let high = Some(match def.default_value() {
            DefaultValue::Real(x) => Limit::Real(x + r.spread as f64),
            DefaultValue::Signed(x) => Limit::Signed(x.saturating_add(r.spread as i64)),
            DefaultValue::Unsigned(x) => Limit::Unsigned(x.saturating_add(r.spread as u64)),
            _ => unreachable!(),
        });
        def = def.bounds(low, high);
        value = default;
    }
    (def, r.name.clone(), None, value)
}

/// The standard objects (for the mandatory ones) and the random ones, and the values to store.
fn dictionary(node: u8, objects: &[Spec]) -> (DynamicDictionary, Vec<(u16, u8, Vec<u8>)>) {
    let mut od = comm::standard_dictionary(node, comm::Identity::default());
    let mut values = Vec::new();
    for (offset, shape, entries) in objects {
        let index = 0x2000 + offset;
        if od.get(index, 0).is_ok() {
            continue;
        }
        let mut add = |def: ObjectDef, name: &str, default: Option<Vec<u8>>, value: Vec<u8>| {
            if od.insert_owned(def, name, default.as_deref()).is_ok() {
                values.push((def.index, def.sub, value));
            }
        };
        if *shape == 0 {
            let (def, name, default, value) = build(index, 0, ObjectType::Var, &entries[0].1);
            add(def, &name, default, value);
            continue;
        }
        let ot = if *shape == 1 {
            ObjectType::Array
        } else {
            ObjectType::Record
        };
        let highest = entries.iter().map(|(s, _)| *s).max().unwrap_or(0);
        let sub0 = ObjectDef::u8(index, 0, Access::Const, highest).object_type(ot);
        add(sub0, &entries[0].1.name, None, vec![highest]);
        for (sub, r) in entries {
            let (def, name, default, value) = build(index, *sub, ot, r);
            add(def, &name, default, value);
        }
    }
    (od, values)
}

fn import(text: &str) -> Description {
    Description::parse(text.as_bytes(), "random.eds", &ImportOptions::strict())
        .unwrap_or_else(|e| panic!("{e}\n{text}"))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn random_dictionaries_survive_an_eds(node in 1u8..=127, objects in objects()) {
        let (od, _) = dictionary(node, &objects);
        let text = export_eds(&od, &ExportOptions::default()).unwrap();
        let d = import(&text);
        prop_assert!(d.warnings.is_empty());
        let back = d.dictionary(node);
        prop_assert_eq!(difference(&od, &back), None, "{}", text);
    }

    #[test]
    fn random_values_survive_a_dcf(node in 1u8..=127, objects in objects()) {
        let (mut od, values) = dictionary(node, &objects);
        for (index, sub, v) in &values {
            od.store(*index, *sub, v).unwrap();
        }
        let text = export_dcf(&od, &ExportOptions::default()).unwrap();
        let d = import(&text);
        prop_assert_eq!(d.commissioning.as_ref().and_then(|c| c.node_id), Some(node));
        let back = d.dictionary(node);
        prop_assert_eq!(difference(&od, &back), None, "{}", text);
    }
}
