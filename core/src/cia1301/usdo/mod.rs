//! USDO, the universal service data object of CANopen FD (CiA 1301): confirmed reads and
//! writes of any node's dictionary over CAN FD frames, expedited (up to 56 bytes in one frame)
//! or segmented (60 bytes a segment), from any client to any server without configured
//! channels.
//!
//! - [`UsdoServer`] serves a node's dictionary through [`ObjectAccess`](crate::od::ObjectAccess),
//!   the path the SDO server takes: the same access rights, type and length checks, hooks and
//!   reactions to writes.
//! - [`UsdoClient`] runs one transfer at a time to any server; the result is a [`UsdoEvent`].
//! - [`codec`] holds the frame formats, [`UsdoAbort`] the one-byte abort codes.
//! - A [`Node`](crate::Node) configured for a CANopen FD network
//!   ([`NodeConfig::fd`](crate::NodeConfig::fd)) runs a [`UsdoServer`] over its dictionary, fed
//!   through [`Machine::handle_frame_fd`](crate::Machine::handle_frame_fd); a
//!   [`Station`](crate::Station) hands it the FD frames of an FD-capable link
//!   ([`SinglePort::fd`](crate::machine::SinglePort::fd)).
//!
//! # Addressing and sessions
//!
//! A request goes out on **0x600 + the client's node-ID** and names its server in the
//! destination byte (**0: every server**); an answer goes out on **0x580 + the server's
//! node-ID** and names the client. So the identifier says who sent a frame, and a server tells
//! its clients apart by it. Each transfer carries the client's session byte, which every answer
//! repeats: a client ignores answers in another session (a late answer to an earlier transfer)
//! and counts them ([`UsdoClientStats::ignored`]).
//!
//! The rule for sessions, on the server: **one transfer per client–server pair**. An initiate
//! request from a client that runs a segmented transfer in another session is refused with an
//! abort (0x060A0023, resource not available) and the running transfer goes on; an initiate in
//! the running session's own number means the client started over, and replaces it. A server
//! runs up to `SESSIONS` segmented transfers (with different clients) at once; one more is
//! refused the same way. Expedited transfers are answered at once and hold no session.
//!
//! A broadcast request (destination 0) is served by every server that can answer it in one
//! frame: an expedited write, or a read of at most 56 bytes; each server answers the client on
//! its own identifier. A broadcast segmented write, or a broadcast read of a longer value, is
//! refused with an abort (0x06010000, unsupported access); broadcast segments are ignored.
//!
//! # Second copies
//!
//! CAN may deliver a frame twice, and on a redundant network the dual-bus layer delivers a twin
//! that arrives later than its merge window as a frame of its own. Two segment frames in a row
//! of one transfer are never equal (the toggle alternates), so a segment request (server) or
//! segment answer (client) equal to the one taken before it is such a copy: it is ignored and
//! counted ([`UsdoServerStats::repeats`], [`UsdoClientStats::repeats`]), not aborted as a
//! toggle error. A copy that arrives after the peer's next frame can no longer be told from a
//! new one; the transfer then ends as the protocol says (an abort).
//!
//! # Memory, overflow, order
//!
//! The server holds `SESSIONS` transfer buffers and the client one, each bounded by the limit
//! it was built with: a value larger is refused (0x05040005, out of memory), never grown past
//! it. Their output queues are bounded (8 frames for the server, 2 for the client, more than
//! one step of the protocol ever produces); a frame past that is dropped and counted
//! ([`UsdoServerStats::tx_dropped`]). Frames leave in the order the machine produced them; a
//! segmented write reaches the dictionary once, when its last segment arrived, so an aborted
//! write leaves the entry as it was, and a segmented read copies the value when it starts, so
//! the client reads one consistent value.
//!
//! Bytes from the bus are never trusted: a frame too short, an unknown command specifier, a
//! length past the frame's end, a wrong toggle or more data than announced is an abort (or,
//! without a destination and session to answer to, a refusal counted in
//! [`UsdoServerStats::malformed`]), never a panic. A transfer whose peer falls silent for the
//! timeout is aborted with 0x05040000 on both sides.
//!
//! # Frame layout: where it came from
//!
//! The CiA 1301 text was not at hand. Taken from public descriptions of the protocol:
//!
//! - CAN in Automation's USDO page ("Universal Service Data Object", can-cia.org) and its
//!   article on uni-, broad- and multicast: the CAN-ID carries the sender's node-ID; the
//!   protocol bytes are, in this order, the destination address (a node, or all of them), the
//!   command specifier, the session-ID (a transaction number of the client), the index, the
//!   sub-index, then the data type and size of the value, which let the receiver check it.
//! - emtas' (embedded-communication.com) USDO overview: an expedited frame carries at most 56
//!   data bytes beside 8 bytes of protocol information; a server with too many sessions
//!   refuses ("server busy"), and refuses a broadcast with a unicast abort.
//! - The issue asking for USDO, and the common account of CiA 1301: abort codes are one byte.
//!
//! duocan's choices, where those sources give no values:
//!
//! | Byte | Initiate and expedited frames | Segment frames |
//! | --- | --- | --- |
//! | 0 | destination node-ID, 0 = broadcast | destination |
//! | 1 | command specifier | command specifier |
//! | 2 | session | session |
//! | 3–4 | index, little-endian | 3: bit 7 last, bit 6 toggle, bits 0–5 data length (0–60) |
//! | 5 | sub-index | 4…: data |
//! | 6 | CiA 301 data type index (0: not given); in an abort, the abort byte | |
//! | 7 | expedited: data length (0–56) | |
//! | 8… | expedited: data; segmented initiate: total size (4 bytes, little-endian) | |
//!
//! Command specifiers: requests 0x01 expedited write, 0x02 segmented write, 0x03 write segment,
//! 0x04 read, 0x05 read segment; answers 0x41 write done or accepted, 0x43 write segment
//! taken, 0x44 expedited value, 0x46 segmented value (total size), 0x45 read segment; 0x80
//! abort either way. Segments alternate a toggle bit from 0, as SDO's do; the abort bytes are
//! [`UsdoAbort`]'s table. A frame is padded with 0xCC to the next CAN FD length and sent with
//! the bit rate switch on. Bulk transfer and the remote (routed) services are not here.
//!
//! ```
//! use duocan_core::cia1301::usdo::{UsdoClient, UsdoServer};
//! use duocan_core::od::{Access, DynamicDictionary, ObjectDef};
//! # use duocan_core::od::{abort::AbortCode, Entry, ObjectAccess, ObjectDictionary};
//! use duocan_core::{Duration, Instant, NodeId};
//! # // A dictionary reached as a bus client would: what a node gives its servers.
//! # struct Od(DynamicDictionary);
//! # impl ObjectAccess for Od {
//! #     fn entry(&self, i: u16, s: u8) -> Result<Entry<'_>, AbortCode> { self.0.get(i, s) }
//! #     fn read(&self, i: u16, s: u8) -> Result<&[u8], AbortCode> { Ok(self.0.get(i, s)?.data) }
//! #     fn write(&mut self, _: Instant, i: u16, s: u8, d: &[u8]) -> Result<(), AbortCode> { self.0.store(i, s, d) }
//! # }
//! let mut od = DynamicDictionary::new(5);
//! od.insert(ObjectDef::u32(0x2000, 0, Access::Rw, 7)).unwrap();
//! let mut od = Od(od);
//! let (client_node, server_node) = (NodeId::must(1), NodeId::must(5));
//! let timeout = Duration::from_millis(100);
//! let mut server: UsdoServer = UsdoServer::new(server_node, timeout, 4096);
//! let mut client: UsdoClient = UsdoClient::new(client_node, 4096);
//!
//! // Write 4 bytes: one request on 0x601 (from node 1), one answer on 0x585 (from node 5).
//! client.download(Instant::ZERO, server_node, 0x2000, 0, 7, &[1, 2, 3, 4], timeout).unwrap();
//! let request = client.poll_transmit().unwrap();
//! assert_eq!(&request.data()[..3], [5, 0x01, 1]); // to node 5, expedited write, session 1
//! server.handle_frame(Instant::from_millis(1), &request, &mut od).unwrap();
//! let answer = server.poll_transmit().unwrap();
//! client.handle_frame(Instant::from_millis(2), &answer);
//! assert!(client.poll_event().unwrap().result.is_ok());
//!
//! // Read it back; then a read nobody answers ends at its deadline with a timeout.
//! client.upload(Instant::from_millis(3), server_node, 0x2000, 0, timeout).unwrap();
//! server.handle_frame(Instant::from_millis(4), &client.poll_transmit().unwrap(), &mut od).unwrap();
//! client.handle_frame(Instant::from_millis(5), &server.poll_transmit().unwrap());
//! assert_eq!(client.poll_event().unwrap().data(), Some(&[1, 2, 3, 4][..]));
//! client.upload(Instant::from_millis(10), NodeId::must(9), 0x2000, 0, timeout).unwrap();
//! assert_eq!(client.poll_timeout(), Some(Instant::from_millis(110)));
//! client.handle_timeout(Instant::from_millis(110));
//! let err = client.poll_event().unwrap().result.unwrap_err();
//! assert_eq!(err.code(), Some(AbortCode::TIMEOUT));
//! ```

