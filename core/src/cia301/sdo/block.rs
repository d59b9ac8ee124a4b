//! The logic block transfers share between server and client: the sending side (download on the
//! client, upload on the server) and the receiving side.
//!
//! Segments are counted over the whole transfer: `ceil(len / 7)` of them, at least one (an empty
//! transfer sends one segment with seven unused bytes). A sub-block numbers its segments
//! 1..=blksize; the receiver acknowledges the last segment it got in sequence and the sender
//! resumes right after it, so a lost segment costs one retransmission of the rest of its
//! sub-block.

use super::buffer::TransferBuffer;
use super::codec::{BlockSegment, MAX_BLOCK_SIZE, SEGMENT_DATA};
use crate::od::abort::AbortCode;

/// Number of segments that carry `len` bytes.
pub const fn segments(len: usize) -> usize {
    if len == 0 {
        1
    } else {
        len.div_ceil(SEGMENT_DATA)
    }
}

/// Unused bytes in the last segment of `len` bytes (the `n` of the end frame).
pub const fn unused(len: usize) -> u8 {
    (segments(len) * SEGMENT_DATA - len) as u8
}

/// True for a block size CiA 301 allows (1–127).
pub const fn valid_block_size(b: u8) -> bool {
    b >= 1 && b <= MAX_BLOCK_SIZE
}

/// What the sender learned from an acknowledgement.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Acked {
    /// Every segment is confirmed: send the end frame.
    Done,
    /// The next sub-block is under way.
    More,
}

/// The sending side of a block transfer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BlockSender {
    len: usize,
    acked: usize,
    blksize: u8,
    next_seq: u8,
    sending: bool,
    last_ack: Option<(u8, u8)>,
}

impl BlockSender {
    /// A sender of `len` bytes, first sub-block of `blksize` segments (checked by the caller).
    #[must_use]
    pub fn new(len: usize, blksize: u8) -> Self {
        BlockSender {
            len,
            acked: 0,
            blksize,
            next_seq: 1,
            sending: true,
            last_ack: None,
        }
    }

    /// The next segment to put on the bus, if the current sub-block is not complete yet.
    pub fn next_segment(&mut self, data: &[u8]) -> Option<[u8; 8]> {
        self.next_segment_in(data, 0)
    }

    /// [`BlockSender::next_segment`] from a window of the data: `window` holds the bytes from
    /// offset `start` of the transfer on (a streamed download keeps only what is not yet
    /// confirmed, so `start` is at most [`BlockSender::acked_bytes`]).
    pub fn next_segment_in(&mut self, window: &[u8], start: usize) -> Option<[u8; 8]> {
        if !self.sending {
            return None;
        }
        let seg = self.acked + self.next_seq as usize - 1;
        let total = segments(self.len);
        if seg >= total {
            self.sending = false;
            return None;
        }
        let from = seg * SEGMENT_DATA;
        let end = (from + SEGMENT_DATA)
            .min(self.len)
            .min(start + window.len());
        let mut bytes = [0u8; SEGMENT_DATA];
        if from < end && from >= start {
            bytes[..end - from].copy_from_slice(&window[from - start..end - start]);
        }
        let last = seg + 1 == total;
        let frame = BlockSegment {
            seqno: self.next_seq,
            last,
            data: bytes,
        }
        .encode();
        if last || self.next_seq >= self.blksize {
            self.sending = false;
        }
        self.next_seq = self.next_seq.saturating_add(1);
        Some(frame)
    }

    /// The transfer offset of the next segment's data.
    pub fn next_offset(&self) -> usize {
        (self.acked + self.next_seq as usize - 1) * SEGMENT_DATA
    }

    /// The transfer's length, learnt late: a streamed download of unknown size starts with
    /// `usize::MAX` and says how long it was once its source ended (before its last segment
    /// goes out).
    pub fn set_len(&mut self, len: usize) {
        self.len = len;
    }

    /// The transfer's length (`usize::MAX` while a streamed one does not know it yet).
    pub fn total_len(&self) -> usize {
        self.len
    }

    /// True while segments of the current sub-block remain to be sent.
    pub fn is_sending(&self) -> bool {
        self.sending
    }

