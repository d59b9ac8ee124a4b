//! `duocan flash` (being built).

use crate::fail::Fail;
use crate::Global;

/// The arguments of `duocan flash`.
#[derive(clap::Args, Debug)]
pub struct Args {}

/// Runs `duocan flash`.
pub async fn run(_g: &Global, _a: Args) -> Result<(), Fail> {
    Err(Fail::usage("flash: not built yet"))
}
