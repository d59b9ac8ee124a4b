//! Streamed transfers: values of any size through a window of bounded size.
//!
//! **The rule.** A streamed transfer runs the ordinary segmented or block protocol, but its
//! session's transfer buffer holds a *window* of the value instead of all of it. A download
//! ([`SdoClient::download_stream`]) takes the caller's bytes with [`SdoClient::feed`] as the
//! window has room ([`SdoClient::wants_data`]) and forgets them once the server has confirmed
//! them; an upload ([`SdoClient::upload_stream`]) hands received bytes out with
//! [`SdoClient::read_stream`] and forgets them there. [`SdoClient::poll_stream`] names a
//! transfer whose caller has something to do (room to fill, data to take).
//!
//! **Memory.** The window is fixed when the transfer starts (at least [`MIN_WINDOW`], at most
//! the client's limit) and the buffer never holds more ([`SdoClient::max_buffer_len`]); nothing
//! is allocated per frame. A block download keeps exactly the bytes from the last confirmed
//! segment on, so a partial acknowledgement is answered from the window; the CRC runs over
//! the bytes as they leave the window and is complete at the end frame.
//!
//! **Back-pressure.** An upload whose reader does not take its data does not grow: the
//! request for the next segment (segmented) or the acknowledgement that opens the next
//! sub-block (block) waits until the window has room for what it asks for. A download whose
//! feeder is slow sends no segment it does not have. The transfer's timeout keeps running
//! meanwhile: a caller slower than the SDO timeout aborts the transfer, as the server would.
//!
//! **The end.** A download ends when the caller says so (`last`) or has fed the size it
//! announced; feeding less than announced aborts (0x08000000). An upload ends with the
//! client's ordinary [`SdoEvent`](super::SdoEvent), whose data is the rest of the window not
//! yet read (at most the window).
//!
//! ```
//! use duocan_core::sdo::{SdoClient, SdoOptions};
//! use duocan_core::{Instant, Machine, NodeId};
//!
//! let mut client: SdoClient = SdoClient::new(64 * 1024);
//! let node = NodeId::must(5);
//! let id = client
//!     .download_stream(Instant::ZERO, node, 0x2002, 0, Some(100_000), 1024, SdoOptions::default())
//!     .unwrap();
//! assert_eq!(client.wants_data(id), 1024);
//! assert_eq!(client.feed(Instant::ZERO, id, &[7; 4096], false), Some(1024), "the window is full");
//! assert_eq!(client.wants_data(id), 0);
//! assert!(client.max_buffer_len() <= 1024);
//! let f = client.poll_transmit().unwrap();
//! assert_eq!(f.data()[..4], [0x21, 0x02, 0x20, 0x00], "segmented download, size indicated");
//! ```

use super::block::BlockSender;
use super::buffer::TransferBuffer;
use super::client::SdoClient;
use super::codec::{Request, SegmentData, MAX_BLOCK_SIZE, SEGMENT_DATA};
use super::crc;
use super::error::{Direction, SdoError, SdoErrorKind};
use super::request::{RequestId, SdoOptions, TransferMode};
use super::session::{start_download, Session, State};
use crate::frame::cob_id::NodeId;
use crate::frame::instant::Instant;
use crate::frame::storage::Storage;
use crate::od::abort::AbortCode;

/// The smallest window: a whole sub-block of the largest block size and one more segment
/// (a download must know a segment is not the last before it sends it; an upload needs room
/// for the sub-block it acknowledges and the held-back last segment).
pub const MIN_WINDOW: usize = MAX_BLOCK_SIZE as usize * SEGMENT_DATA + SEGMENT_DATA + 1;

/// What a streaming session knows beyond its window.
#[derive(Clone, Copy, Debug)]
pub(super) struct Stream {
    /// The transfer offset of the window's first byte.
    pub base: usize,
    /// The size announced (the caller's for a download, the server's for an upload).
    pub total: Option<usize>,
    /// Download: the caller's source ended; everything is in the window or sent.
    pub ended: bool,
    /// The CRC of the bytes that left the window.
    pub crc: u16,
    /// The caller has something to do: [`SdoClient::poll_stream`] says so once.
    pub notify: bool,
    /// Upload: a request held back until the window has `room` bytes free.
    pub held: Option<(Request, usize)>,
}

