//! Process data objects: the PDO engine a [`crate::node::Node`] runs, the parameter tables, and
//! the master side that configures a slave's PDOs over SDO.
//!
//! The engine reads everything from the dictionary: communication parameters (0x1400–0x15FF,
//! 0x1800–0x19FF) and mappings (0x1600–0x17FF, 0x1A00–0x1BFF). A node with capacity for `T`
//! TPDOs and `R` RPDOs serves TPDO1–T and RPDO1–R; parameter objects of higher numbers may exist
//! in the dictionary but are inert. PDOs are numbered from 1 as CiA 301 names them: RPDO1 is
//! 0x1400/0x1600, TPDO3 is 0x1802/0x1A02.
//!
//! Writes to the parameters follow CiA 301 (checked by the node before they are stored):
//! - a valid PDO's identifier (COB-ID bits 0–29) cannot change: invalidate it first (0x06090030);
//!   11-bit identifiers CiA 301 restricts (NMT, SYNC/TIME/EMCY ranges, SDO, error control) are
//!   refused (0x06090030);
//! - transmission types 241–251 (TPDO) and 241–253 (RPDO) are reserved (0x06090030); RTR-only
//!   types need bit 30 (no RTR) clear (0x06090030);
//! - inhibit time and SYNC start value change only while the PDO is invalid (0x06090030);
//! - mapping entries change only while the PDO is invalid and sub 0 is 0, sub 0 only while the
//!   PDO is invalid (0x06090030, as CANopenNode and Lely answer); each entry must exist
//!   (0x06020000/0x06090011), be mappable in that direction with a length it can hold
//!   (0x06040041); sub 0 = n checks entries 1..n and their total against 64 bits, 512 on a
//!   CANopen FD network (0x06040042).
//!
//! **CAN FD (feature `fd`).** An engine told it is on a CANopen FD network (the node's
//! `NodeConfig::fd`) checks mappings against 512 bits instead of 64 (0x06040042 beyond), sends
//! every TPDO as a CAN FD frame and takes RPDOs from CAN FD frames (classic frames on an RPDO's
//! identifier are still taken, as a classic frame holds a PDO of up to 8 bytes). A TPDO of `n`
//! mapped bytes goes in the shortest CAN FD frame that holds them: 20 bytes in a 20-byte frame,
//! 21 in a 24-byte one, the padding bytes 0xCC (CiA 1301's padding, as the USDO frames have; a
//! receiver ignores them, as it ignores the extra bytes of a frame longer than its mapping). The frames wait in
//! the node's CAN FD queue, apart from the classic one: a TPDO and a classic frame queued at
//! the same time may leave in either order. An RPDO frame shorter than its mapping is refused as
//! on the classic path (EMCY 0x8210). MPDOs (feature `mpdo`) travel as FD MPDOs there
//! ([`crate::cia301::mpdo`] says which layout and why): the application's sends go in CAN FD
//! frames, an MPDO receiver takes them (and classic MPDOs still).
//! A synchronous RPDO or a type-252 TPDO longer than 8 bytes keeps its payload in a bounded
//! table shared by the engine (the `wide` module says why and what happens when it is full).
//!
//! Dummy entries (index 0x0001–0x001B of a supported fixed-size type, sub 0) are placeholders:
//! skipped on reception, zeros on transmission.
//!
//! With the `mpdo` feature, a mapping count of 0xFE or 0xFF (accepted while the PDO is
//! invalid, its entries then unused and unchecked) makes the PDO a multiplexed PDO, which the
//! `cia301::mpdo` module describes; without it those counts are refused as any above 64.

mod dictionary;
mod events;
mod index;
pub(crate) mod mapping;
#[cfg(feature = "mpdo")]
mod multiplexed;
pub mod params;
mod rpdo;
mod tpdo;
#[cfg(feature = "fd")]
mod wide;

pub use mapping::{
    check_entry, check_mapping, check_mapping_within, mask, read_bits, write_bits, Dir, MapEntry,
    MAX_BITS, MAX_ENTRIES,
};
#[cfg(feature = "fd")]
pub use mapping::{read_bits_wide, write_bits_wide, FD_MAX_BITS};
#[cfg(feature = "fd")]
pub use wide::WIDE_PAYLOADS;

