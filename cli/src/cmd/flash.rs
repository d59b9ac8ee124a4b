//! `duocan flash NODE FILE [--program N] [--no-start] [--verify] [--expect-id ID]`: program
//! download as CiA 302-3 describes it, the way the library's master runs it
//! (`duocan::master` program download), from the command line.
//!
//! # The steps
//!
//! 1. stop the program: 0x1F51 sub N = 0;
//! 2. clear the staging area: 0x1F51 sub N = 3;
//! 3. the image to 0x1F50 sub N, a DOMAIN, by SDO block transfer with CRC (segmented if the
//!    node has no block transfer), streamed from the file: any size, the tool holding at most
//!    a window of it, with the progress bar (a line per tenth in a log);
//! 4. with `--verify`, 0x1F50 sub N read back and compared byte by byte, where the node lets
//!    it be read (CiA 302-3 makes program data write-only on most devices: the tool then says
//!    it could not compare, and relies on the node's own check of the image and steps 5–6);
//! 5. unless `--no-start`: start, 0x1F51 sub N = 1 (the node makes a verified staged image
//!    its program and runs it);
//! 6. 0x1F57 sub N (flash status: bit 0 busy, bits 1–7 the error code) and 0x1F56 sub N
//!    (software identification) read and shown; with `--verify`, a flash error or a program
//!    that does not run is a failure, and with `--expect-id` so is another identification.
//!
//! # Failure
//!
//! Any step that fails ends the flash there with exit 1: the step, the abort code and its
//! meaning, and the flash status the node reports. When steps 1–4 fail the tool then writes
//! reset (0x1F51 sub N = 2), as the library's master does: the node drops what it staged and
//! runs the program it had, so a failed flash never starts a half image.

use crate::args::{parse_node, parse_sub, parse_unsigned};
use crate::bus::{self, Bus};
use crate::cmd::sdo::verify::Compare;
use crate::fail::Fail;
use crate::out;
use crate::progress::Progress;
use crate::Global;
use duocan::net::{NetError, RemoteSdo};
use duocan::sdo::{SdoErrorKind, SdoOptions, TransferMode};
use duocan::{AbortCode, Duration, NodeId};
use serde_json::json;
use std::path::PathBuf;

/// 0x1F50 program data.
const PROGRAM_DATA: u16 = 0x1F50;
/// 0x1F51 program control.
const PROGRAM_CONTROL: u16 = 0x1F51;
/// 0x1F56 program software identification.
const PROGRAM_ID: u16 = 0x1F56;
/// 0x1F57 flash status identification.
const FLASH_STATUS: u16 = 0x1F57;
/// 0x1F51 commands.
const STOP: u8 = 0;
const START: u8 = 1;
const RESET: u8 = 2;
const CLEAR: u8 = 3;

/// The arguments of `duocan flash`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The node-ID (1-127)
    #[arg(value_parser = parse_node)]
    node: NodeId,
    /// The program image (any size)
    file: PathBuf,
    /// The program number: the sub-index of 0x1F50/0x1F51/0x1F56/0x1F57 (1-254)
    #[arg(long, default_value = "1", value_parser = parse_program)]
    program: u8,
    /// Do not start the program after the download (it stays stopped, the image staged)
    #[arg(long)]
    no_start: bool,
    /// Read the image back and compare where the node allows it, and fail on a flash error
    /// or a program that does not run
    #[arg(long)]
    verify: bool,
    /// The software identification (0x1F56) the new program must report; implies --verify
    #[arg(long, value_name = "ID", value_parser = parse_id)]
    expect_id: Option<u32>,
}

fn parse_program(s: &str) -> Result<u8, String> {
    let n = parse_sub(s)?;
    if n == 0 || n == 255 {
        return Err(format!("program {n}: give 1 to 254"));
    }
    Ok(n)
}

fn parse_id(s: &str) -> Result<u32, String> {
    parse_unsigned(s, "32 bits")
}

