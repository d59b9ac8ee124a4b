//! `duocan monitor` (being built).

use crate::fail::Fail;
use crate::Global;

/// The arguments of `duocan monitor`.
#[derive(clap::Args, Debug)]
pub struct Args {}

/// Runs `duocan monitor`.
pub async fn run(_g: &Global, _a: Args) -> Result<(), Fail> {
    Err(Fail::usage("monitor: not built yet"))
}
