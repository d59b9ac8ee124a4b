//! The `boards` key of a `[[network]]` table: the device description of a pair's A or B board,
//! an EDS or a DCF file (CiA 306), read and checked with the station file.
//!
//! ```toml
//! boards = [
//!     { node = 0x10, eds = "devices/io_board.eds" },   # relative: to the station file's folder
//!     { node = 0x50, dcf = "devices/io_board_b.dcf" },
//! ]
//! ```
//!
//! What the station does with them:
//!
//! - **names and types**: the description is attached to the node (`Network::add_node`), so
//!   REST SDO requests take an entry's name (`…/sdo/Producer%20heartbeat%20time`) and give its
//!   value typed by its data type when the request names no type;
//! - **a DCF's configuration**: every `ParameterValue` that differs from the device's default
//!   becomes an SDO write the master makes when it boots the board (the CiA 302-3
//!   configuration manager of the library, `SlaveConfig::from_dcf`, through
//!   `RedundantNetworkBuilder::member_config`), before the board is started; the heartbeat the
//!   pair supervision needs is the station's `pair_heartbeat_ms` whatever the DCF says. An EDS
//!   names only: nothing is written.
//!
//! A file is read leniently, as vendors write them: what it gets wrong is a warning (shown by
//! `duocan station check`, logged by `run`); what leaves nothing to read is an error naming the
//! EDS file, its line, section and key. A `dcf` that holds no configuration (no
//! `ParameterValue`, no `[DeviceComissioning]`) is refused (name it with `eds`), as is a DCF
//! whose `[DeviceComissioning]` `NodeID` is another node's.

use super::Source;
use duocan::eds::{Description, FileKind, ImportOptions};
use serde::Deserialize;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use toml::Spanned;

/// One `boards` entry as written.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct BoardTable {
    node: Spanned<u8>,
    eds: Option<Spanned<String>>,
    dcf: Option<Spanned<String>>,
}

/// A board's description, read and checked.
#[derive(Clone, Debug)]
pub struct Board {
    /// The board's node-ID (a pair member of its network).
    pub node: u8,
    /// The file, as the station file names it joined to that file's folder.
    pub path: PathBuf,
    /// `eds` or `dcf`: which key named it (a DCF's values are written at boot).
    pub kind: FileKind,
    /// What the file says.
    pub desc: Arc<Description>,
}

impl Board {
    /// The number of warnings the lenient reading gave (those kept and those counted).
    #[must_use]
    pub fn warnings(&self) -> usize {
        self.desc.warnings.len() + self.desc.warnings_dropped
    }
    /// The SDO writes a DCF configures the board with at boot (none for an EDS).
    #[must_use]
    pub fn writes(&self) -> usize {
        match self.kind {
            FileKind::Eds => 0,
            FileKind::Dcf => self.slave_config().map_or(0, |c| c.steps.len()),
        }
    }
    /// The master's configuration of the board from its DCF (none for an EDS).
    #[must_use]
    pub fn slave_config(&self) -> Option<duocan::master::SlaveConfig> {
        let node = duocan::NodeId::new(self.node)?;
        (self.kind == FileKind::Dcf)
            .then(|| duocan::master::SlaveConfig::from_dcf(node, &self.desc))
    }
}

