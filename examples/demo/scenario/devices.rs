//! The station's device descriptions (`examples/demo/devices/`): every board builds its
//! dictionary from the boards' EDS, and the masters configure each rack's boards from the
//! rack's DCF.
//!
//! All boards run the same firmware, so one EDS (`io_board.eds`) describes them all; its serial
//! number is `$NODEID+0x1000`. The boards of a rack share one configuration, so one DCF per rack
//! (`turnout_rack.dcf`, …) holds it and the master applies it to each board's node-ID
//! (`SlaveConfig::from_dcf`): the heartbeat producer time (20 ms, the pair supervision's) and
//! the EMCY inhibit time (10 ms), the only `ParameterValue`s that differ from the EDS. The
//! railway racks' boards take their 29-bit identifiers from the profile (they follow from the
//! board's address, which no EDS expression can say), as before.
//!
//! The files are read strictly: a mistake in them stops the demo with an error naming the file,
//! line, section and key.

use duocan::eds::{Description, EdsError, ImportOptions};
use std::path::Path;
use std::rc::Rc;

/// Where the files are.
pub const DIR: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/demo/devices");
/// The boards' EDS.
pub const BOARD_EDS: &str = "io_board.eds";
/// Each rack's DCF, in rack order (turnout, signal, track-circuit, misc).
pub const RACK_DCFS: [&str; 4] = [
    "turnout_rack.dcf",
    "signal_rack.dcf",
    "track_rack.dcf",
    "misc_rack.dcf",
];

/// The descriptions, read once and shared by the racks (a revived board builds its dictionary
/// from the same EDS).
pub struct Devices {
    /// The boards' EDS.
    pub board: Rc<Description>,
    /// Each rack's DCF.
    pub racks: [Rc<Description>; 4],
}

fn read(name: &str) -> Result<Rc<Description>, EdsError> {
    Description::read_with(Path::new(DIR).join(name), &ImportOptions::strict()).map(Rc::new)
}

impl Devices {
    /// Reads the EDS and the four DCFs.
    pub fn load() -> Result<Devices, EdsError> {
        let board = read(BOARD_EDS)?;
        let [a, b, c, d] = RACK_DCFS;
        Ok(Devices {
            board,
            racks: [read(a)?, read(b)?, read(c)?, read(d)?],
        })
    }
}