    /// The receiver confirmed `ackseq` segments of the sub-block and asks for `blksize` next.
    /// `None`: a second copy of the previous acknowledgement that cannot belong to this
    /// sub-block (CAN may deliver a frame twice); ignored.
    pub fn ack(&mut self, ackseq: u8, blksize: u8) -> Result<Option<Acked>, AbortCode> {
        let sent = self.next_seq - 1;
        if ackseq > sent {
            if self.last_ack == Some((ackseq, blksize)) {
                return Ok(None);
            }
            return Err(AbortCode::INVALID_SEQUENCE);
        }
        self.last_ack = Some((ackseq, blksize));
        if !valid_block_size(blksize) {
            return Err(AbortCode::INVALID_BLOCK_SIZE);
        }
        self.acked += ackseq as usize;
        if self.acked >= segments(self.len) {
            self.sending = false;
            return Ok(Some(Acked::Done));
        }
        self.blksize = blksize;
        self.next_seq = 1;
        self.sending = true;
        Ok(Some(Acked::More))
    }

    /// Bytes confirmed so far.
    pub fn acked_bytes(&self) -> usize {
        (self.acked * SEGMENT_DATA).min(self.len)
    }
}

/// What the receiver does after a segment.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Received {
    /// Nothing to say yet.
    Continue,
    /// A second copy of the segment that closed the previous sub-block (CAN may deliver a frame
    /// twice): ignored.
    Duplicate,
    /// The sub-block is over: acknowledge this sequence number (a new sub-block starts).
    Ack(u8),
}

/// Where the received data may not go: past `max` bytes the transfer aborts with `code`
/// (the entry's size: length too high; the buffer's limit: out of memory).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Bound {
    /// Most bytes accepted.
    pub max: usize,
    /// The abort code past it.
    pub code: AbortCode,
}

/// The receiving side of a block transfer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BlockReceiver {
    blksize: u8,
    last_good: u8,
    tail: Option<[u8; SEGMENT_DATA]>,
    complete: bool,
    started: bool,
    /// The segment that closed the last sub-block, to recognise a second copy of it.
    closer: Option<[u8; 8]>,
    /// The last sub-block was acknowledged by the timer: until the next one begins (its first
    /// segment in sequence), what arrives may be the rest of the old one, still on its way.
    resync: bool,
}

impl BlockReceiver {
    /// A receiver of sub-blocks of `blksize` segments.
    #[must_use]
    pub fn new(blksize: u8) -> Self {
        BlockReceiver {
            blksize,
            last_good: 0,
            tail: None,
            complete: false,
            started: false,
            closer: None,
            resync: false,
        }
    }

    /// The block size asked of the sender.
    pub fn blksize(&self) -> u8 {
        self.blksize
    }

    /// True once the last segment was received and acknowledged: the end frame comes next.
    pub fn complete(&self) -> bool {
        self.complete
    }

    /// True when a segment of the current sub-block arrived (the sub-block timer runs).
    pub fn in_sub_block(&self) -> bool {
        self.started
    }

    /// True if `d` repeats the segment that closed the previous sub-block and nothing of the
    /// next one arrived yet: a double reception, not a new segment.
    pub fn is_repeat(&self, d: &[u8; 8]) -> bool {
        !self.started && self.closer == Some(*d)
    }

    /// A segment arrived. In-sequence data goes to `buf` (the last segment is held back until
    /// the end frame says how much of it is data); a segment out of sequence is ignored, and
    /// the end of the sub-block is acknowledged with the last good sequence number.
    pub fn segment<B: TransferBuffer>(
        &mut self,
        d: &[u8; 8],
        buf: &mut B,
        bound: Bound,
    ) -> Result<Received, AbortCode> {
        if self.is_repeat(d) {
            return Ok(Received::Duplicate);
        }
        let s = BlockSegment::decode(d);
        if s.seqno == 0 || s.seqno > self.blksize {
            return Err(AbortCode::INVALID_SEQUENCE);
        }
        self.started = true;
        if s.seqno == self.last_good + 1 {
            self.resync = false;
            self.last_good = s.seqno;
            if s.last {
                self.tail = Some(s.data);
                return Ok(Received::Ack(self.finish_sub_block(Some(*d))));
            }
            if buf.len() + SEGMENT_DATA > bound.max || !buf.extend(&s.data) {
                return Err(bound.code);
            }
            if s.seqno == self.blksize {
                return Ok(Received::Ack(self.finish_sub_block(Some(*d))));
            }
            return Ok(Received::Continue);
        }
        // Out of sequence: a segment was lost (or this one repeats). Only the segment that
        // closes the sub-block matters: it is time to tell the sender where to resume. Not
        // after the timer acknowledged: the old sub-block's late segments (a receiver that was
        // not scheduled in time finds them queued) would acknowledge again, and the sender
        // would take it for the new sub-block and send its start twice. The timer runs on, so
        // a new sub-block that lost its first segment is still acknowledged.
        if !self.resync && (s.last || s.seqno == self.blksize) {
            return Ok(Received::Ack(self.finish_sub_block(Some(*d))));
        }
        Ok(Received::Continue)
    }

