//! One client session: the state of a transfer to one server and the frames it sends.

use super::block::{BlockReceiver, BlockSender, Bound};
use super::buffer::TransferBuffer;
use super::codec::{Init, Request, SegmentData, SEGMENT_DATA};
use super::error::Direction;
use super::request::{Channel, RequestId, SdoOptions, TransferMode};
use super::stream::{self, Stream};
use crate::frame::cob_id::NodeId;
use crate::frame::instant::Instant;
use crate::frame::queue::Bounded;
use crate::frame::Frame;
use crate::od::abort::AbortCode;

#[derive(Clone, Copy, Debug)]
pub(super) enum State {
    Idle,
    DownloadInit {
        expedited: bool,
    },
    DownloadSegment {
        toggle: bool,
        offset: usize,
        last: bool,
    },
    /// A streamed segmented download whose next segment waits for the caller's data.
    DownloadWait {
        toggle: bool,
        offset: usize,
    },
    BlockDownloadInit,
    BlockDownload {
        tx: BlockSender,
        crc: bool,
    },
    BlockDownloadEnd,
    UploadInit,
    UploadSegment {
        toggle: bool,
        size: Option<u32>,
    },
    BlockUploadInit,
    BlockUpload {
        rx: BlockReceiver,
        crc: bool,
        size: Option<u32>,
    },
}

pub(super) struct Session<B> {
    pub(super) state: State,
    pub(super) request: RequestId,
    pub(super) node: NodeId,
    pub(super) index: u16,
    pub(super) sub: u8,
    pub(super) channel: Channel,
    pub(super) opts: SdoOptions,
    pub(super) direction: Direction,
    pub(super) mode: TransferMode,
    pub(super) buf: B,
    pub(super) bound: Bound,
    pub(super) deadline: Option<Instant>,
    pub(super) subblock_deadline: Option<Instant>,
    pub(super) out: Bounded<Frame, 4>,
    /// Set while the transfer streams: `buf` is then a window of the value, not all of it.
    pub(super) stream: Option<Stream>,
    /// The answer handled last on `channel`, kept across transfers on it: its second copy is
    /// recognised.
    pub(super) last_rx: Option<[u8; 8]>,
    /// An initiate answer about another object came during this transfer: when no answer of
    /// its own follows, that is what the timeout reports.
    pub(super) stale: bool,
}

impl<B: TransferBuffer> Session<B> {
    pub(super) fn new(limit: usize) -> Self {
        let node = NodeId::must(1);
        Session {
            state: State::Idle,
            request: RequestId(0),
            node,
            index: 0,
            sub: 0,
            channel: Channel::predefined(node),
            opts: SdoOptions::default(),
            direction: Direction::Upload,
            mode: TransferMode::Auto,
            buf: B::with_limit(limit),
            bound: Bound {
                max: limit,
                code: AbortCode::OUT_OF_MEMORY,
            },
            deadline: None,
            subblock_deadline: None,
            out: Bounded::new(),
            stream: None,
            last_rx: None,
            stale: false,
        }
    }
    pub(super) fn active(&self) -> bool {
        !matches!(self.state, State::Idle)
    }
    pub(super) fn send(&mut self, d: [u8; 8]) {
        self.out.push(Frame::from_array(self.channel.request, d));
    }
    pub(super) fn request(&mut self, r: Request) {
        self.send(r.encode());
    }
    pub(super) fn touch(&mut self, now: Instant) {
        self.deadline = Some(now + self.opts.timeout);
    }
}

/// Sends the initiate frame of a download in `mode`.
pub(super) fn start_download<B: TransferBuffer>(s: &mut Session<B>, mode: TransferMode) {
    let (index, sub) = (s.index, s.sub);
    let size = match &s.stream {
        Some(st) => st.total.map(|n| n as u32),
        None => Some(s.buf.len() as u32),
    };
    s.mode = mode;
    match mode {
        TransferMode::Expedited => {
            if let Some(init) = Init::expedited(s.buf.as_slice()) {
                s.request(Request::InitiateDownload { index, sub, init });
                s.state = State::DownloadInit { expedited: true };
                return;
            }
            // Not 1–4 bytes (a fallback from block with such data): segmented it is.
            start_download(s, TransferMode::Segmented)
        }
        TransferMode::Block => {
            let crc = s.opts.crc;
            s.request(Request::BlockDownloadInitiate {
                index,
                sub,
                crc,
                size,
            });
            s.state = State::BlockDownloadInit;
        }
        TransferMode::Segmented | TransferMode::Auto => {
            s.mode = TransferMode::Segmented;
            s.request(Request::InitiateDownload {
                index,
                sub,
                init: Init::Segmented { size },
            });
            s.state = State::DownloadInit { expedited: false };
        }
    }
}

pub(super) fn next_download_segment<B: TransferBuffer>(
    s: &mut Session<B>,
    toggle: bool,
    offset: usize,
) {
    if s.stream.is_some() {
        return stream::next_segment(s, toggle, offset);
    }
    let len = s.buf.len();
    let end = (offset + SEGMENT_DATA).min(len);
    let data = SegmentData::from_slice(&s.buf.as_slice()[offset..end]);
    let last = end == len;
    s.request(Request::DownloadSegment { toggle, data, last });
    s.state = State::DownloadSegment {
        toggle,
        offset: end,
        last,
    };
}

/// Checks an announced upload size and sets the bound for the data to come.
pub(super) fn prepare_upload<B: TransferBuffer>(
    s: &mut Session<B>,
    size: Option<u32>,
) -> Result<(), AbortCode> {
    let limit = s.buf.limit();
    s.bound = Bound {
        max: limit,
        code: AbortCode::OUT_OF_MEMORY,
    };
    if let Some(st) = &mut s.stream {
        // The window is the bound; the announced size is checked against the whole stream.
        st.total = size.map(|n| n as usize);
        s.buf.reserve(limit);
        return Ok(());
    }
    if let Some(n) = size {
        let n = n as usize;
        if n > limit {
            return Err(AbortCode::OUT_OF_MEMORY);
        }
        s.buf.reserve(n);
        s.bound = Bound {
            max: n,
            code: AbortCode::LENGTH_TOO_HIGH,
        };
    }
    Ok(())
}

pub(super) fn upload_segment<B: TransferBuffer>(
    s: &mut Session<B>,
    toggle: bool,
    expected: bool,
    data: SegmentData,
    last: bool,
    size: Option<u32>,
) -> Result<Option<()>, AbortCode> {
    if toggle != expected {
        return Err(AbortCode::TOGGLE_BIT);
    }
    let bytes = data.bytes();
    if s.buf.len() + bytes.len() > s.bound.max || !s.buf.extend(bytes) {
        return Err(s.bound.code);
    }
    let got = stream::received(s);
    if size.is_some_and(|n| got > n as usize) {
        return Err(AbortCode::LENGTH_TOO_HIGH);
    }
    if last {
        if size.is_some_and(|n| got < n as usize) {
            return Err(AbortCode::LENGTH_TOO_LOW);
        }
        return Ok(Some(()));
    }
    stream::request_room(s, Request::UploadSegment { toggle: !toggle }, SEGMENT_DATA);
    s.state = State::UploadSegment {
        toggle: !toggle,
        size,
    };
    Ok(None)
}