use crate::cia301::emcy;
use crate::cia301::service::{ServiceEvent, ServiceOutput};
use crate::frame::instant::{earliest, Duration, Instant};
use crate::frame::queue::Bounded;
use crate::frame::storage::{BoundedVec, Inline, Storage, Table};
#[cfg(feature = "fd")]
use crate::frame::FdFrame;
use crate::frame::{Frame, Id};
use crate::od::abort::AbortCode;
use crate::od::{key, ObjectDictionary};
pub use dictionary::restricted_id;
pub(crate) use dictionary::{check_write, classify};
use dictionary::{map_index, read_rpdo, read_tpdo};
pub use events::{PdoError, PdoEvent, RpdoStatus, TpdoStatus};
use index::{equal_range, id_key, Reverse};
use rpdo::{OnFrame, Recovered, Rpdo};
use tpdo::{OnRtr, OnSync, Tpdo};

/// Whether a PDO's new parameters let it run on as it was (else it restarts): the same
/// identifier, transmission type, mapping and error, and (`mpdo`) the same kind, classic or
/// MPDO of one mode. Two versions so that an image without the feature is built as it was.
#[cfg(feature = "mpdo")]
macro_rules! same_run {
    ($new:ident, $old:ident) => {
        $new.id == $old.id
            && $new.mpdo == $old.mpdo
            && $new.ttype == $old.ttype
            && $new.mapping == $old.mapping
            && $new.error == $old.error
    };
}
#[cfg(not(feature = "mpdo"))]
macro_rules! same_run {
    ($new:ident, $old:ident) => {
        $new.id == $old.id
            && $new.ttype == $old.ttype
            && $new.mapping == $old.mapping
            && $new.error == $old.error
    };
}

/// An EMCY the engine wants the node to raise or clear.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum EmcyAction {
    Raise(u16, [u8; 5]),
    Clear(u16),
}

/// The dictionary and the output the engine works with while it runs.
pub(crate) struct Io<'a, D, O> {
    pub od: &'a mut D,
    pub out: O,
}

impl<D, O: ServiceOutput> Io<'_, D, O> {
    fn send(&mut self, id: Id, data: &[u8]) {
        if let Ok(f) = Frame::new(id, data) {
            self.out.send(f);
        }
    }
    fn event(&mut self, at: Instant, e: PdoEvent) {
        self.out.event(at, ServiceEvent::Pdo(e));
    }
    /// A CAN FD frame of `data`, padded with 0xCC up to the next CAN FD length.
    #[cfg(feature = "fd")]
    fn send_fd(&mut self, id: Id, data: &[u8]) {
        if let Ok(f) = FdFrame::padded(id, data, 0xCC) {
            self.out.send_fd(f);
        }
    }
}

/// The PDO engine of a node: `T` TPDOs and `R` RPDOs inline, or as many as it was built with on
/// the heap.
pub(crate) struct PdoEngine<const T: usize, const R: usize, S: Storage = Inline> {
    tpdos: Table<Tpdo, T, S>,
    rpdos: Table<Rpdo, R, S>,
    rx_index: S::Vec<(u32, u16), R>,
    tx_index: S::Vec<(u32, u16), T>,
    reverse: Reverse<S, T>,
    running: bool,
    /// No engine deadline is earlier than this (it may be early: a lower bound, made exact at
    /// the next timeout, so that a reception costs O(1) however many RPDOs there are).
    next: Option<Instant>,
    rx_events: bool,
    emcy: Bounded<EmcyAction, 8>,
    timeouts: u16,
    shorts: u16,
    #[cfg(feature = "mpdo")]
    mpdo: multiplexed::MpdoState,
    /// On a CANopen FD network (`Some`): PDOs of up to 64 bytes in CAN FD frames, and the
    /// payloads of the wide ones that wait for a SYNC or an RTR.
    #[cfg(feature = "fd")]
    wide: Option<wide::WideHolder>,
}

