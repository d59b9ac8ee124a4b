//! Service data objects (CiA 301 §7.2.4): confirmed access to another node's dictionary.
//!
//! - [`SdoServer`]: serves a node's dictionary on one channel; the [`crate::Node`] owns one
//!   (channel from 0x1200) and hands it the frames of that channel while the NMT state allows SDO.
//! - [`SdoClient`]: a [`crate::Machine`] running up to `S` transfers at once to different
//!   servers; results are [`SdoEvent`]s.
//! - Expedited, segmented and block transfer (with CRC, block size negotiation and
//!   retransmission from the last good segment), upload and download, every CiA 301 abort code
//!   where the standard puts it, timeouts on both sides.
//! - Transfers are bounded by a [`TransferBuffer`]: a heap buffer with a limit (`alloc`) or an
//!   inline array (no_std), never unbounded.
//! - A client transfer may also stream ([`SdoClient::download_stream`],
//!   [`SdoClient::upload_stream`]): a value of any size through a window of the buffer, with
//!   back-pressure both ways.
//!
//! [`codec`] holds the frame formats, [`block`] the sub-block logic both sides share, [`crc`] the
//! block CRC, [`stream`] the client's streamed transfers (the rule, memory, back-pressure).

pub mod block;
mod buffer;
mod client;
pub mod codec;
pub mod crc;
mod error;
mod request;
mod server;
mod session;
pub mod stream;

#[cfg(feature = "alloc")]
pub use buffer::HeapBuffer;
pub use buffer::{DefaultBuffer, InlineBuffer, TransferBuffer, DEFAULT_LIMIT, INLINE_CAPACITY};
pub use client::SdoClient;
pub use error::{Direction, SdoError, SdoErrorKind};
pub use request::{Channel, RequestId, SdoClientStats, SdoEvent, SdoOptions, TransferMode};
pub use server::{SdoServer, SdoServerConfig, SdoServerStats};
pub use stream::MIN_WINDOW;
