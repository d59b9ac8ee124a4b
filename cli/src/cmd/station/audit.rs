//! The station's persistent audit trail: each network's audit records (every failover, role
//! change, port verdict and LSS assignment its supervisor records) appended to a file of its
//! own, `AUDIT_DIR/NETWORK.audit`, one line each:
//!
//! ```text
//! 1765090000.125 run=1765089990000 #3 1.250000s pair 0 (A node 0x11, B node 0x21) active A -> B: …
//! ```
//!
//! (the wall-clock second of the write, the run — the station's start in Unix milliseconds —
//! and the record as the supervisor prints it: its sequence number and the network's time).
//! An operator's control action over HTTP ([`rest`](super::rest)) is a line of its own, written
//! before the operator is answered: who (the role, the client's address), what, and how it
//! ended:
//!
//! ```text
//! 1765090003.500 run=1765089990000 operator role=control-token client=127.0.0.1:50712: nmt stop node 0x50: done
//! ```
//!
//! **Durability.** A record is one `write` on a file opened for appending, then `fdatasync`:
//! once [`AuditLog::append`] returned, the record survives the station being killed (SIGKILL)
//! and the machine losing power. Only then is it acknowledged (the `written` line of the
//! `duocan::station::audit` log target, at debug level). A write cut short by a crash leaves a
//! line without its end: the next start ends it first, so that no record is glued to it.
//!
//! **Memory and size.** Nothing is kept in memory but the open file. A file that would grow
//! past `audit_max_bytes` is rotated first (`.audit` → `.audit.1` → … → `.audit.K`, the oldest
//! of `audit_keep` dropped), so the trail takes at most `(keep + 1) × max` bytes. The records
//! come from the supervisor's own bounded trail; if more happened between two reads than it
//! holds, a line says how many were overwritten before they could be written.

use std::fs::{File, OpenOptions};
use std::io::{self, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

/// One network's audit file.
pub struct AuditLog {
    path: PathBuf,
    file: File,
    size: u64,
    max: u64,
    keep: u32,
}

impl AuditLog {
    /// Opens (creates) `dir/NAME.audit` for `network`, ending a line a crash cut short.
    pub fn open(dir: &Path, network: &str, max: u64, keep: u32) -> io::Result<AuditLog> {
        std::fs::create_dir_all(dir)?;
        let path = dir.join(format!("{}.audit", file_name(network)));
        let mut file = open_append(&path)?;
        let mut size = file.metadata()?.len();
        if size > 0 {
            let mut last = [0u8];
            let mut reader = File::open(&path)?;
            reader.seek(SeekFrom::End(-1))?;
            reader.read_exact(&mut last)?;
            if last[0] != b'\n' {
                file.write_all(b"\n")?;
                file.sync_data()?;
                size += 1;
                tracing::warn!(target: "duocan::station::audit", file = %path.display(),
                    "the last record was cut short (the station stopped mid-write): ended it");
            }
        }
        Ok(AuditLog {
            path,
            file,
            size,
            max: max.max(1),
            keep,
        })
    }

    /// The file's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Appends `line` (one record, without its newline) and makes it durable.
    pub fn append(&mut self, line: &str) -> io::Result<()> {
        let mut buf = Vec::with_capacity(line.len() + 1);
        buf.extend_from_slice(line.as_bytes());
        buf.push(b'\n');
        if self.size > 0 && self.size + buf.len() as u64 > self.max {
            self.rotate()?;
        }
        self.file.write_all(&buf)?;
        self.file.sync_data()?;
        self.size += buf.len() as u64;
        Ok(())
    }

    /// `.audit.K-1` → `.audit.K`, …, `.audit` → `.audit.1`, and a new `.audit`.
    fn rotate(&mut self) -> io::Result<()> {
        let numbered = |k: u32| PathBuf::from(format!("{}.{k}", self.path.display()));
        if self.keep == 0 {
            std::fs::remove_file(&self.path)?;
        } else {
            for k in (1..self.keep).rev() {
                if numbered(k).exists() {
                    std::fs::rename(numbered(k), numbered(k + 1))?;
                }
            }
            std::fs::rename(&self.path, numbered(1))?;
        }
        self.file = open_append(&self.path)?;
        self.size = 0;
        Ok(())
    }
}

fn open_append(path: &Path) -> io::Result<File> {
    OpenOptions::new().create(true).append(true).open(path)
}

/// A network's name as a file name: letters, digits, `-` and `_` kept, the rest `_`.
pub fn file_name(network: &str) -> String {
    network
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// The wall clock as `seconds.millis` since the Unix epoch.
pub fn wall() -> String {
    let t = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap_or_default();
    format!("{}.{:03}", t.as_secs(), t.subsec_millis())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("duocan-audit-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        d
    }

    #[test]
    fn records_append_and_a_cut_line_is_ended_at_the_next_start() {
        let d = dir("cut");
        let mut log = AuditLog::open(&d, "rack 1/a", 1 << 20, 3).unwrap();
        assert!(log.path().ends_with("rack_1_a.audit"));
        log.append("one").unwrap();
        drop(log);
        // A crash mid-write: a record without its end.
        let path = d.join("rack_1_a.audit");
        let mut f = open_append(&path).unwrap();
        f.write_all(b"tw").unwrap();
        drop(f);
        let mut log = AuditLog::open(&d, "rack 1/a", 1 << 20, 3).unwrap();
        log.append("three").unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "one\ntw\nthree\n");
        let _ = std::fs::remove_dir_all(&d);
    }

    #[test]
    fn a_full_file_is_rotated_and_the_oldest_dropped() {
        let d = dir("rotate");
        // 10 bytes a file: two 4-byte records ("nnn\n") each.
        let mut log = AuditLog::open(&d, "n", 10, 2).unwrap();
        for i in 0..9 {
            log.append(&format!("{i}{i}{i}")).unwrap();
        }
        let read = |s: &str| std::fs::read_to_string(d.join(s)).unwrap_or_default();
        assert_eq!(read("n.audit"), "888\n");
        assert_eq!(read("n.audit.1"), "666\n777\n");
        assert_eq!(read("n.audit.2"), "444\n555\n");
        assert!(!d.join("n.audit.3").exists());
        let _ = std::fs::remove_dir_all(&d);
    }
}