/// The `boards` of a network whose pairs are `pairs`, each file read relative to the station
/// file's folder.
pub(super) fn boards(
    src: &Source<'_>,
    given: Option<&Spanned<Vec<Spanned<BoardTable>>>>,
    pairs: &[[u8; 2]],
) -> Result<Vec<Board>, String> {
    let Some(given) = given else {
        return Ok(Vec::new());
    };
    let base = Path::new(src.name)
        .parent()
        .unwrap_or(Path::new(""))
        .to_path_buf();
    let mut out: Vec<Board> = Vec::new();
    for b in given.get_ref() {
        let t = b.get_ref();
        let node = *t.node.get_ref();
        let at = t.node.span();
        if !pairs.iter().any(|p| p.contains(&node)) {
            let members: Vec<String> = pairs
                .iter()
                .flatten()
                .map(|n| format!("{n:#04x}"))
                .collect();
            let why = if members.is_empty() {
                format!("{node:#04x} is no pair member: the network has no pairs")
            } else {
                format!(
                    "{node:#04x} is no pair member: a board is one of {}",
                    members.join(", ")
                )
            };
            return Err(src.span(at, "boards: node", why));
        }
        if out.iter().any(|o| o.node == node) {
            let why = format!("{node:#04x} twice: a board has one description");
            return Err(src.span(at, "boards: node", why));
        }
        let (file, kind, key) = match (&t.eds, &t.dcf) {
            (Some(f), None) => (f, FileKind::Eds, "eds"),
            (None, Some(f)) => (f, FileKind::Dcf, "dcf"),
            (Some(_), Some(f)) => {
                let why = "eds or dcf, not both: a DCF is the EDS with this board's values";
                return Err(src.span(f.span(), "boards: dcf", why));
            }
            (None, None) => {
                let why = format!(
                    "board {node:#04x} names no file: give eds = \"FILE.eds\" (names) or \
                     dcf = \"FILE.dcf\" (names, and its values written at boot)"
                );
                return Err(src.span(b.span(), "boards", why));
            }
        };
        let name = file.get_ref().trim();
        let key_at = format!("boards: {key}");
        if name.is_empty() {
            return Err(src.span(file.span(), &key_at, "a file's path"));
        }
        let path = base.join(name);
        let desc = Description::read_with(&path, &ImportOptions::lenient())
            .map_err(|e| src.span(file.span(), &key_at, format_args!("board {node:#04x}: {e}")))?;
        if kind == FileKind::Dcf {
            if desc.kind != FileKind::Dcf {
                let why = format!(
                    "board {node:#04x}: {} is an EDS (no ParameterValue, no \
                     [DeviceComissioning]): name it with eds = \"…\", or give a DCF",
                    path.display()
                );
                return Err(src.span(file.span(), &key_at, why));
            }
            let theirs = desc.commissioning.as_ref().and_then(|c| c.node_id);
            if let Some(id) = theirs.filter(|&id| id != 0 && id != node) {
                let why = format!(
                    "board {node:#04x}: {} configures node {id:#04x} ([DeviceComissioning] \
                     NodeID): a DCF is one node's",
                    path.display()
                );
                return Err(src.span(file.span(), &key_at, why));
            }
        }
        out.push(Board {
            node,
            path,
            kind,
            desc: Arc::new(desc),
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::super::parse;
    use std::path::PathBuf;

    /// A folder of its own for test `name`, holding `files`.
    fn dir(name: &str, files: &[(&str, &str)]) -> PathBuf {
        let d = std::env::temp_dir().join(format!("duocan-boards-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        for (f, text) in files {
            std::fs::write(d.join(f), text).unwrap();
        }
        d
    }

    const DCF: &str = include_str!("../../../../tests/station_files/board.dcf");
    const HEAD: &str = "[[network]]\nname = \"a\"\nbuses = \"sim-pairs\"\nnode_id = 1\n\
                        pairs = [[0x10, 0x50]]\n";

    /// The station `text` in folder `d`, parsed.
    fn parse_in(d: &std::path::Path, text: &str) -> Result<super::super::Station, String> {
        let name = d.join("s.toml").display().to_string();
        parse(text, &name).map_err(|e| e.replace(&name, "s.toml"))
    }

    #[test]
    fn an_eds_and_a_dcf_are_read_and_the_dcf_configures_its_board() {
        let d = dir("good", &[("a.dcf", DCF), ("b.eds", DCF)]);
        let text = format!(
            "{HEAD}boards = [{{ node = 0x10, dcf = \"a.dcf\" }}, {{ node = 0x50, eds = \"b.eds\" }}]\n"
        );
        let st = parse_in(&d, &text).unwrap();
        let b = &st.networks[0].boards;
        assert_eq!(b.len(), 2);
        assert_eq!((b[0].node, b[0].kind), (0x10, duocan::eds::FileKind::Dcf));
        assert_eq!(b[0].path, d.join("a.dcf"));
        // Output 1 differs from its default: one write; the EDS (a DCF named as one) none.
        assert_eq!(b[0].writes(), 1);
        assert_eq!(b[1].writes(), 0);
        assert!(b[1].slave_config().is_none());
        assert_eq!(b[0].warnings(), 0);
        assert_eq!(b[1].desc.entry("Output 1").unwrap().index, 0x6200);
    }

    #[test]
    fn each_error_names_the_key_and_what_is_allowed() {
        let d = dir(
            "bad",
            &[
                ("a.dcf", DCF),
                (
                    "eds.eds",
                    &DCF.replace("ParameterValue=0x1234\n", "")
                        .replace("[DeviceComissioning]\nNodeID=0x10\nNodeName=board A\n", ""),
                ),
                ("bad.eds", &DCF.replace("DataType=0x0006", "DataType=zz")),
                ("none.ini", "[Foo]\nbar=1\n"),
            ],
        );
        let err = |boards: &str| {
            let e = parse_in(&d, &format!("{HEAD}boards = [{boards}]\n")).unwrap_err();
            assert!(e.starts_with("s.toml:6:"), "{e}");
            e
        };
        let e = err("{ node = 0x12, eds = \"a.dcf\" }");
        assert!(
            e.contains("boards: node: 0x12 is no pair member: a board is one of 0x10, 0x50"),
            "{e}"
        );
        let e = err("{ node = 0x10, eds = \"a.dcf\" }, { node = 0x10, eds = \"a.dcf\" }");
        assert!(e.contains("boards: node: 0x10 twice"), "{e}");
        let e = err("{ node = 0x10, eds = \"a.dcf\", dcf = \"a.dcf\" }");
        assert!(e.contains("boards: dcf: eds or dcf, not both"), "{e}");
        let e = err("{ node = 0x10 }");
        assert!(
            e.contains("boards: board 0x10 names no file: give eds"),
            "{e}"
        );
        let e = err("{ node = 0x10, eds = \" \" }");
        assert!(e.contains("boards: eds: a file's path"), "{e}");
        // The file: missing, broken (its own line, section and key), of the wrong kind or node.
        let e = err("{ node = 0x10, eds = \"none.eds\" }");
        assert!(
            e.contains("boards: eds: board 0x10: ") && e.contains("none.eds"),
            "{e}"
        );
        assert!(e.contains("cannot read the file"), "{e}");
        let e = err("{ node = 0x10, eds = \"none.ini\" }");
        assert!(e.contains("none.ini: not a device description"), "{e}");
        let e = err("{ node = 0x10, dcf = \"eds.eds\" }");
        assert!(
            e.contains("boards: dcf: board 0x10: ") && e.contains("is an EDS"),
            "{e}"
        );
        let e = err("{ node = 0x50, dcf = \"a.dcf\" }");
        assert!(e.contains("configures node 0x10"), "{e}");
        // What a lenient reading takes is a warning that says where, not an error.
        let st = parse_in(
            &d,
            &format!("{HEAD}boards = [{{ node = 0x10, eds = \"bad.eds\" }}]\n"),
        )
        .unwrap();
        let w = st.networks[0].boards[0].desc.warnings[0].to_string();
        assert!(w.contains("bad.eds:85: [6200sub1] DataType"), "{w}");
        // An unknown key: the TOML reader lists the known ones.
        let e = parse_in(
            &d,
            &format!("{HEAD}boards = [{{ node = 0x10, edf = \"a\" }}]\n"),
        )
        .unwrap_err();
        assert!(
            e.starts_with("s.toml:6:") && e.contains("eds") && e.contains("dcf"),
            "{e}"
        );
        // Bad input of any kind is an error, never a panic.
        for junk in ["{ node = 300 }", "1", "{ node = 0x10, eds = 5 }", "\"x\""] {
            let r = parse_in(&d, &format!("{HEAD}boards = [{junk}]\n"));
            assert!(r.is_err(), "{junk}");
        }
    }
}