/// Runs `duocan flash`.
pub async fn run(g: &Global, a: Args) -> Result<(), Fail> {
    // The file first: a missing image is a usage error before anything is sent.
    let size = std::fs::metadata(&a.file)
        .map_err(|e| Fail::usage(format!("{}: {e}", a.file.display())))?
        .len();
    if size == 0 {
        // /dev/null, a truncated build: an empty download would erase the program for nothing.
        return Err(Fail::usage(format!(
            "{}: the image is empty: nothing to download",
            a.file.display()
        )));
    }
    let bus = bus::open(g, false)?;
    let r = flash(g, &bus, &a, size).await;
    bus.close().await;
    r
}

/// A flash status (0x1F57) in words.
fn status_text(status: u32) -> String {
    let code = (status >> 1) & 0x7F;
    let what = match code {
        0 => "no error",
        1 => "no valid program",
        2 => "data format unknown",
        3 => "data format error or checksum mismatch",
        4 => "flash not cleared before the download",
        5 => "flash write error",
        6 => "address outside the flash",
        7 => "flash secured",
        64..=127 => "manufacturer-specific error",
        _ => "reserved error code",
    };
    let busy = if status & 1 != 0 { ", in progress" } else { "" };
    format!("{what} (flash status {status:#x}, code {code}{busy})")
}

struct Flash {
    sdo: RemoteSdo,
    node: NodeId,
    n: u8,
}

impl Flash {
    fn label(&self) -> String {
        format!("flash node {:#04x} program {}", self.node.raw(), self.n)
    }

    /// A failed step, with the node's flash status if it gives one.
    async fn failed(&self, step: &str, e: NetError) -> Fail {
        let status = match self.sdo.read::<u32>(FLASH_STATUS, self.n).await {
            Ok(s) => format!("\nthe node's flash status: {}", status_text(s)),
            Err(_) => String::new(),
        };
        let hint = if e.is_no_answer() {
            "\nhint: `duocan scan` lists the nodes that answer; --timeout MS waits longer"
        } else {
            ""
        };
        Fail::protocol(format!("{}: {step}: {e}{status}{hint}", self.label()))
    }

    async fn control(&self, cmd: u8, step: &str) -> Result<(), Fail> {
        match self.sdo.write::<u8>(PROGRAM_CONTROL, self.n, cmd).await {
            Ok(()) => Ok(()),
            Err(e) => Err(self.failed(step, e).await),
        }
    }

    /// After a failed stop, clear, download or compare: back to the program the node had.
    async fn reset(&self) {
        let _ = self.sdo.write::<u8>(PROGRAM_CONTROL, self.n, RESET).await;
    }
}

