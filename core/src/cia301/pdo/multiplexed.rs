//! The PDO engine's MPDO side (`mpdo` feature): receiving on RPDOs whose mapping count is
//! 0xFE/0xFF, and the application's sends on TPDOs marked so. The rules are in
//! [`crate::cia301::mpdo`]; on a CANopen FD network (`fd`) the frames are FD MPDOs
//! ([`crate::cia301::mpdo::FdMpdo`]), received as classic ones are.

use super::{Io, PdoEngine, PdoEvent};
use crate::cia301::mpdo::access::{self, bump};
use crate::cia301::mpdo::{self, Mode, Mpdo, MpdoError, MpdoStats};
use crate::cia301::service::ServiceOutput;
use crate::frame::instant::Instant;
use crate::frame::storage::Storage;
use crate::frame::Id;
use crate::od::ObjectDictionary;

/// The engine's MPDO state: the node's own ID (byte 0 of its SAM frames, the destination it
/// accepts) and the consumer's counters.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct MpdoState {
    pub node: u8,
    pub stats: MpdoStats,
}

impl<const T: usize, const R: usize, S: Storage> PdoEngine<T, R, S> {
    /// The node's ID, for its MPDOs (the node sets it before every use of the engine, so an
    /// LSS change takes effect at once).
    #[inline]
    pub fn set_node(&mut self, node: u8) {
        self.mpdo.node = node;
    }

    /// What the MPDO consumer did.
    pub fn mpdo_stats(&self) -> MpdoStats {
        self.mpdo.stats
    }

    /// A frame for RPDO slot `k`, an MPDO: false (counted) when it is no MPDO's length.
    pub(super) fn mpdo_length_ok(&mut self, k: usize, len: usize) -> bool {
        if !self.rpdos[k].p.is_mpdo() || len == mpdo::LEN {
            return true;
        }
        bump(&mut self.mpdo.stats.malformed);
        false
    }

    /// A CAN FD frame for RPDO slot `k`, an MPDO: false (counted) when it is no FD MPDO's
    /// length (a CAN FD length of 8 to 64 bytes).
    #[cfg(feature = "fd")]
    pub(super) fn mpdo_fd_length_ok(&mut self, k: usize, len: usize) -> bool {
        if !self.rpdos[k].p.is_mpdo()
            || (len >= mpdo::LEN && crate::frame::fd::dlc_for_len(len).is_some())
        {
            return true;
        }
        bump(&mut self.mpdo.stats.malformed);
        false
    }

    /// Applies a received MPDO (RPDO slot `k`).
    pub(super) fn apply_mpdo<D: ObjectDictionary, O: ServiceOutput>(
        &mut self,
        k: usize,
        now: Instant,
        payload: &[u8; 8],
        io: &mut Io<'_, D, O>,
    ) {
        let Ok(m) = Mpdo::decode(payload) else {
            bump(&mut self.mpdo.stats.malformed);
            return;
        };
        self.apply_parts(k, now, (m.mode, m.node, m.index, m.sub), &m.data, io);
    }

    /// Applies a received FD MPDO (RPDO slot `k`, asynchronous): its value may be up to 60
    /// bytes, of which the object takes as many as it holds.
    #[cfg(feature = "fd")]
    pub(super) fn apply_mpdo_fd<D: ObjectDictionary, O: ServiceOutput>(
        &mut self,
        k: usize,
        now: Instant,
        data: &[u8],
        io: &mut Io<'_, D, O>,
    ) {
        let Ok(m) = mpdo::FdMpdo::decode(data) else {
            bump(&mut self.mpdo.stats.malformed);
            return;
        };
        self.apply_parts(k, now, (m.mode, m.node, m.index, m.sub), m.data(), io);
    }

    /// Applies an MPDO's header (mode, node, index, sub) and value, classic or FD.
    fn apply_parts<D: ObjectDictionary, O: ServiceOutput>(
        &mut self,
        k: usize,
        now: Instant,
        (mode, node, index, sub): (Mode, u8, u16, u8),
        value: &[u8],
        io: &mut Io<'_, D, O>,
    ) {
        let st = &mut self.mpdo.stats;
        let (index, sub) = match mode {
            Mode::Destination if node != 0 && node != self.mpdo.node => {
                bump(&mut st.other_node);
                return;
            }
            Mode::Destination => (index, sub),
            Mode::Source => match mpdo::dispatch(io.od, node, index, sub) {
                Some(local) => local,
                None => {
                    bump(&mut st.not_dispatched);
                    return;
                }
            },
        };
        let pdo = k as u16 + 1;
        match access::write(io.od, index, sub, value) {
            Ok(()) => {
                bump(&mut st.written);
                if self.rx_events {
                    io.event(now, PdoEvent::MpdoWritten { pdo, index, sub });
                }
                self.written(now, index, sub, io);
            }
            Err(reason) => {
                bump(&mut st.refused);
                io.event(
                    now,
                    PdoEvent::MpdoRefused {
                        pdo,
                        index,
                        sub,
                        reason,
                    },
                );
            }
        }
    }

