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
//! The files are compiled into the demo and read strictly when it starts: a mistake in them
//! stops the demo with an error naming the file, line, section and key. After the day,
//! [`configured`] checks that every board holds its rack's DCF values.

use super::Station;
use duocan::eds::{Description, EdsError, ImportOptions};
use duocan_redundancy::Member;
use std::rc::Rc;

/// The boards' EDS, by name and content (compiled in, so the demo runs from any directory).
pub const BOARD_EDS: (&str, &str) = ("io_board.eds", include_str!("../devices/io_board.eds"));
/// Each rack's DCF, in rack order (turnout, signal, track-circuit, misc).
pub const RACK_DCFS: [(&str, &str); 4] = [
    (
        "turnout_rack.dcf",
        include_str!("../devices/turnout_rack.dcf"),
    ),
    (
        "signal_rack.dcf",
        include_str!("../devices/signal_rack.dcf"),
    ),
    ("track_rack.dcf", include_str!("../devices/track_rack.dcf")),
    ("misc_rack.dcf", include_str!("../devices/misc_rack.dcf")),
];

/// The descriptions, read once and shared by the racks (a revived board builds its dictionary
/// from the same EDS).
pub struct Devices {
    /// The boards' EDS.
    pub board: Rc<Description>,
    /// Each rack's DCF.
    pub racks: [Rc<Description>; 4],
}

/// Reads one description, strictly; errors name it.
pub fn read((name, text): (&str, &str)) -> Result<Rc<Description>, EdsError> {
    Description::parse(text.as_bytes(), name, &ImportOptions::strict()).map(Rc::new)
}

impl Devices {
    /// Reads the EDS and the four DCFs.
    pub fn load() -> Result<Devices, EdsError> {
        let [a, b, c, d] = RACK_DCFS;
        Ok(Devices {
            board: read(BOARD_EDS)?,
            racks: [read(a)?, read(b)?, read(c)?, read(d)?],
        })
    }
}

/// After the day: (boards, boards holding every `ParameterValue` of their rack's DCF).
pub fn configured(st: &Station) -> (usize, usize) {
    let (mut boards, mut holding) = (0, 0);
    for (r, dcf) in st.racks.iter().zip(&st.devices.racks) {
        for p in 0..r.pairs() {
            for m in [Member::A, Member::B] {
                let node = r.board_node(p, m).raw();
                let holds = dcf.parameter_values().all(|e| {
                    let want = e.value_bytes(node);
                    let mut b = [0u8; 4];
                    let n = want.len().min(4);
                    b[..n].copy_from_slice(&want[..n]);
                    r.board_value(&st.sim, p, m, e.index, e.sub) == Some(u32::from_le_bytes(b))
                });
                boards += 1;
                holding += usize::from(holds);
            }
        }
    }
    (boards, holding)
}
