//! What a client request is: the channel it goes on, its options, its id, and the event that
//! reports its result.

use super::buffer::{DefaultBuffer, TransferBuffer};
use super::codec::MAX_BLOCK_SIZE;
use super::error::{Direction, SdoError};
use crate::frame::cob_id::{predefined, CobId, NodeId};
use crate::frame::instant::{Duration, Instant};
use crate::frame::Id;
use core::fmt;

/// The pair of identifiers of one client–server channel (CiA 301 0x1280 sub 1 and sub 2).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Channel {
    /// Client → server.
    pub request: Id,
    /// Server → client.
    pub response: Id,
}

impl Channel {
    /// The default channel of a node's first server: 0x600 + n and 0x580 + n.
    #[must_use]
    pub const fn predefined(node: NodeId) -> Channel {
        Channel {
            request: predefined::sdo_rx(node),
            response: predefined::sdo_tx(node),
        }
    }
    /// A channel from the COB-IDs of an SDO client parameter (0x1280 sub 1, sub 2); `None` if
    /// either is invalid (bit 31) or malformed.
    pub fn from_cob_ids(client_to_server: u32, server_to_client: u32) -> Option<Channel> {
        let id = |v: u32| {
            let c = CobId(v);
            if c.is_valid() {
                c.can_id()
            } else {
                None
            }
        };
        Some(Channel {
            request: id(client_to_server)?,
            response: id(server_to_client)?,
        })
    }
}

/// Which SDO protocol a transfer uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TransferMode {
    /// Download: expedited for 1–4 bytes, block from [`SdoOptions::block_threshold`] on,
    /// segmented otherwise. Upload: the server chooses expedited or segmented.
    Auto,
    /// Expedited (1–4 bytes, one frame each way).
    Expedited,
    /// Segmented (7 bytes per round trip).
    Segmented,
    /// Block transfer; falls back to expedited/segmented when the server answers 0x05040001.
    Block,
}

/// How one transfer is carried out.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub struct SdoOptions {
    /// Protocol.
    pub mode: TransferMode,
    /// How long to wait for each answer before aborting with 0x05040000.
    pub timeout: Duration,
    /// Block upload: how long to wait for the rest of a sub-block before acknowledging what
    /// arrived (recovers a lost end of a sub-block without a full timeout).
    ///
    /// Default 500 ms, half the answer timeout: long enough that a receiver which was not
    /// scheduled for a while (a loaded host) does not acknowledge while the rest of the
    /// sub-block is still on its way, which would have the sender resend what is coming
    /// anyway; short enough that the sender still waits for the acknowledgement.
    pub subblock_timeout: Duration,
    /// Offer CRC in block transfer (used when the server supports it too).
    pub crc: bool,
    /// Block upload: segments per sub-block (1–127).
    pub block_size: u8,
    /// Block upload: protocol switch threshold; the server may answer expedited/segmented when
    /// the value has at most this many bytes (0: never).
    pub pst: u8,
    /// [`TransferMode::Auto`] downloads of at least this many bytes use block transfer.
    pub block_threshold: Option<usize>,
    /// The channel, if not the client's default for the node.
    pub channel: Option<Channel>,
}

// Builders: the struct is `#[non_exhaustive]` (it may gain fields), so code outside the crate
// starts from a constructor or `Default` and sets what it needs.
impl SdoOptions {
    /// The options with [`mode`](Self::mode) replaced.
    #[must_use]
    pub fn with_mode(mut self, mode: TransferMode) -> Self {
        self.mode = mode;
        self
    }
    /// The options with [`timeout`](Self::timeout) replaced.
    #[must_use]
    pub fn with_timeout(mut self, timeout: Duration) -> Self {
        self.timeout = timeout;
        self
    }
    /// The options with [`subblock_timeout`](Self::subblock_timeout) replaced.
    #[must_use]
    pub fn with_subblock_timeout(mut self, subblock_timeout: Duration) -> Self {
        self.subblock_timeout = subblock_timeout;
        self
    }
    /// The options with [`crc`](Self::crc) replaced.
    #[must_use]
    pub fn with_crc(mut self, crc: bool) -> Self {
        self.crc = crc;
        self
    }
    /// The options with [`block_size`](Self::block_size) replaced.
    #[must_use]
    pub fn with_block_size(mut self, block_size: u8) -> Self {
        self.block_size = block_size;
        self
    }
    /// The options with [`pst`](Self::pst) replaced.
    #[must_use]
    pub fn with_pst(mut self, pst: u8) -> Self {
        self.pst = pst;
        self
    }
    /// The options with [`block_threshold`](Self::block_threshold) replaced.
    #[must_use]
    pub fn with_block_threshold(mut self, block_threshold: Option<usize>) -> Self {
        self.block_threshold = block_threshold;
        self
    }
    /// The options with [`channel`](Self::channel) replaced.
    #[must_use]
    pub fn with_channel(mut self, channel: Option<Channel>) -> Self {
        self.channel = channel;
        self
    }
}