impl Stream {
    fn new(total: Option<usize>) -> Self {
        Stream {
            base: 0,
            total,
            ended: false,
            crc: 0,
            notify: false,
            held: None,
        }
    }
}

/// Forgets the window's bytes before transfer offset `upto`, adding them to the CRC.
fn drain<B: TransferBuffer>(s: &mut Session<B>, upto: usize) {
    let Some(st) = &mut s.stream else { return };
    let n = upto.saturating_sub(st.base).min(s.buf.len());
    st.crc = crc::update(st.crc, &s.buf.as_slice()[..n]);
    s.buf.consume(n);
    st.base += n;
    if s.buf.limit() - s.buf.len() >= s.buf.limit() / 2 && !st.ended {
        st.notify = true;
    }
}

/// Bytes received (or fed) so far: the window's end as a transfer offset.
pub(super) fn received<B: TransferBuffer>(s: &Session<B>) -> usize {
    s.stream.map_or(0, |st| st.base) + s.buf.len()
}

/// The length and CRC of the whole value, once all of it is in or through the window.
pub(super) fn length_and_crc<B: TransferBuffer>(s: &mut Session<B>) -> (usize, u16) {
    match s.stream {
        None => (s.buf.len(), crc::crc16(s.buf.as_slice())),
        Some(st) => (st.base + s.buf.len(), crc::update(st.crc, s.buf.as_slice())),
    }
}

/// The length a block download's sender starts with: all of it, the announced size, or
/// `usize::MAX` until a streamed source ends ([`BlockSender::set_len`]).
pub(super) fn send_len<B: TransferBuffer>(s: &Session<B>) -> usize {
    match s.stream {
        None => s.buf.len(),
        Some(st) if st.ended => st.base + s.buf.len(),
        Some(st) => st.total.unwrap_or(usize::MAX),
    }
}

/// A block download's sub-block was confirmed up to `acked` bytes: they leave the window.
pub(super) fn confirmed<B: TransferBuffer>(s: &mut Session<B>, acked: usize) {
    drain(s, acked);
}

/// Sends `r` now if the window has `room` bytes free (or the transfer does not stream), else
/// holds it until the reader has taken enough ([`SdoClient::read_stream`]).
pub(super) fn request_room<B: TransferBuffer>(s: &mut Session<B>, r: Request, room: usize) {
    let free = s.buf.limit() - s.buf.len();
    match &mut s.stream {
        Some(st) => {
            if s.buf.len() >= s.buf.limit() / 2 {
                st.notify = true;
            }
            if free < room {
                st.held = Some((r, room));
                st.notify = true;
                return;
            }
            s.request(r);
        }
        None => s.request(r),
    }
}

/// The next segment of a streamed segmented download, after the server confirmed the bytes
/// before `offset`; waits for the caller when the window cannot say whether it is the last.
pub(super) fn next_segment<B: TransferBuffer>(s: &mut Session<B>, toggle: bool, offset: usize) {
    drain(s, offset);
    let Some(st) = s.stream else { return };
    let have = s.buf.len();
    if !st.ended && have <= SEGMENT_DATA {
        s.state = State::DownloadWait { toggle, offset };
        if let Some(st) = &mut s.stream {
            st.notify = true;
        }
        return;
    }
    let n = have.min(SEGMENT_DATA);
    let last = st.ended && have <= SEGMENT_DATA;
    let data = SegmentData::from_slice(&s.buf.as_slice()[..n]);
    s.request(Request::DownloadSegment { toggle, data, last });
    s.state = State::DownloadSegment {
        toggle,
        offset: offset + n,
        last,
    };
}

/// The next segment of a block download's sub-block from the window, if the window has it
/// (and, before the source ended, knows it is not the last).
pub(super) fn block_segment(
    tx: &mut BlockSender,
    window: &[u8],
    stream: Option<&Stream>,
) -> Option<[u8; 8]> {
    let Some(st) = stream else {
        return tx.next_segment(window);
    };
    ready(tx, window.len(), st).then(|| tx.next_segment_in(window, st.base))?
}