impl<const T: usize, const R: usize, S: Storage> PdoEngine<T, R, S> {
    /// An engine for `tpdos` TPDOs and `rpdos` RPDOs (inline storage: `T` and `R`).
    #[must_use]
    pub fn new(tpdos: usize, rpdos: usize) -> Self {
        PdoEngine {
            tpdos: Table::new(tpdos, Tpdo::new),
            rpdos: Table::new(rpdos, Rpdo::new),
            rx_index: S::vec(rpdos),
            tx_index: S::vec(tpdos),
            reverse: Reverse::new(tpdos),
            running: false,
            next: None,
            rx_events: true,
            emcy: Bounded::new(),
            timeouts: 0,
            shorts: 0,
            #[cfg(feature = "mpdo")]
            mpdo: multiplexed::MpdoState::default(),
            #[cfg(feature = "fd")]
            wide: None,
        }
    }

    /// The engine is on a CANopen FD network (or not): the PDO parameters are read again at
    /// the next [`PdoEngine::load_all`] against the frame this gives.
    #[cfg(feature = "fd")]
    pub fn set_fd(&mut self, fd: bool) {
        if fd != self.wide.is_some() {
            self.wide = fd.then(wide::holder);
        }
    }

    /// Wide payloads (synchronous CAN FD PDOs beyond 8 bytes) dropped because the engine's
    /// table was full; 0 on a classic network.
    #[cfg(feature = "fd")]
    pub fn wide_dropped(&self) -> u32 {
        self.wide.as_ref().map_or(0, |w| w.dropped())
    }

    /// The longest mapping a PDO of this engine may have: 64 bits, or 512 on a CANopen FD
    /// network.
    #[inline(always)]
    pub fn max_bits(&self) -> u32 {
        #[cfg(feature = "fd")]
        if self.wide.is_some() {
            return mapping::FD_MAX_BITS;
        }
        MAX_BITS
    }

    /// TPDOs the engine runs (TPDO1 up to this).
    pub fn tpdo_capacity(&self) -> usize {
        self.tpdos.len()
    }

    /// RPDOs the engine runs (RPDO1 up to this).
    pub fn rpdo_capacity(&self) -> usize {
        self.rpdos.len()
    }

    pub fn set_rx_events(&mut self, on: bool) {
        self.rx_events = on;
    }

    pub fn take_emcy(&mut self) -> Option<EmcyAction> {
        self.emcy.pop()
    }

    #[must_use]
    pub fn poll_timeout(&self) -> Option<Instant> {
        if self.running {
            self.next
        } else {
            None
        }
    }

    fn note(&mut self, t: Option<Instant>) {
        self.next = earliest(self.next, t);
    }

    /// RPDO `pdo` came shorter than its mapping, the first of an episode: the event, and the
    /// length EMCY (0x8210) counted once per episode.
    fn too_short<D: ObjectDictionary, O: ServiceOutput>(
        &mut self,
        now: Instant,
        io: &mut Io<'_, D, O>,
        pdo: u16,
        expected: u8,
        got: u8,
    ) {
        io.event(now, PdoEvent::RpdoTooShort { pdo, expected, got });
        Self::count_episode(
            &mut self.shorts,
            &mut self.emcy,
            emcy::code::PDO_LENGTH,
            true,
            pdo,
        );
    }

    fn count_episode(
        counter: &mut u16,
        emcy: &mut Bounded<EmcyAction, 8>,
        code: u16,
        open: bool,
        pdo: u16,
    ) {
        if open {
            *counter += 1;
            if *counter == 1 {
                let b = pdo.to_le_bytes();
                emcy.push(EmcyAction::Raise(code, [b[0], b[1], 0, 0, 0]));
            }
        } else {
            *counter = counter.saturating_sub(1);
            if *counter == 0 {
                emcy.push(EmcyAction::Clear(code));
            }
        }
    }

    fn recovered(&mut self, rec: Recovered, pdo: u16) {
        if rec.length {
            Self::count_episode(
                &mut self.shorts,
                &mut self.emcy,
                emcy::code::PDO_LENGTH,
                false,
                pdo,
            );
        }
        if rec.timeout {
            Self::count_episode(
                &mut self.timeouts,
                &mut self.emcy,
                emcy::code::RPDO_TIMEOUT,
                false,
                pdo,
            );
        }
    }

