//! The compact definition gives back exactly what its builders were given.

use super::*;
use proptest::prelude::*;

fn limit() -> impl Strategy<Value = Option<Limit>> {
    prop_oneof![
        Just(None),
        any::<u64>().prop_map(|v| Some(Limit::Unsigned(v))),
        any::<i64>().prop_map(|v| Some(Limit::Signed(v))),
        any::<u64>().prop_map(|b| Some(Limit::Real(f64::from_bits(b)))),
    ]
}

fn default() -> impl Strategy<Value = DefaultValue> {
    prop_oneof![
        Just(DefaultValue::Zero),
        any::<u64>().prop_map(DefaultValue::Unsigned),
        any::<i64>().prop_map(DefaultValue::Signed),
        any::<u64>().prop_map(|b| DefaultValue::Real(f64::from_bits(b))),
        any::<u32>().prop_map(DefaultValue::NodeIdPlus),
        Just(DefaultValue::Bytes(b"abc")),
    ]
}

/// Reals compared by their bits: a NaN limit or default must come back as the same NaN.
fn same_limit(a: Option<Limit>, b: Option<Limit>) -> bool {
    match (a, b) {
        (Some(Limit::Real(x)), Some(Limit::Real(y))) => x.to_bits() == y.to_bits(),
        _ => a == b,
    }
}

fn same_default(a: DefaultValue, b: DefaultValue) -> bool {
    match (a, b) {
        (DefaultValue::Real(x), DefaultValue::Real(y)) => x.to_bits() == y.to_bits(),
        _ => a == b,
    }
}

proptest! {
    #[test]
    fn defaults_and_limits_come_back_exactly(d in default(), low in limit(), high in limit()) {
        let def = ObjectDef::new(0x2000, 1, DataType::Integer64).default(d).bounds(low, high);
        prop_assert!(same_default(def.default_value(), d));
        prop_assert!(same_limit(def.low(), low));
        prop_assert!(same_limit(def.high(), high));
        prop_assert_eq!(def.is_limited(), low.is_some() || high.is_some());
        // Setting one leaves the others as they were.
        let again = def.default(DefaultValue::Zero);
        prop_assert!(same_limit(again.low(), low));
        prop_assert!(same_limit(again.high(), high));
        let unlimited = def.bounds(None, None);
        prop_assert!(same_default(unlimited.default_value(), d));
        prop_assert!(!unlimited.is_limited());
    }
}

#[test]
fn limits_sets_both_and_debug_shows_the_values() {
    let def = ObjectDef::u16(0x2000, 0, Access::Rw, 80)
        .limits(Limit::Unsigned(0), Limit::Unsigned(250))
        .named("Speed limit");
    assert_eq!(def.low(), Some(Limit::Unsigned(0)));
    assert_eq!(def.high(), Some(Limit::Unsigned(250)));
    assert_eq!(def.default_value(), DefaultValue::Unsigned(80));
    let text = format!("{def:?}");
    assert!(text.contains("default: Unsigned(80)"), "{text}");
    assert!(text.contains("high: Some(Unsigned(250))"), "{text}");
}
