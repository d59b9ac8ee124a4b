//! `duocan pdo` (being built).

use crate::fail::Fail;
use crate::Global;

/// The subcommands of `duocan pdo`.
#[derive(clap::Subcommand, Debug)]
pub enum Pdo {
    /// Being built
    Show,
}

/// Runs `duocan pdo`.
pub async fn run(_g: &Global, _c: Pdo) -> Result<(), Fail> {
    Err(Fail::usage("pdo: not built yet"))
}
