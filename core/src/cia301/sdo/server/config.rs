//! How a server behaves: timeouts, block transfer and its sub-block size, the transfer limit.

use crate::cia301::sdo::buffer::DEFAULT_LIMIT;
use crate::cia301::sdo::codec::MAX_BLOCK_SIZE;
use crate::frame::instant::Duration;

/// How a server behaves.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub struct SdoServerConfig {
    /// How long the server waits for the client's next frame before aborting with 0x05040000.
    pub timeout: Duration,
    /// How long the server waits for the rest of a sub-block after a segment before it
    /// acknowledges what it has (recovers a lost end of a sub-block without a full timeout).
    ///
    /// Default 500 ms, half the answer timeout: long enough that a receiver which was not
    /// scheduled for a while (a loaded host) does not acknowledge while the rest of the
    /// sub-block is still on its way, which would have the sender resend what is coming
    /// anyway; short enough that the sender still waits for the acknowledgement.
    pub subblock_timeout: Duration,
    /// Block transfer supported. Without it, block requests get 0x05040001 as from a server
    /// that does not know them, and clients fall back to segmented transfer. A build without
    /// the crate feature `sdo-block` has no block transfer in the server: this is `false` by
    /// default there, and block requests are refused so whatever it says.
    pub block: bool,
    /// CRC supported in block transfer.
    pub crc: bool,
    /// Segments per sub-block the server asks for in block downloads (1–127).
    pub block_size: u8,
    /// Largest value one transfer may carry; beyond it the server answers 0x05040005.
    pub max_transfer: usize,
}

// Builders: the struct is `#[non_exhaustive]` (it may gain fields), so code outside the crate
// starts from a constructor or `Default` and sets what it needs.
impl SdoServerConfig {
    /// The configuration with [`timeout`](Self::timeout) replaced.
    #[must_use]
    pub fn with_timeout(mut self, timeout: Duration) -> Self {
        self.timeout = timeout;
        self
    }
    /// The configuration with [`subblock_timeout`](Self::subblock_timeout) replaced.
    #[must_use]
    pub fn with_subblock_timeout(mut self, subblock_timeout: Duration) -> Self {
        self.subblock_timeout = subblock_timeout;
        self
    }
    /// The configuration with [`block`](Self::block) replaced.
    #[must_use]
    pub fn with_block(mut self, block: bool) -> Self {
        self.block = block;
        self
    }
    /// The configuration with [`crc`](Self::crc) replaced.
    #[must_use]
    pub fn with_crc(mut self, crc: bool) -> Self {
        self.crc = crc;
        self
    }
    /// The configuration with [`block_size`](Self::block_size) replaced.
    #[must_use]
    pub fn with_block_size(mut self, block_size: u8) -> Self {
        self.block_size = block_size;
        self
    }
    /// The configuration with [`max_transfer`](Self::max_transfer) replaced.
    #[must_use]
    pub fn with_max_transfer(mut self, max_transfer: usize) -> Self {
        self.max_transfer = max_transfer;
        self
    }
}

impl Default for SdoServerConfig {
    fn default() -> Self {
        SdoServerConfig {
            timeout: Duration::from_millis(1000),
            subblock_timeout: Duration::from_millis(500),
            block: cfg!(feature = "sdo-block"),
            crc: true,
            block_size: MAX_BLOCK_SIZE,
            max_transfer: DEFAULT_LIMIT,
        }
    }
}