    fn rebuild_indexes<D: ObjectDictionary + ?Sized>(&mut self, od: &D) {
        self.rx_index.clear();
        for (k, r) in self.rpdos.iter().enumerate() {
            if let (true, Some(id)) = (r.p.active(), r.p.id) {
                let _ = self.rx_index.try_push((id_key(id), k as u16));
            }
        }
        index::sort_pairs(&mut self.rx_index);
        self.tx_index.clear();
        for (k, t) in self.tpdos.iter().enumerate() {
            if let (true, Some(id)) = (t.p.active(), t.p.id) {
                let _ = self.tx_index.try_push((id_key(id), k as u16));
            }
        }
        index::sort_pairs(&mut self.tx_index);
        self.reverse.rebuild(&self.tpdos, od);
    }

    /// Reads every PDO's parameters (boot, reset communication). Nothing runs until
    /// [`PdoEngine::start`].
    pub fn load_all<D: ObjectDictionary, O: ServiceOutput>(
        &mut self,
        now: Instant,
        io: &mut Io<'_, D, O>,
    ) {
        self.stop();
        for k in 0..self.tpdos.len() {
            let p = read_tpdo(io.od, k as u16, self.max_bits());
            report(io, now, Dir::Transmit, k, p.id, p.error);
            self.tpdos[k].p = p;
        }
        for k in 0..self.rpdos.len() {
            let p = read_rpdo(io.od, k as u16, self.max_bits());
            report(io, now, Dir::Receive, k, p.id, p.error);
            self.rpdos[k].p = p;
        }
        self.rebuild_indexes(io.od);
    }

    /// Re-reads one PDO after a write to its parameters.
    pub fn reload<D: ObjectDictionary, O: ServiceOutput>(
        &mut self,
        now: Instant,
        dir: Dir,
        slot: u16,
        io: &mut Io<'_, D, O>,
    ) {
        let k = slot as usize;
        match dir {
            Dir::Transmit if k < self.tpdos.len() => {
                let new = read_tpdo(io.od, slot, self.max_bits());
                let t = &mut self.tpdos[k];
                let old = t.p;
                if new == old {
                    return;
                }
                report(io, now, dir, k, new.id, new.error);
                let same_run = same_run!(new, old) && new.sync_start == old.sync_start;
                if same_run {
                    if new.event_timer != old.event_timer {
                        t.retime(now, new);
                    } else {
                        t.p = new;
                    }
                } else {
                    t.stop();
                    t.p = new;
                    #[cfg(feature = "fd")]
                    if let Some(w) = &mut self.wide {
                        w.take(wide::tx_key(k));
                    }
                    if self.running {
                        t.start(now);
                    }
                    self.rebuild_indexes(io.od);
                }
                self.service_tpdo(k, now, io);
            }
            Dir::Receive if k < self.rpdos.len() => {
                let new = read_rpdo(io.od, slot, self.max_bits());
                let old = self.rpdos[k].p;
                if new == old {
                    return;
                }
                report(io, now, dir, k, new.id, new.error);
                if same_run!(new, old) {
                    self.rpdos[k].p = new;
                } else {
                    let rec = self.rpdos[k].stop();
                    self.recovered(rec, k as u16 + 1);
                    self.rpdos[k].p = new;
                    #[cfg(feature = "fd")]
                    if let Some(w) = &mut self.wide {
                        w.take(wide::rx_key(k));
                    }
                    if self.running {
                        self.rpdos[k].start();
                    }
                    self.rebuild_indexes(io.od);
                }
            }
            _ => {}
        }
    }

    /// Entering operational: PDOs start; event-driven TPDOs send their current values.
    pub fn start<D: ObjectDictionary, O: ServiceOutput>(
        &mut self,
        now: Instant,
        io: &mut Io<'_, D, O>,
    ) {
        self.running = true;
        self.next = None;
        for t in self.tpdos.iter_mut() {
            t.start(now);
        }
        for r in self.rpdos.iter_mut() {
            r.start();
        }
        self.service(now, io);
    }