    /// TPDO `pdo`'s identifier, if it is an MPDO of `mode` the engine may send now.
    fn mpdo_id(&self, pdo: u16, mode: Mode) -> Result<Id, MpdoError> {
        let t = self
            .tpdos
            .get((pdo as usize).wrapping_sub(1))
            .ok_or(MpdoError::NoSuchPdo { pdo })?;
        if t.p.mpdo != Some(mode) || t.p.error.is_some() {
            return Err(MpdoError::WrongMode { pdo });
        }
        match t.p.id {
            Some(id) if self.running => Ok(id),
            _ => Err(MpdoError::NotRunning { pdo }),
        }
    }

    /// Sends the MPDO (`mode`, `node`, `index`, `sub`, `data`) on TPDO `pdo`: classic (up to 4
    /// data bytes), or on a CANopen FD network an FD MPDO (up to 60). `BadRequest` for more
    /// data, or a header no MPDO has.
    #[allow(clippy::too_many_arguments)]
    fn mpdo_send<D, O: ServiceOutput>(
        &mut self,
        now: Instant,
        pdo: u16,
        id: Id,
        (mode, node, index, sub): (Mode, u8, u16, u8),
        data: &[u8],
        io: &mut Io<'_, D, O>,
    ) -> Result<(), MpdoError> {
        #[cfg(feature = "fd")]
        if io.out.fd_network() {
            let m = mpdo::FdMpdo::new(mode, node, index, sub, data).ok_or(MpdoError::BadRequest)?;
            io.out.send_fd(m.frame(id));
            self.tpdos[pdo as usize - 1].sent(now);
            return Ok(());
        }
        let m = match mode {
            Mode::Destination => Mpdo::dam(node, index, sub, data),
            Mode::Source => Mpdo::sam(node, index, sub, data),
        }
        .ok_or(MpdoError::BadRequest)?;
        io.out.send(m.frame(id));
        self.tpdos[pdo as usize - 1].sent(now);
        Ok(())
    }

    /// Sends a destination-address MPDO on TPDO `pdo` (mapping count 0xFF): `data` (up to 4
    /// bytes; up to 60 in an FD MPDO on a CANopen FD network) for (`index`, `sub`) of node
    /// `dest` (0: every node).
    #[allow(clippy::too_many_arguments)]
    pub fn send_dam<D, O: ServiceOutput>(
        &mut self,
        now: Instant,
        pdo: u16,
        dest: u8,
        index: u16,
        sub: u8,
        data: &[u8],
        io: &mut Io<'_, D, O>,
    ) -> Result<(), MpdoError> {
        let id = self.mpdo_id(pdo, Mode::Destination)?;
        self.mpdo_send(
            now,
            pdo,
            id,
            (Mode::Destination, dest, index, sub),
            data,
            io,
        )
    }

    /// Sends this node's (`index`, `sub`) as a source-address MPDO on TPDO `pdo` (mapping count
    /// 0xFE), if the object scanner list covers it: an object of up to 4 bytes, up to 60 in an
    /// FD MPDO on a CANopen FD network.
    pub fn send_sam<D: ObjectDictionary, O: ServiceOutput>(
        &mut self,
        now: Instant,
        pdo: u16,
        index: u16,
        sub: u8,
        io: &mut Io<'_, D, O>,
    ) -> Result<(), MpdoError> {
        let id = self.mpdo_id(pdo, Mode::Source)?;
        #[cfg(feature = "fd")]
        let mut v = [0u8; mpdo::FD_DATA_MAX];
        #[cfg(not(feature = "fd"))]
        let mut v = [0u8; mpdo::DATA_LEN];
        #[cfg(feature = "fd")]
        let room = if io.out.fd_network() {
            mpdo::FD_DATA_MAX
        } else {
            mpdo::DATA_LEN
        };
        #[cfg(not(feature = "fd"))]
        let room = mpdo::DATA_LEN;
        let n = access::read(io.od, index, sub, &mut v[..room])?;
        let me = self.mpdo.node;
        self.mpdo_send(now, pdo, id, (Mode::Source, me, index, sub), &v[..n], io)
    }
}
