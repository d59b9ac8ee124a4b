//! CAN FD frames through the merger (feature `fd`): the same rule, records and memory as
//! classic frames (see the [module documentation](super#can-fd-frames)), keyed by every byte.

use super::table::MergeFrame;
use super::{Merger, Sample, Trust, Verdict};
use duocan_core::frame::FdFrame;
use duocan_core::Instant;

impl<const SLOTS: usize> Merger<SLOTS> {
    /// [`Merger::arrive`] for a CAN FD frame.
    pub fn arrive_fd(&mut self, now: Instant, port: usize, frame: &FdFrame) -> Verdict {
        self.arrive_fd_at(now, now, port, frame, Trust::Trusted).0
    }

    /// [`Merger::arrive_at`] for a CAN FD frame: its twin is a copy with the same identifier,
    /// format, length and data bytes, whatever its BRS and ESI flags.
    pub fn arrive_fd_at(
        &mut self,
        now: Instant,
        at: Instant,
        port: usize,
        frame: &FdFrame,
        trust: Trust,
    ) -> (Verdict, Option<Sample>) {
        self.arrive_any(now, at, port, frame, trust)
    }

    /// [`Merger::unmatched`] for a CAN FD frame's key.
    pub fn unmatched_fd(&self, frame: &FdFrame) -> Option<(usize, u16)> {
        let (hi, lo) = frame.key();
        let s = frame.find(&self.table, hi, lo, frame.hash(hi, lo))?;
        let slot = &self.table.slots[s];
        (slot.unmatched > 0).then_some((slot.side as usize, slot.unmatched))
    }
}

#[cfg(test)]
mod tests {
    use super::super::{Merger, Verdict};
    use duocan_core::frame::FdFrame;
    use duocan_core::{Duration, Frame, Id, Instant};

    fn t(ms: u64) -> Instant {
        Instant::from_millis(ms)
    }

    fn merger() -> Merger<64> {
        Merger::new(Duration::from_millis(5))
    }

    #[test]
    fn an_fd_twin_is_dropped_whatever_its_brs_and_esi() {
        let mut m = merger();
        let f = FdFrame::new(Id::Standard(0x185), &[0xA5; 64]).unwrap();
        assert_eq!(m.arrive_fd(t(10), 0, &f.with_brs(true)), Verdict::Deliver);
        // The sender is error passive on bus 1 and its copy there went without bit rate switch.
        let other = f.with_esi(true);
        assert_eq!(m.arrive_fd(t(11), 1, &other), Verdict::Duplicate);
        assert_eq!((m.stats().delivered, m.stats().duplicates), (1, 1));
    }

    #[test]
    fn a_classic_and_an_fd_frame_of_the_same_bytes_are_two_frames() {
        let mut m = merger();
        let c = Frame::from_array(Id::Standard(0x185), [1, 2, 3, 4, 5, 6, 7, 8]);
        let f = FdFrame::try_from(c).unwrap();
        assert_eq!(m.arrive(t(10), 0, &c), Verdict::Deliver);
        assert_eq!(m.arrive_fd(t(11), 1, &f), Verdict::Deliver);
        // Each finds its own twin.
        assert_eq!(m.arrive_fd(t(12), 0, &f), Verdict::Duplicate);
        assert_eq!(m.arrive(t(12), 1, &c), Verdict::Duplicate);
        assert_eq!(m.unmatched(&c), None);
        assert_eq!(m.unmatched_fd(&f), None);
    }

    #[test]
    fn every_byte_and_the_length_tell_fd_frames_apart() {
        let mut m = merger();
        let mut data = [7u8; 64];
        let a = FdFrame::new(Id::Extended(0x1ABC_DEF0), &data).unwrap();
        data[63] = 8;
        let b = FdFrame::new(Id::Extended(0x1ABC_DEF0), &data).unwrap();
        let short = FdFrame::new(Id::Extended(0x1ABC_DEF0), &data[..48]).unwrap();
        let base = FdFrame::new(Id::Standard(0x0F0), &data[..48]).unwrap();
        for f in [a, b, short, base] {
            assert_eq!(m.arrive_fd(t(10), 0, &f), Verdict::Deliver);
        }
        assert_eq!(m.unmatched_fd(&a), Some((0, 1)));
        assert_eq!(m.unmatched_fd(&b), Some((0, 1)));
        for f in [base, short, b, a] {
            assert_eq!(m.arrive_fd(t(12), 1, &f), Verdict::Duplicate);
        }
        assert_eq!(m.keys(), 4);
    }

    #[test]
    fn fd_frames_beyond_the_capacity_are_evicted_as_classic_ones() {
        let mut m = merger();
        for k in 0..200u32 {
            let f = FdFrame::new(Id::Standard((k % 0x7FF) as u16), &[k as u8; 24]).unwrap();
            assert_eq!(m.arrive_fd(t(10), 0, &f), Verdict::Deliver);
            assert!(m.len() <= m.capacity());
        }
        assert_eq!(m.stats().evicted, 200 - m.capacity() as u64);
        // A port index other than 0 and 1 is delivered and counted, not recorded.
        let f = FdFrame::new(Id::Standard(1), &[]).unwrap();
        assert_eq!(m.arrive_fd(t(10), 7, &f), Verdict::Deliver);
        assert_eq!(m.stats().bad_port, 1);
    }
}