    /// Leaving operational: everything stops, buffered data is dropped, open errors cleared.
    pub fn stop(&mut self) {
        self.running = false;
        self.next = None;
        #[cfg(feature = "fd")]
        if let Some(w) = &mut self.wide {
            w.clear();
        }
        for t in self.tpdos.iter_mut() {
            t.stop();
        }
        for k in 0..self.rpdos.len() {
            let rec = self.rpdos[k].stop();
            self.recovered(rec, k as u16 + 1);
        }
    }

    fn send_tpdo<D: ObjectDictionary, O: ServiceOutput>(
        &mut self,
        k: usize,
        now: Instant,
        io: &mut Io<'_, D, O>,
    ) {
        #[cfg(feature = "fd")]
        if self.wide.is_some() {
            return self.send_tpdo_fd(k, now, io);
        }
        let t = &mut self.tpdos[k];
        let Some(id) = t.p.id else { return };
        let mut buf = [0u8; 8];
        let n =
            t.p.mapping
                .pack(io.od, map_index(Dir::Transmit, k as u16), &mut buf);
        io.send(id, &buf[..n as usize]);
        t.sent(now);
        let d = t.deadline();
        self.note(d);
    }

    /// Sends TPDO `k` in a CAN FD frame (up to 64 bytes, padded with 0xCC).
    #[cfg(feature = "fd")]
    fn send_tpdo_fd<D: ObjectDictionary, O: ServiceOutput>(
        &mut self,
        k: usize,
        now: Instant,
        io: &mut Io<'_, D, O>,
    ) {
        let t = &mut self.tpdos[k];
        let Some(id) = t.p.id else { return };
        let mut buf = [0u8; 64];
        let n =
            t.p.mapping
                .pack_wide(io.od, map_index(Dir::Transmit, k as u16), &mut buf);
        io.send_fd(id, &buf[..n as usize]);
        t.sent(now);
        let d = t.deadline();
        self.note(d);
    }

    /// Sends TPDO `k` if it is due at `now`, else records when it will be.
    fn service_tpdo<D: ObjectDictionary, O: ServiceOutput>(
        &mut self,
        k: usize,
        now: Instant,
        io: &mut Io<'_, D, O>,
    ) {
        if self.tpdos[k].due(now) {
            self.send_tpdo(k, now, io);
        } else {
            let d = self.tpdos[k].deadline();
            self.note(d);
        }
    }

    /// Everything due at `now`; then the exact next deadline.
    fn service<D: ObjectDictionary, O: ServiceOutput>(
        &mut self,
        now: Instant,
        io: &mut Io<'_, D, O>,
    ) {
        let mut next = None;
        for k in 0..self.tpdos.len() {
            if self.tpdos[k].due(now) {
                self.send_tpdo(k, now, io);
            }
            next = earliest(next, self.tpdos[k].deadline());
        }
        for k in 0..self.rpdos.len() {
            if let Some(last) = self.rpdos[k].due(now) {
                let pdo = k as u16 + 1;
                io.event(now, PdoEvent::RpdoTimeout { pdo, last });
                Self::count_episode(
                    &mut self.timeouts,
                    &mut self.emcy,
                    emcy::code::RPDO_TIMEOUT,
                    true,
                    pdo,
                );
            }
            next = earliest(next, self.rpdos[k].deadline());
        }
        self.next = next;
    }

    /// The caller's clock stepped back `by` (the clock contract, [`crate::frame::instant`]):
    /// event timers, reception timeouts and inhibit times keep what they have left to run.
    pub fn step_back(&mut self, by: Duration) {
        for t in self.tpdos.iter_mut() {
            t.step_back(by);
        }
        for r in self.rpdos.iter_mut() {
            r.step_back(by);
        }
        // The bound is made exact by the timeout this causes: a timer that saturated at the end
        // of time was "never" in it, and is a real deadline once moved back.
        self.next = Some(Instant::ZERO);
    }

    /// Time passed.
    pub fn handle_timeout<D: ObjectDictionary, O: ServiceOutput>(
        &mut self,
        now: Instant,
        io: &mut Io<'_, D, O>,
    ) {
        if !self.running || self.next.is_none_or(|t| t > now) {
            return;
        }
        self.service(now, io);
    }

