//! The master side of CiA 304: a slave's SRDOs configured over SDO during its boot, as a
//! configuration tool does it: each SRDO's parameters, mapping and checksum, then 0x13FE = 0xA5.
//!
//! The slave checks the whole configuration again when it is told to enter operational and
//! refuses (stays pre-operational, says why) if anything does not match, so a wrong checksum
//! or a mapping the slave cannot serve shows as a slave that does not start.

use super::SlaveConfig;
use crate::cia304::srdo::config::{self, SrdoConfig};

impl SlaveConfig {
    /// Writes SRDO `n` (1–64) of the slave with `cfg` over SDO, in the configuration's order,
    /// with the checksum computed here, then marks the SRDO configuration valid (0x13FE =
    /// 0xA5). For several SRDOs call it once each: every SRDO's writes void the mark on the
    /// slave, and the last call's mark comes after all of them.
    #[must_use]
    pub fn srdo(self, n: u16, cfg: &SrdoConfig) -> SlaveConfig {
        config::writes(n, cfg)
            .chain([config::mark_valid()])
            .fold(self, |s, w| s.write(w.index, w.sub, w.data()))
    }
}
