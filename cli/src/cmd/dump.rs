//! `duocan dump` (being built).

use crate::fail::Fail;
use crate::Global;

/// The arguments of `duocan dump`.
#[derive(clap::Args, Debug)]
pub struct Args {}

/// Runs `duocan dump`.
pub async fn run(_g: &Global, _a: Args) -> Result<(), Fail> {
    Err(Fail::usage("dump: not built yet"))
}