    /// A SYNC was received or produced: synchronous RPDOs take effect, synchronous TPDOs go.
    pub fn on_sync<D: ObjectDictionary, O: ServiceOutput>(
        &mut self,
        now: Instant,
        counter: Option<u8>,
        io: &mut Io<'_, D, O>,
    ) {
        if !self.running {
            return;
        }
        for k in 0..self.rpdos.len() {
            if let Some(b) = self.rpdos[k].buffered.take() {
                #[cfg(feature = "fd")]
                if let Some(w) = &mut self.wide {
                    if self.rpdos[k].p.mapping.bits() > MAX_BITS {
                        if let Some(p) = w.take(wide::rx_key(k)) {
                            self.apply_wide(k, now, &p, io);
                        }
                        continue;
                    }
                }
                self.apply(k, now, &b, io);
            }
        }
        for k in 0..self.tpdos.len() {
            match self.tpdos[k].on_sync(counter) {
                OnSync::Nothing => {}
                OnSync::Send => self.send_tpdo(k, now, io),
                OnSync::Sample => {
                    let t = &mut self.tpdos[k];
                    #[cfg(feature = "fd")]
                    if let (Some(w), true) = (&mut self.wide, t.p.mapping.bits() > MAX_BITS) {
                        let mut buf = [0u8; 64];
                        t.p.mapping
                            .pack_wide(io.od, map_index(Dir::Transmit, k as u16), &mut buf);
                        // The inline 8 bytes only say "sampled"; the table holds the payload.
                        t.sampled = w.put(wide::tx_key(k), &buf).then_some([0; 8]);
                        continue;
                    }
                    let mut buf = [0u8; 8];
                    t.p.mapping
                        .pack(io.od, map_index(Dir::Transmit, k as u16), &mut buf);
                    t.sampled = Some(buf);
                }
            }
        }
    }

    /// Writes an RPDO payload into the dictionary; mapped writes trigger TPDOs as any write.
    fn apply<D: ObjectDictionary, O: ServiceOutput>(
        &mut self,
        k: usize,
        now: Instant,
        payload: &[u8; 8],
        io: &mut Io<'_, D, O>,
    ) {
        #[cfg(feature = "mpdo")]
        if self.rpdos[k].p.is_mpdo() {
            return self.apply_mpdo(k, now, payload, io);
        }
        let m = self.rpdos[k].p.mapping;
        let track = !self.reverse.is_empty();
        let mut keys: heapless::Vec<(u16, u8), { MAX_ENTRIES as usize }> = heapless::Vec::new();
        m.unpack(io.od, map_index(Dir::Receive, k as u16), payload, |i, s| {
            if track {
                let _ = keys.push((i, s));
            }
        });
        if self.rx_events {
            io.event(now, PdoEvent::RpdoReceived { pdo: k as u16 + 1 });
        }
        for (i, s) in keys {
            self.written(now, i, s, io);
        }
    }

    /// [`PdoEngine::apply`] for a payload of up to 64 bytes (a CAN FD frame, or any buffered
    /// one with `fd`).
    #[cfg(feature = "fd")]
    fn apply_wide<D: ObjectDictionary, O: ServiceOutput>(
        &mut self,
        k: usize,
        now: Instant,
        payload: &[u8; 64],
        io: &mut Io<'_, D, O>,
    ) {
        let m = self.rpdos[k].p.mapping;
        if m.bits() <= MAX_BITS {
            // A classic-sized mapping (and an MPDO, always 8 bytes): the classic path.
            let mut b = [0u8; 8];
            b.copy_from_slice(&payload[..8]);
            return self.apply(k, now, &b, io);
        }
        let track = !self.reverse.is_empty();
        let mut keys: heapless::Vec<(u16, u8), { MAX_ENTRIES as usize }> = heapless::Vec::new();
        m.unpack_wide(io.od, map_index(Dir::Receive, k as u16), payload, |i, s| {
            if track {
                let _ = keys.push((i, s));
            }
        });
        if self.rx_events {
            io.event(now, PdoEvent::RpdoReceived { pdo: k as u16 + 1 });
        }
        for (i, s) in keys {
            self.written(now, i, s, io);
        }
    }

