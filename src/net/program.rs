//! Program download through the front door (CiA 302-3): a new program for a node, by
//! [`RemoteNode::download_program`].
//!
//! **The rule.** The master's own procedure, [`ProgramDownload`], decides the steps and what a
//! failure means (stop, clear, the image to 0x1F50, start, read 0x1F56; a failed step before
//! start resets the node to the program it had, and the new one is never started); the front
//! door only carries its accesses. The image goes by block transfer, streamed
//! ([`RemoteSdo::write_from`](super::RemoteSdo::write_from)), so its size is bounded by the
//! node's transfer limit and store, not by the network's ([`MAX_TRANSFER`](super::MAX_TRANSFER)),
//! and `progress` hears how much of it the node has confirmed.

use super::error::NetError;
use super::remote::RemoteNode;
use super::sdo_stream::TransferProgress;
use crate::cia301::sdo::TransferMode;
use crate::cia302::master::{ProgramAccess, ProgramDownload, ProgramReport};

impl RemoteNode {
    /// Downloads `image` as the node's new program and starts it (the master's CiA 302-3
    /// procedure, see [`ProgramDownload`]); returns the node-ID, the size and the software
    /// identification the node reports afterwards (0x1F56 sub 1). A step that fails is
    /// [`NetError::Program`] naming it; the network closing or a local failure comes as
    /// itself. `progress` hears the image's bytes as the node confirms them.
    ///
    /// ```
    /// # #[tokio::main(flavor = "current_thread", start_paused = true)]
    /// # async fn main() -> Result<(), Box<dyn std::error::Error>> {
    /// # let bus = duocan::port::mem::MemBus::new("doc");
    /// # let net = duocan::net::Network::open(bus.port())?;
    /// // A node without program download objects refuses the first step.
    /// # let _ = duocan::net::Network::simulated_on(&bus, [5], Default::default());
    /// let e = net.node(5).download_program(&[1, 2, 3], |_| {}).await.unwrap_err();
    /// assert!(matches!(e, duocan::net::NetError::Program(_)));
    /// # Ok(()) }
    /// ```
    pub async fn download_program(
        &self,
        image: &[u8],
        mut progress: impl FnMut(TransferProgress),
    ) -> Result<ProgramReport, NetError> {
        let mut run = ProgramDownload::new(self.id()?, image.to_vec(), 0);
        let sdo = self.sdo();
        let block = sdo.clone().with_mode(TransferMode::Block);
        while let Some(access) = run.access() {
            let r = match access {
                ProgramAccess::Write {
                    index,
                    sub,
                    data,
                    block: true,
                } => block
                    .write_from(index, sub, data, Some(data.len() as u64), &mut progress)
                    .await
                    .map(|_| Vec::new()),
                ProgramAccess::Write {
                    index, sub, data, ..
                } => sdo.write_bytes(index, sub, data).await.map(|()| Vec::new()),
                ProgramAccess::Read { index, sub } => sdo.read_bytes(index, sub).await,
            };
            match r {
                Ok(data) => run.handle(Ok(&data)),
                Err(NetError::Sdo(e)) => run.handle(Err(e)),
                Err(e) => return Err(e),
            }
        }
        match run.result() {
            Some(Ok(report)) => Ok(report),
            Some(Err(e)) => Err(NetError::Program(e)),
            None => Err(NetError::Closed),
        }
    }
}