async fn flash(g: &Global, bus: &Bus, a: &Args, size: u64) -> Result<(), Fail> {
    let node = a.node;
    let opts = SdoOptions::default()
        .with_timeout(Duration::from_millis(g.timeout))
        .with_mode(TransferMode::Block)
        .with_crc(true);
    let f = Flash {
        sdo: bus.net.node(node.raw()).sdo().with_options(opts),
        node,
        n: a.program,
    };
    let verify = a.verify || a.expect_id.is_some();
    f.control(STOP, "stop (0x1F51 = 0)").await?;
    if let Err(e) = f.control(CLEAR, "clear (0x1F51 = 3)").await {
        f.reset().await;
        return Err(e);
    }
    let file = tokio::fs::File::open(&a.file)
        .await
        .map_err(|e| Fail::usage(format!("{}: {e}", a.file.display())))?;
    let mut progress = Progress::new(f.label(), g.quiet);
    let sent = f
        .sdo
        .write_from(
            PROGRAM_DATA,
            a.program,
            tokio::io::BufReader::new(file),
            Some(size),
            |p| progress.update(p),
        )
        .await;
    let sent = match sent {
        Ok(n) => n,
        Err(e) => {
            let fail = f.failed("download (0x1F50)", e).await;
            f.reset().await;
            return Err(fail);
        }
    };
    let summary = progress.finish();
    let compared = if verify {
        match read_back(g, &f, &a.file, sent).await {
            Ok(c) => Some(c),
            Err(e) => {
                f.reset().await;
                return Err(e);
            }
        }
    } else {
        None
    };
    if !a.no_start {
        f.control(START, "start (0x1F51 = 1)").await?;
    }
    let status = f.sdo.read::<u32>(FLASH_STATUS, a.program).await.ok();
    let ident = f.sdo.read::<u32>(PROGRAM_ID, a.program).await.ok();
    let running = f.sdo.read::<u8>(PROGRAM_CONTROL, a.program).await.ok();
    if verify {
        if let Some(s) = status.filter(|s| (s >> 1) & 0x7F != 0) {
            return Err(Fail::protocol(format!(
                "{}: the node reports {}",
                f.label(),
                status_text(s)
            )));
        }
        if !a.no_start && running != Some(START) {
            return Err(Fail::protocol(format!(
                "{}: the program does not run after start (0x1F51 reads {})",
                f.label(),
                running.map_or("nothing".into(), |r| r.to_string())
            )));
        }
        if let Some(want) = a.expect_id {
            if ident != Some(want) {
                return Err(Fail::protocol(format!(
                    "{}: software identification {} (0x1F56), expected {want:#010x}",
                    f.label(),
                    ident.map_or("not readable".into(), |i| format!("{i:#010x}"))
                )));
            }
        }
    }
    let mut text = format!("{}: {summary} written", f.label());
    match compared {
        Some(true) => text.push_str(", read back and compared"),
        Some(false) => text.push_str(", not read back (0x1F50 is write-only on this node)"),
        None => {}
    }
    text.push_str(if a.no_start {
        ", not started"
    } else {
        ", started"
    });
    if let Some(s) = status {
        text.push_str(&format!("; {}", status_text(s)));
    }
    if let Some(i) = ident {
        text.push_str(&format!("; software identification {i:#010x}"));
    }
    out::result(
        g.json,
        &text,
        json!({
            "node": node.raw(),
            "program": a.program,
            "bytes": sent,
            "started": !a.no_start,
            "compared": compared,
            "running": running.map(|r| r == START),
            "flash_status": status,
            "identification": ident,
        }),
    );
    Ok(())
}

/// Reads 0x1F50 back and compares it with the file: `Ok(true)` compared and equal,
/// `Ok(false)` the node does not let it be read.
async fn read_back(g: &Global, f: &Flash, path: &PathBuf, sent: u64) -> Result<bool, Fail> {
    let src =
        std::fs::File::open(path).map_err(|e| Fail::usage(format!("{}: {e}", path.display())))?;
    let mut cmp = Compare::new(Box::new(std::io::BufReader::new(src)));
    let mut progress = Progress::new(format!("verify {}", f.label()), g.quiet);
    let back = f
        .sdo
        .read_to(PROGRAM_DATA, f.n, &mut cmp, |p| progress.update(p))
        .await;
    let _ = progress.finish();
    match back {
        Ok(n) => {
            cmp.check(n, sent)
                .map_err(|why| Fail::protocol(format!("{}: verify failed: {why}", f.label())))?;
            Ok(true)
        }
        Err(NetError::Sdo(e)) if matches!(e.kind, SdoErrorKind::Server(c) if c == AbortCode::WRITE_ONLY) => {
            Ok(false)
        }
        Err(e) => Err(f.failed("read back (0x1F50)", e).await),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn program_numbers_and_status_words() {
        assert_eq!(parse_program("1"), Ok(1));
        assert_eq!(parse_program("0xFE"), Ok(254));
        assert!(parse_program("0").is_err() && parse_program("255").is_err());
        assert_eq!(status_text(0), "no error (flash status 0x0, code 0)");
        assert_eq!(
            status_text(3 << 1 | 1),
            "data format error or checksum mismatch (flash status 0x7, code 3, in progress)"
        );
    }

    proptest::proptest! {
        #[test]
        fn parsers_never_panic(s in ".*") {
            let _ = parse_program(&s);
            let _ = parse_id(&s);
        }
    }
}