    /// A frame from the bus. False when it is no PDO of this node.
    pub fn handle_frame<D: ObjectDictionary, O: ServiceOutput>(
        &mut self,
        now: Instant,
        frame: &Frame,
        io: &mut Io<'_, D, O>,
    ) -> bool {
        let k = id_key(frame.id());
        if frame.is_remote() {
            let (lo, hi) = equal_range(&self.tx_index, k);
            for i in lo..hi {
                let slot = self.tx_index[i].1 as usize;
                match self.tpdos[slot].rtr() {
                    OnRtr::Ignore => {}
                    OnRtr::SendSampled => {
                        let t = &mut self.tpdos[slot];
                        if let (Some(b), Some(id)) = (t.sampled, t.p.id) {
                            let n = t.p.mapping.bytes() as usize;
                            #[cfg(feature = "fd")]
                            if let Some(w) = &self.wide {
                                match w.get(wide::tx_key(slot)) {
                                    Some(p) if n > 8 => io.send_fd(id, &p[..n]),
                                    _ => io.send_fd(id, &b[..n.min(8)]),
                                }
                                t.sent(now);
                                continue;
                            }
                            io.send(id, &b[..n]);
                            t.sent(now);
                        }
                    }
                    OnRtr::Event => self.service_tpdo(slot, now, io),
                }
            }
            return lo < hi;
        }
        let (lo, hi) = equal_range(&self.rx_index, k);
        for i in lo..hi {
            let slot = self.rx_index[i].1 as usize;
            let pdo = slot as u16 + 1;
            #[cfg(feature = "mpdo")]
            if !self.mpdo_length_ok(slot, frame.data().len()) {
                continue;
            }
            let mut rec = Recovered::default();
            match self.rpdos[slot].frame(now, frame.data(), &mut rec) {
                OnFrame::Ignore | OnFrame::Buffered => {}
                OnFrame::TooShort {
                    expected,
                    got,
                    first: true,
                } => self.too_short(now, io, pdo, expected, got),
                OnFrame::TooShort { .. } => {}
                OnFrame::Apply => {
                    let mut b = [0u8; 8];
                    let d = frame.data();
                    b[..d.len()].copy_from_slice(d);
                    self.apply(slot, now, &b, io);
                }
            }
            self.recovered(rec, pdo);
            let d = self.rpdos[slot].deadline();
            self.note(d);
        }
        lo < hi
    }

    /// A CAN FD frame from the bus (feature `fd`). False when it is no PDO of this node, or the
    /// engine is not on a CANopen FD network. An RPDO frame shorter than its mapping is refused
    /// as a classic one is (event, EMCY 0x8210); an MPDO receiver takes FD MPDOs (a CAN FD
    /// length of 8 to 64 bytes, else counted as malformed).
    #[cfg(feature = "fd")]
    pub fn handle_frame_fd<D: ObjectDictionary, O: ServiceOutput>(
        &mut self,
        now: Instant,
        frame: &FdFrame,
        io: &mut Io<'_, D, O>,
    ) -> bool {
        if self.wide.is_none() {
            return false;
        }
        let (lo, hi) = equal_range(&self.rx_index, id_key(frame.id()));
        for i in lo..hi {
            let slot = self.rx_index[i].1 as usize;
            let pdo = slot as u16 + 1;
            #[cfg(feature = "mpdo")]
            if !self.mpdo_fd_length_ok(slot, frame.data().len()) {
                continue;
            }
            let mut rec = Recovered::default();
            match self.rpdos[slot].frame(now, frame.data(), &mut rec) {
                OnFrame::Ignore => {}
                OnFrame::Buffered => {
                    if self.rpdos[slot].p.mapping.bits() > MAX_BITS {
                        let mut b = [0u8; 64];
                        for (d, s) in b.iter_mut().zip(frame.data()) {
                            *d = *s;
                        }
                        let kept = self
                            .wide
                            .as_mut()
                            .is_some_and(|w| w.put(wide::rx_key(slot), &b));
                        if !kept {
                            // Dropped (counted): nothing to apply at the SYNC.
                            self.rpdos[slot].buffered = None;
                        }
                    }
                }
                OnFrame::TooShort {
                    expected,
                    got,
                    first: true,
                } => self.too_short(now, io, pdo, expected, got),
                OnFrame::TooShort { .. } => {}
                #[cfg(feature = "mpdo")]
                OnFrame::Apply if self.rpdos[slot].p.is_mpdo() => {
                    self.apply_mpdo_fd(slot, now, frame.data(), io);
                }
                OnFrame::Apply => {
                    let mut b = [0u8; 64];
                    for (d, s) in b.iter_mut().zip(frame.data()) {
                        *d = *s;
                    }
                    self.apply_wide(slot, now, &b, io);
                }
            }
            self.recovered(rec, pdo);
            let d = self.rpdos[slot].deadline();
            self.note(d);
        }
        lo < hi
    }