fn ready(tx: &BlockSender, window: usize, st: &Stream) -> bool {
    let have = st.base + window;
    let o = tx.next_offset();
    let need = match tx.total_len() {
        usize::MAX => o + SEGMENT_DATA + 1,
        len => (o + SEGMENT_DATA).min(len),
    };
    st.ended || have >= need
}

/// True when a block download's sub-block is waiting for the caller's data, not for the bus.
pub(super) fn starved<B: TransferBuffer>(s: &Session<B>) -> bool {
    match (s.state, &s.stream) {
        (State::BlockDownload { tx, .. }, Some(st)) => !ready(&tx, s.buf.len(), st),
        _ => false,
    }
}

impl<B: TransferBuffer, const SESSIONS: usize, S: Storage> SdoClient<B, SESSIONS, S> {
    /// Starts writing a value of any size to (index, sub) of `node`, through a window of
    /// `window` bytes (raised to [`MIN_WINDOW`]); `size`, if given, is announced to the server
    /// and the transfer ends once that much was fed. Feed it with [`SdoClient::feed`]. The mode
    /// is segmented unless the options ask for block transfer (or `Auto` with a block threshold
    /// the size reaches); never expedited.
    #[allow(clippy::too_many_arguments)]
    pub fn download_stream(
        &mut self,
        now: Instant,
        node: NodeId,
        index: u16,
        sub: u8,
        size: Option<u32>,
        window: usize,
        opts: SdoOptions,
    ) -> Result<RequestId, SdoError> {
        self.watch_clock(now);
        let window = self.window(node, index, sub, Direction::Download, window)?;
        let mode = match opts.mode {
            TransferMode::Block => TransferMode::Block,
            TransferMode::Auto
                if opts
                    .block_threshold
                    .zip(size)
                    .is_some_and(|(t, n)| n as usize >= t) =>
            {
                TransferMode::Block
            }
            _ => TransferMode::Segmented,
        };
        let i = self.take_session(node, index, sub, Direction::Download, &opts)?;
        let s = &mut self.sessions[i];
        s.buf.clear();
        s.buf.set_limit(window);
        s.buf.reserve(window);
        let mut st = Stream::new(size.map(|n| n as usize));
        st.ended = size == Some(0);
        s.stream = Some(st);
        start_download(s, mode);
        s.touch(now);
        Ok(s.request)
    }

    /// Starts reading (index, sub) of `node`, a value of any size, through a window of
    /// `window` bytes (raised to [`MIN_WINDOW`]). Take the data with
    /// [`SdoClient::read_stream`]; the result event carries what was not taken yet.
    pub fn upload_stream(
        &mut self,
        now: Instant,
        node: NodeId,
        index: u16,
        sub: u8,
        window: usize,
        opts: SdoOptions,
    ) -> Result<RequestId, SdoError> {
        let window = self.window(node, index, sub, Direction::Upload, window)?;
        let id = self.upload(now, node, index, sub, opts)?;
        if let Some(s) = self.streaming(id) {
            s.buf.set_limit(window);
            s.stream = Some(Stream::new(None));
        }
        Ok(id)
    }

    fn window(
        &self,
        node: NodeId,
        index: u16,
        sub: u8,
        direction: Direction,
        window: usize,
    ) -> Result<usize, SdoError> {
        let window = window.max(MIN_WINDOW);
        if window > self.limit() {
            return Err(SdoError {
                node,
                index,
                sub,
                direction,
                kind: SdoErrorKind::TooLong {
                    len: window,
                    limit: self.limit(),
                },
            });
        }
        Ok(window)
    }

    fn streaming(&mut self, request: RequestId) -> Option<&mut Session<B>> {
        self.sessions
            .iter_mut()
            .find(|s| s.active() && s.request == request)
    }

