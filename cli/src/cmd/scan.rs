//! `duocan scan` (being built).

use crate::fail::Fail;
use crate::Global;

/// The arguments of `duocan scan`.
#[derive(clap::Args, Debug)]
pub struct Args {}

/// Runs `duocan scan`.
pub async fn run(_g: &Global, _a: Args) -> Result<(), Fail> {
    Err(Fail::usage("scan: not built yet"))
}
