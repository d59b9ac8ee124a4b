//! `duocan record` (being built).

use crate::fail::Fail;
use crate::Global;

/// The arguments of `duocan record`.
#[derive(clap::Args, Debug)]
pub struct Args {}

/// Runs `duocan record`.
pub async fn run(_g: &Global, _a: Args) -> Result<(), Fail> {
    Err(Fail::usage("record: not built yet"))
}
