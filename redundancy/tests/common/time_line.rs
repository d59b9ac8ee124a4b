//! What the clock-contract properties share (`link/clock_properties.rs`,
//! `supervisor/step_properties.rs`): the sizes of the steps back, and the comparison of a run on
//! a forward-only clock with the same run stepped back, its outputs moved onto the reference time
//! line.
#![allow(dead_code)]

use duocan::Duration;
use proptest::prelude::*;
use std::fmt::Debug;

const MS: u64 = 1_000;

/// A step back: mostly a few milliseconds, sometimes up to two hours.
pub fn step_size() -> impl Strategy<Value = Duration> {
    prop_oneof![
        3 => (1u64..20 * MS).prop_map(Duration::from_micros),
        1 => (1u64..7200).prop_map(Duration::from_secs),
    ]
}

/// Both runs saw the same, in the same order; the first difference is shown with what led to it.
pub fn same_time_line<T: PartialEq + Debug>(
    reference: &[T],
    stepped: &[T],
) -> Result<(), TestCaseError> {
    let first_difference = reference.iter().zip(stepped).position(|(a, b)| a != b);
    if let Some(k) = first_difference {
        let from = k.saturating_sub(6);
        prop_assert!(
            false,
            "first difference at {k}:\nreference {:#?}\nstepped   {:#?}",
            &reference[from..=k],
            &stepped[from..=k]
        );
    }
    prop_assert_eq!(reference.len(), stepped.len());
    Ok(())
}