    /// Bytes a streamed download takes now: the window's free room, no more than what remains
    /// of an announced size; 0 for anything else.
    pub fn wants_data(&self, request: RequestId) -> usize {
        self.sessions
            .iter()
            .find(|s| s.active() && s.request == request && s.direction == Direction::Download)
            .and_then(|s| Some((s, s.stream?)))
            .filter(|(_, st)| !st.ended)
            .map_or(0, |(s, st)| {
                let room = s.buf.limit() - s.buf.len();
                st.total
                    .map_or(room, |t| room.min(t.saturating_sub(st.base + s.buf.len())))
            })
    }

    /// Feeds a streamed download: takes as much of `data` as [`SdoClient::wants_data`] allows
    /// and returns how much (`None`: `request` is not a streamed download running now). `last`
    /// ends the source once all of `data` was taken; feeding less than the announced size
    /// aborts the transfer (0x08000000, reported in its result).
    pub fn feed(
        &mut self,
        now: Instant,
        request: RequestId,
        data: &[u8],
        last: bool,
    ) -> Option<usize> {
        let want = self.wants_data(request);
        let i = self.sessions.iter().position(|s| {
            s.active()
                && s.request == request
                && s.direction == Direction::Download
                && s.stream.is_some_and(|st| !st.ended)
        })?;
        let s = &mut self.sessions[i];
        let n = want.min(data.len());
        let _ = s.buf.extend(&data[..n]);
        let st = s.stream.as_mut()?;
        let have = st.base + s.buf.len();
        if (last && n == data.len()) || st.total == Some(have) {
            st.ended = true;
            if st.total.is_some_and(|t| t != have) {
                self.abort_session(i, now, AbortCode::GENERAL);
                return Some(n);
            }
            if let State::BlockDownload { tx, .. } = &mut s.state {
                tx.set_len(have);
            }
        }
        if let State::DownloadWait { toggle, offset } = s.state {
            next_segment(s, toggle, offset);
        }
        if n > 0 {
            s.touch(now);
        }
        Some(n)
    }

    /// Takes received bytes of a streamed upload into `out` and returns how many (`None`:
    /// `request` is not a streamed upload running now). Room made lets a held-back request
    /// go out.
    pub fn read_stream(
        &mut self,
        now: Instant,
        request: RequestId,
        out: &mut [u8],
    ) -> Option<usize> {
        let s = self.sessions.iter_mut().find(|s| {
            s.active()
                && s.request == request
                && s.direction == Direction::Upload
                && s.stream.is_some()
        })?;
        let n = out.len().min(s.buf.len());
        out[..n].copy_from_slice(&s.buf.as_slice()[..n]);
        let base = s.stream.map_or(0, |st| st.base);
        drain(s, base + n);
        let st = s.stream.as_mut()?;
        st.notify = false;
        if let Some((r, room)) = st.held {
            if s.buf.limit() - s.buf.len() >= room {
                st.held = None;
                s.request(r);
                s.touch(now);
            }
        }
        Some(n)
    }

    /// A streamed transfer whose caller has something to do: a download with room to fill
    /// (half the window free, or a segment waiting for data), an upload with data to take
    /// (half the window full, or a request held back for room). Each such change is named
    /// once; the caller then asks [`SdoClient::wants_data`] or calls
    /// [`SdoClient::read_stream`].
    #[must_use]
    pub fn poll_stream(&mut self) -> Option<RequestId> {
        self.sessions.iter_mut().find_map(|s| {
            let st = s.stream.as_mut().filter(|st| st.notify)?;
            st.notify = false;
            s.active().then_some(s.request)
        })
    }

    /// How far a streamed transfer is: (bytes confirmed by the server for a download, received
    /// for an upload; the size announced, if any). `None` when `request` is not a streamed
    /// transfer running now.
    pub fn stream_progress(&self, request: RequestId) -> Option<(usize, Option<usize>)> {
        let s = self
            .sessions
            .iter()
            .find(|s| s.active() && s.request == request)?;
        let st = s.stream?;
        let done = match s.direction {
            Direction::Download => st.base,
            Direction::Upload => st.base + s.buf.len(),
        };
        Some((done, st.total))
    }
}
