//! `duocan eds validate FILE...` and `duocan eds export NODE`: device descriptions checked, and
//! written from a live node.
//!
//! # validate
//!
//! Each file is read twice, as the library reads descriptions: leniently (what a real file gets
//! wrong is a warning naming the line, section and key, and the value taken instead) and
//! strictly (the first such quirk is an error). Every warning and the error, if any, is printed
//! as `FILE:LINE: [SECTION] KEY: what; taken: …`, then one verdict line per file:
//!
//! | verdict | meaning | exit |
//! |---|---|---|
//! | `ok` | both reads accept it | 0 |
//! | `N warnings` | the lenient read accepts it, the strict one stops at the first warning | 0 (1 with `--strict`) |
//! | `error` | not even the lenient read accepts it (a number that is none, a size cap) | 1 |
//! | `unreadable` | the file cannot be opened or read at all | 2 |
//!
//! The exit code is the worst of all files, so a CI step `duocan eds validate *.eds` fails on
//! any broken file; `--json` gives one object per file (`file`, `verdict`, `strict_ok`, and
//! `problems` with `level`, `line`, `section`, `key`, `message`, `taken`).
//!
//! # export
//!
//! See [`export`].

mod export;

use crate::fail::Fail;
use crate::out;
use crate::Global;
use duocan::eds::{Description, EdsErrorKind, ImportOptions, Location};
use serde_json::{json, Value};
use std::path::PathBuf;

pub use export::ExportArgs;

/// The subcommands of `duocan eds`.
#[derive(clap::Subcommand, Debug)]
pub enum Eds {
    /// Check EDS/DCF files: every warning and error with its line; exit 1 on an error, 2 if
    /// a file cannot be read
    Validate {
        /// The files
        #[arg(required = true)]
        files: Vec<PathBuf>,
        /// Warnings count as errors (exit 1)
        #[arg(long)]
        strict: bool,
    },
    /// Write a live node's dictionary, read over SDO, as an EDS (or a DCF with --as-dcf)
    Export(ExportArgs),
}

/// Runs `duocan eds`.
pub async fn run(g: &Global, c: Eds) -> Result<(), Fail> {
    match c {
        Eds::Validate { files, strict } => validate(g, &files, strict),
        Eds::Export(a) => export::run(g, a).await,
    }
}

/// How one file fared.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Verdict {
    Ok,
    Warnings,
    Error,
    Unreadable,
}

/// One problem as printed.
struct Problem {
    level: &'static str,
    at: Location,
    message: String,
    taken: Option<String>,
}

impl Problem {
    fn text(&self) -> String {
        let taken = self
            .taken
            .as_ref()
            .map(|t| format!("; taken: {t}"))
            .unwrap_or_default();
        format!("{}: {}: {}{taken}", self.at, self.level, self.message)
    }
    fn json(&self) -> Value {
        json!({
            "level": self.level,
            "line": self.at.line,
            "section": self.at.section,
            "key": self.at.key,
            "message": self.message,
            "taken": self.taken,
        })
    }
}

/// Reads one file both ways.
fn check(path: &std::path::Path) -> (Verdict, bool, Vec<Problem>) {
    let lenient = Description::read_with(path, &ImportOptions::lenient());
    let strict_ok = Description::read_with(path, &ImportOptions::strict()).is_ok();
    match lenient {
        Err(e) => {
            let verdict = if matches!(e.kind, EdsErrorKind::Io { .. }) {
                Verdict::Unreadable
            } else {
                Verdict::Error
            };
            let p = Problem {
                level: "error",
                at: *e.at,
                message: e.kind.to_string(),
                taken: None,
            };
            (verdict, strict_ok, vec![p])
        }
        Ok(d) => {
            let mut problems: Vec<Problem> = d
                .warnings
                .iter()
                .map(|w| Problem {
                    level: "warning",
                    at: w.at.clone(),
                    message: w.kind.to_string(),
                    taken: Some(w.taken.clone()),
                })
                .collect();
            if d.warnings_dropped > 0 {
                problems.push(Problem {
                    level: "warning",
                    at: Location {
                        file: d.source.clone(),
                        ..Location::default()
                    },
                    message: format!("{} more warnings not kept", d.warnings_dropped),
                    taken: None,
                });
            }
            let verdict = if problems.is_empty() && strict_ok {
                Verdict::Ok
            } else {
                Verdict::Warnings
            };
            (verdict, strict_ok, problems)
        }
    }
}

fn validate(g: &Global, files: &[PathBuf], strict: bool) -> Result<(), Fail> {
    let mut worst = Verdict::Ok;
    let mut all = Vec::new();
    for path in files {
        let (verdict, strict_ok, problems) = check(path);
        worst = worst.max(verdict);
        let name = path.display().to_string();
        let summary = match verdict {
            Verdict::Ok => "ok".to_string(),
            Verdict::Warnings => {
                let n = problems.len();
                format!(
                    "{n} warning{}, strict read {}",
                    if n == 1 { "" } else { "s" },
                    if strict_ok { "accepts it" } else { "fails" }
                )
            }
            Verdict::Error => "error".to_string(),
            Verdict::Unreadable => "unreadable".to_string(),
        };
        if g.json {
            let verdict_name = match verdict {
                Verdict::Ok => "ok",
                Verdict::Warnings => "warnings",
                Verdict::Error => "error",
                Verdict::Unreadable => "unreadable",
            };
            all.push(json!({
                "file": name,
                "verdict": verdict_name,
                "strict_ok": strict_ok,
                "problems": problems.iter().map(Problem::json).collect::<Vec<_>>(),
            }));
        } else {
            let mut text = String::new();
            for p in &problems {
                text.push_str(&p.text());
                text.push('\n');
            }
            text.push_str(&format!("{name}: {summary}\n"));
            out::print_text(&text);
        }
    }
    if g.json {
        out::emit_json(&Value::Array(all));
    }
    match worst {
        Verdict::Unreadable => Err(Fail::usage("a file could not be read")),
        Verdict::Error => Err(Fail::protocol("a description has errors")),
        Verdict::Warnings if strict => Err(Fail::protocol(
            "a description has warnings (--strict counts them as errors)",
        )),
        _ => Ok(()),
    }
}
