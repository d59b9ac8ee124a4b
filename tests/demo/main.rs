//! The railway station demo (`examples/demo`): the same scenario, its invariants asserted, and
//! its timeline chart.

#[path = "../../examples/demo/scenario/mod.rs"]
#[allow(dead_code)]
mod scenario;

mod devices;
mod handover;
mod replacement;
mod report_svg;
mod run;
mod stopped;