mod abort;
mod client;
pub mod codec;
mod event;
mod server;
#[cfg(test)]
mod tests;

pub use abort::UsdoAbort;
pub use client::UsdoClient;
pub use event::{UsdoClientStats, UsdoError, UsdoErrorKind, UsdoEvent};
pub use server::{UsdoServer, UsdoServerStats};

use crate::frame::cob_id::NodeId;
use crate::frame::Id;

/// Base of the identifiers USDO requests go out on: 0x600 + the client's node-ID.
pub const REQUEST_BASE: u16 = 0x600;
/// Base of the identifiers USDO answers go out on: 0x580 + the server's node-ID.
pub const ANSWER_BASE: u16 = 0x580;

/// The identifier a client's requests go out on.
pub const fn request_id(client: NodeId) -> Id {
    Id::Standard(REQUEST_BASE + client.raw() as u16)
}

/// The identifier a server's answers go out on.
pub const fn answer_id(server: NodeId) -> Id {
    Id::Standard(ANSWER_BASE + server.raw() as u16)
}

/// The client that sent a request on `id`, if `id` is a USDO request identifier.
pub fn client_of(id: Id) -> Option<u8> {
    match id {
        Id::Standard(raw) if (REQUEST_BASE + 1..=REQUEST_BASE + 127).contains(&raw) => {
            Some((raw - REQUEST_BASE) as u8)
        }
        _ => None,
    }
}