    /// An entry was written (by the application, SDO or an RPDO): event-driven TPDOs mapping it
    /// are triggered.
    pub fn written<D: ObjectDictionary, O: ServiceOutput>(
        &mut self,
        now: Instant,
        index: u16,
        sub: u8,
        io: &mut Io<'_, D, O>,
    ) {
        if !self.running || self.reverse.is_empty() {
            return;
        }
        let key = key(index, sub);
        if self.reverse.overflow {
            for k in 0..self.tpdos.len() {
                if self.maps(k, key, io.od) && self.tpdos[k].trigger() {
                    self.service_tpdo(k, now, io);
                }
            }
            return;
        }
        let (lo, hi) = equal_range(self.reverse.pairs(), key);
        for i in lo..hi {
            let k = self.reverse.pairs()[i].1 as usize;
            if self.tpdos[k].trigger() {
                self.service_tpdo(k, now, io);
            }
        }
    }

    fn maps<D: ObjectDictionary>(&self, k: usize, key: u32, od: &D) -> bool {
        let t = &self.tpdos[k];
        t.p.event_capable()
            && (0..t.p.mapping.count()).any(|j| {
                let e = t.p.mapping.entry(od, map_index(Dir::Transmit, k as u16), j);
                !e.is_dummy() && crate::od::key(e.index, e.sub) == key
            })
    }

    /// The application asks TPDO `pdo` to be sent (types 254/255: now, or when the inhibit time
    /// ends; type 0: at the next SYNC).
    pub fn request<D: ObjectDictionary, O: ServiceOutput>(
        &mut self,
        now: Instant,
        pdo: u16,
        io: &mut Io<'_, D, O>,
    ) -> Result<(), PdoError> {
        let k = (pdo as usize).wrapping_sub(1);
        let t = self.tpdos.get_mut(k).ok_or(PdoError::NoSuchPdo { pdo })?;
        if !t.running() {
            return Err(PdoError::NotRunning { pdo });
        }
        if !t.p.event_capable() {
            return Err(PdoError::NotEventDriven {
                pdo,
                transmission_type: t.p.ttype,
            });
        }
        if t.trigger() {
            self.service_tpdo(k, now, io);
        }
        Ok(())
    }

    pub fn tpdo_status(&self, pdo: u16) -> Option<TpdoStatus> {
        let t = self.tpdos.get((pdo as usize).wrapping_sub(1))?;
        Some(TpdoStatus {
            id: t.p.id,
            transmission_type: t.p.ttype,
            running: t.running(),
            mapped_bits: t.p.mapping.bits(),
            sent: t.sent,
            last_sent: t.last_sent(),
            error: t.p.error,
        })
    }

    pub fn rpdo_status(&self, pdo: u16) -> Option<RpdoStatus> {
        let r = self.rpdos.get((pdo as usize).wrapping_sub(1))?;
        Some(RpdoStatus {
            id: r.p.id,
            transmission_type: r.p.ttype,
            running: r.running(),
            mapped_bits: r.p.mapping.bits(),
            received: r.received,
            last_received: r.last_rx(),
            timed_out: r.timed_out(),
            length_error: r.length_error(),
            error: r.p.error,
        })
    }
}

fn report<D, O: ServiceOutput>(
    io: &mut Io<'_, D, O>,
    now: Instant,
    dir: Dir,
    k: usize,
    id: Option<Id>,
    error: Option<AbortCode>,
) {
    if let (Some(_), Some(reason)) = (id, error) {
        io.event(
            now,
            PdoEvent::Unusable {
                dir,
                pdo: k as u16 + 1,
                reason,
            },
        );
    }
}