impl Default for SdoOptions {
    fn default() -> Self {
        SdoOptions {
            mode: TransferMode::Auto,
            timeout: Duration::from_millis(1000),
            subblock_timeout: Duration::from_millis(500),
            crc: true,
            block_size: MAX_BLOCK_SIZE,
            pst: 0,
            block_threshold: None,
            channel: None,
        }
    }
}

impl SdoOptions {
    /// The defaults with another mode.
    #[must_use]
    pub fn mode(mode: TransferMode) -> Self {
        SdoOptions {
            mode,
            ..SdoOptions::default()
        }
    }
}

/// Names one request of a client.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct RequestId(pub u32);

impl fmt::Display for RequestId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "SDO request #{}", self.0)
    }
}

/// The result of a request.
#[derive(Clone, Debug, PartialEq)]
pub struct SdoEvent<B = DefaultBuffer> {
    /// When it finished.
    pub at: Instant,
    /// Which request.
    pub request: RequestId,
    /// The server's node.
    pub node: NodeId,
    /// Object index.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// Upload or download.
    pub direction: Direction,
    /// The protocol finally used (after a fallback from block, the one fallen back to).
    pub mode: TransferMode,
    /// The uploaded bytes (empty for a download), or why it failed.
    pub result: Result<B, SdoError>,
}

impl<B: TransferBuffer> SdoEvent<B> {
    /// The uploaded bytes, if the request succeeded.
    pub fn data(&self) -> Option<&[u8]> {
        self.result.as_ref().ok().map(|b| b.as_slice())
    }
}

/// One line: `SDO request #3: upload from node 0x10 0x1018sub1, 4 bytes`, or the error's own.
impl<B: TransferBuffer> fmt::Display for SdoEvent<B> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.result {
            Ok(b) => write!(
                f,
                "{}: {} {} {:#06x}sub{}, {} bytes",
                self.request,
                self.direction,
                self.node,
                self.index,
                self.sub,
                b.as_slice().len()
            ),
            Err(e) => write!(f, "{}: {e}", self.request),
        }
    }
}

/// Counters of a client.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SdoClientStats {
    /// Requests accepted.
    pub started: u32,
    /// Requests that succeeded.
    pub completed: u32,
    /// Requests that failed.
    pub failed: u32,
    /// Block transfers that fell back to segmented.
    pub fallbacks: u32,
    /// Frames on a session's identifier that are no SDO frame (remote, not 8 bytes).
    pub malformed: u32,
    /// Frames dropped because the output was not drained.
    pub tx_dropped: u32,
    /// Results dropped because nobody polled them (cannot happen: sessions stay taken until
    /// their result is polled).
    pub events_dropped: u32,
    /// Second copies ignored: an answer equal to the one before it on its channel that the
    /// transfer could not take (a twin the dual-bus layer delivered late, a frame CAN delivered
    /// twice), or a sub-block acknowledgement after the last one (see [`SdoClient`]).
    ///
    /// [`SdoClient`]: super::SdoClient
    pub repeats: u32,
    /// Initiate answers ignored because they name another object than the transfer's: an
    /// answer to an earlier request on the channel, delivered late (a lagging bus's twin). A
    /// transfer that gets no answer of its own after one ends at its timeout with 0x06040043
    /// (general parameter incompatibility), as it would have at once.
    pub stale: u32,
}