    /// The sub-block timer expired: acknowledge what arrived so the sender resumes.
    pub fn timeout(&mut self) -> u8 {
        self.resync = true;
        self.finish_sub_block(None)
    }

    fn finish_sub_block(&mut self, closer: Option<[u8; 8]>) -> u8 {
        self.closer = closer;
        let ack = self.last_good;
        self.last_good = 0;
        self.started = false;
        if self.tail.is_some() {
            self.complete = true;
        }
        ack
    }

    /// The end frame arrived: the used part of the last segment joins the data.
    pub fn finish<B: TransferBuffer>(
        &mut self,
        unused: u8,
        buf: &mut B,
        bound: Bound,
    ) -> Result<(), AbortCode> {
        let Some(tail) = self.tail.take() else {
            return Err(AbortCode::COMMAND_SPECIFIER);
        };
        let used = SEGMENT_DATA.saturating_sub(unused as usize);
        if buf.len() + used > bound.max || !buf.extend(&tail[..used]) {
            return Err(bound.code);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cia301::sdo::buffer::InlineBuffer;

    const BIG: Bound = Bound {
        max: 4096,
        code: AbortCode::OUT_OF_MEMORY,
    };

    #[test]
    fn segment_counts_at_the_boundaries() {
        assert_eq!((segments(0), unused(0)), (1, 7));
        assert_eq!((segments(1), unused(1)), (1, 6));
        assert_eq!((segments(7), unused(7)), (1, 0));
        assert_eq!((segments(8), unused(8)), (2, 6));
        assert_eq!((segments(889), unused(889)), (127, 0));
        assert_eq!((segments(890), unused(890)), (128, 6));
    }

    /// Runs sender and receiver against each other, dropping the segments `lose` picks
    /// (by overall send count), and returns the received bytes and the sub-block count.
    fn run(len: usize, blksize: u8, mut lose: impl FnMut(usize) -> bool) -> (Vec<u8>, usize) {
        let data: Vec<u8> = (0..len).map(|i| (i * 7 + 3) as u8).collect();
        let mut tx = BlockSender::new(len, blksize);
        let mut rx = BlockReceiver::new(blksize);
        let mut buf = InlineBuffer::<4096>::with_limit(4096);
        let mut n = 0;
        let mut blocks = 0;
        loop {
            let mut ack = None;
            while let Some(f) = tx.next_segment(&data) {
                n += 1;
                if lose(n) {
                    continue;
                }
                if let Received::Ack(a) = rx.segment(&f, &mut buf, BIG).unwrap() {
                    ack = Some(a);
                }
            }
            blocks += 1;
            // Every segment that closes the sub-block was lost: the receiver's timer fires.
            let a = ack.unwrap_or_else(|| rx.timeout());
            if tx.ack(a, rx.blksize()).unwrap() == Some(Acked::Done) {
                assert!(rx.complete());
                rx.finish(unused(len), &mut buf, BIG).unwrap();
                return (buf.as_slice().to_vec(), blocks);
            }
            assert!(blocks < 1000, "no progress");
        }
    }

    #[test]
    fn lossless_transfers_take_ceil_segments_over_blksize_sub_blocks() {
        for len in [0, 1, 4, 5, 7, 8, 889, 890, 2000] {
            let (got, blocks) = run(len, 127, |_| false);
            let want: Vec<u8> = (0..len).map(|i| (i * 7 + 3) as u8).collect();
            assert_eq!(got, want, "len {len}");
            assert_eq!(blocks, segments(len).div_ceil(127), "len {len}");
        }
    }

    #[test]
    fn lost_segments_are_sent_again_from_the_last_good_one() {
        let want: Vec<u8> = (0..890).map(|i| (i * 7 + 3) as u8).collect();
        // Lose the 5th, the 127th (closes the first sub-block) and the very last.
        let (got, blocks) = run(890, 127, |n| n == 5 || n == 127 || n == 128);
        assert_eq!(got, want);
        assert!(blocks >= 3);
        // Pseudo-random loss of one segment in three.
        let mut seed = 7u32;
        let (got, _) = run(890, 10, |_| {
            seed = seed.wrapping_mul(1_103_515_245).wrapping_add(12345);
            (seed >> 16).is_multiple_of(3)
        });
        assert_eq!(got, want);
    }

    /// The receiver's timer acknowledges while the rest of the sub-block is still on its way
    /// (a receiver not scheduled in time): those late segments, the closing one included, are
    /// not acknowledged again, and the data stays exactly what was sent.
    #[test]
    fn late_segments_after_the_timer_acknowledged_are_not_acknowledged_again() {
        let data: Vec<u8> = (0..200u32).map(|i| (i * 13 + 1) as u8).collect();
        let mut tx = BlockSender::new(data.len(), 10);
        let mut rx = BlockReceiver::new(10);
        let mut buf = InlineBuffer::<256>::with_limit(256);
        let first: Vec<[u8; 8]> = core::iter::from_fn(|| tx.next_segment(&data)).collect();
        assert_eq!(first.len(), 10);
        for f in &first[..4] {
            assert_eq!(rx.segment(f, &mut buf, BIG), Ok(Received::Continue));
        }
        assert_eq!(rx.timeout(), 4);
        for f in &first[4..] {
            assert_eq!(
                rx.segment(f, &mut buf, BIG),
                Ok(Received::Continue),
                "late {f:?}"
            );
        }
        assert_eq!(tx.ack(4, 10), Ok(Some(Acked::More)));
        loop {
            let mut ack = None;
            while let Some(f) = tx.next_segment(&data) {
                if let Received::Ack(a) = rx.segment(&f, &mut buf, BIG).unwrap() {
                    ack = Some(a);
                }
            }
            if tx.ack(ack.expect("an ack per sub-block"), 10).unwrap() == Some(Acked::Done) {
                break;
            }
        }
        rx.finish(unused(data.len()), &mut buf, BIG).unwrap();
        assert_eq!(buf.as_slice(), &data[..]);
    }

    #[test]
    fn bad_sequence_numbers_and_block_sizes_abort() {
        let mut rx = BlockReceiver::new(10);
        let mut buf = InlineBuffer::<64>::with_limit(64);
        assert_eq!(
            rx.segment(&[0x00; 8], &mut buf, BIG),
            Err(AbortCode::INVALID_SEQUENCE)
        );
        assert_eq!(
            rx.segment(&[11; 8], &mut buf, BIG),
            Err(AbortCode::INVALID_SEQUENCE)
        );
        let mut tx = BlockSender::new(100, 10);
        tx.next_segment(&[0; 100]);
        assert_eq!(tx.ack(2, 10), Err(AbortCode::INVALID_SEQUENCE));
        assert_eq!(tx.ack(1, 0), Err(AbortCode::INVALID_BLOCK_SIZE));
        assert_eq!(tx.ack(1, 128), Err(AbortCode::INVALID_BLOCK_SIZE));
    }

    #[test]
    fn the_bound_is_enforced_with_its_code() {
        let mut rx = BlockReceiver::new(10);
        let mut buf = InlineBuffer::<64>::with_limit(64);
        let b = Bound {
            max: 10,
            code: AbortCode::LENGTH_TOO_HIGH,
        };
        assert_eq!(rx.segment(&[1; 8], &mut buf, b), Ok(Received::Continue));
        assert_eq!(
            rx.segment(&[2; 8], &mut buf, b),
            Err(AbortCode::LENGTH_TOO_HIGH)
        );
        assert_eq!(buf.len(), 7);
    }
}
