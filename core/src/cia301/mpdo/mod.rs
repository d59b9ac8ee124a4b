//! Multiplexed PDOs (CiA 301 MPDO, `mpdo` feature): one PDO that carries, frame by frame, the
//! value of any object together with its index and sub-index.
//!
//! # The rule
//!
//! A PDO is an MPDO when its mapping count (sub 0 of 0x16xx/0x1Axx) is **0xFE**
//! (source-address mode, SAM) or **0xFF** (destination-address mode, DAM); its other mapping
//! entries are not used. The node's PDO engine then treats it so; every other count is a
//! classic PDO, unchanged.
//!
//! - **DAM, producer**: the application sends a value to object (index, sub) of node N, or of
//!   every node with N = 0 ([`Node::mpdo_send_dam`](crate::node::Node::mpdo_send_dam)) on a
//!   TPDO whose count is 0xFF.
//! - **DAM, consumer**: an RPDO marked as MPDO takes a DAM frame addressed to its node or to 0
//!   and writes the value into (index, sub) by the rules of an RPDO-mapped write
//!   ([`access::write`]: the entry exists, is RPDO-mappable, writable and of a fixed size the
//!   value covers). A frame for another node is ignored and counted.
//! - **SAM, producer**: the application sends one of its own objects
//!   ([`Node::mpdo_send_sam`](crate::node::Node::mpdo_send_sam)) on a TPDO whose count is
//!   0xFE; only objects the **object scanner list** (0x1FA0–0x1FCF) covers go out, with the
//!   node's own ID in byte 0.
//! - **SAM, consumer**: an RPDO marked as MPDO looks the producer's node-ID, index and
//!   sub-index up in the **object dispatcher list** (0x1FD0–0x1FFF) and writes the value into
//!   the local object it names, by the same rules; a frame no entry covers is ignored and
//!   counted.
//!
//! An RPDO marked as MPDO (0xFE or 0xFF) takes both address types, each by its own rule: the
//! frame's bit 7 decides, so one RPDO can receive the master's DAM writes and a neighbour's
//! SAM values on one identifier. Writes that land trigger event-driven TPDOs mapping the
//! object, as an RPDO's do. A write the dictionary refuses is counted
//! ([`MpdoStats::refused`]) and reported ([`PdoEvent::MpdoRefused`](crate::pdo::PdoEvent)),
//! never a panic.
//!
//! # Memory, overflow, order
//!
//! Nothing is copied out of the dictionary: the scanner and dispatcher lists are read where
//! they are stored, at each frame (their sub 0 says how many entries each index holds, at most
//! 254), so they have no capacity of their own to overflow, and a change through SDO takes
//! effect with the next frame. The cost is a walk over the list objects present. The counters
//! ([`MpdoStats`]) saturate. Each frame is handled when it arrives (asynchronous RPDO) or at
//! the next SYNC (synchronous RPDO: the last frame before the SYNC, as any RPDO), in the order
//! received; the dispatcher list is searched in index and sub-index order and the first entry
//! that covers the object wins.
//!
//! # Frame layout: where it came from
//!
//! - **Classic MPDO** ([`Mpdo`]): CiA 301's layout: byte 0 bit 7 address type (0 SAM, 1 DAM),
//!   bits 0–6 node-ID; bytes 1–2 index (little-endian); byte 3 sub-index; bytes 4–7 data,
//!   little-endian. Always 8 bytes; another length is refused.
//! - **Scanner list entry** ([`ScannerEntry`], UNSIGNED32): bits 0–7 sub-index, 8–23 index,
//!   24–31 block size; **dispatcher list entry** ([`DispatcherEntry`], UNSIGNED64): bits 0–7
//!   producer node-ID, 8–15 producer sub-index, 16–31 producer index, 32–39 local sub-index,
//!   40–55 local index, 56–63 block size. These are the layouts of CiA 301 as this crate's
//!   authors know them; the public references searched while writing this module did not
//!   contain the CiA table to check them against. A block size of 0 covering nothing is this
//!   crate's choice.
//! - **FD MPDO** ([`FdMpdo`], `fd` feature): **this crate's own choice**; the CiA 1301 text
//!   was not at hand (neither the public references searched nor CiA 301 give an FD layout).
//!   It keeps CiA 301's classic layout (above) in a CAN FD frame: the four header bytes are the
//!   classic ones and the value follows from byte 4, little-endian, so a value of up to four
//!   bytes is the classic MPDO's eight bytes exactly; a longer one (up to 60 bytes) is
//!   zero-filled to the CAN FD length that holds it. A received FD MPDO must have a CAN FD
//!   length from 8 to 64 bytes (another is counted in [`MpdoStats::malformed`]). On a CANopen
//!   FD network (the node's `NodeConfig::fd`) the engine sends every MPDO in this form, in
//!   destination- and source-address mode alike, and takes it, classic MPDOs still, on an
//!   MPDO RPDO; the object takes as many of the value's bytes as it holds. A synchronous MPDO
//!   RPDO keeps a frame's first eight bytes to the SYNC (the engine's inline buffer: no more
//!   memory), so there values of up to four bytes apply and longer ones are refused as too
//!   short; an asynchronous one takes any.
//! - Transmission by the application only: an MPDO TPDO is not sent by SYNC, event timer or
//!   remote request (it has no fixed content to send), and its inhibit time is not applied.
//!
//! Bytes from the bus are never trusted: a frame of the wrong length, or a SAM from node 0, is
//! counted in [`MpdoStats::malformed`] and dropped.
//!
//! ```
//! use duocan_core::mpdo::{DispatcherEntry, Mode, Mpdo, ScannerEntry};
//!
//! // The master writes 0x1234 into 0x2000/1 of node 5.
//! let m = Mpdo::dam(5, 0x2000, 1, &[0x34, 0x12]).unwrap();
//! assert_eq!(m.to_bytes(), [0x85, 0x00, 0x20, 0x01, 0x34, 0x12, 0, 0]);
//! assert_eq!(Mpdo::decode(&m.to_bytes()), Ok(m));
//! assert!(Mpdo::decode(&[0x85, 0, 0x20]).is_err());
//!
//! // Node 7 may send 0x6000/1..=4; a consumer maps node 7's 0x6000/2 to its 0x2100/12.
//! let scan = ScannerEntry::from_raw(0x04_6000_01);
//! assert!(scan.covers(0x6000, 4) && !scan.covers(0x6000, 5));
//! let disp = DispatcherEntry::from_raw(0x04_2100_0B_6000_01_07);
//! assert_eq!(disp.map(7, 0x6000, 2), Some((0x2100, 0x0C)));
//! assert_eq!(disp.map(8, 0x6000, 2), None);
//! assert_eq!(Mode::from_mapping_count(0xFE), Some(Mode::Source));
//! ```

pub mod access;
mod codec;
#[cfg(feature = "fd")]
mod fd;
mod lists;
mod tables;

pub use access::{MpdoError, MpdoStats};
pub use codec::{Mode, Mpdo, MpdoDecodeError, DAM_COUNT, DATA_LEN, LEN, SAM_COUNT};
#[cfg(feature = "fd")]
pub use fd::{FdMpdo, FD_DATA_MAX};
pub use lists::{dispatch, scanned, DispatcherEntry, ScannerEntry, DISPATCHER, SCANNER};
pub use tables::{dispatcher_list, scanner_list, LISTS};

// The tests use the dynamic dictionary and proptest.
#[cfg(all(test, feature = "std"))]
mod tests;
