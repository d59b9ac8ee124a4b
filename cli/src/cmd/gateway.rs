//! `duocan gateway` (being built).

use crate::fail::Fail;
use crate::Global;

/// The arguments of `duocan gateway`.
#[derive(clap::Args, Debug)]
pub struct Args {}

/// Runs `duocan gateway`.
pub async fn run(_g: &Global, _a: Args) -> Result<(), Fail> {
    Err(Fail::usage("gateway: not built yet"))
}
