//! `duocan eds` (being built).

use crate::fail::Fail;
use crate::Global;

/// The subcommands of `duocan eds`.
#[derive(clap::Subcommand, Debug)]
pub enum Eds {
    /// Being built
    Show,
}

/// Runs `duocan eds`.
pub async fn run(_g: &Global, _c: Eds) -> Result<(), Fail> {
    Err(Fail::usage("eds: not built yet"))
}
