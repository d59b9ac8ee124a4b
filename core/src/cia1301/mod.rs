//! Layer 4, the CANopen FD services of CiA 1301 (feature `fd`): beside the CiA 301 services of
//! [`crate::cia301`], on the same dictionary and frame primitives, carried in
//! [CAN FD frames](crate::frame::fd).
//!
//! | Object | Module | Identifiers |
//! | --- | --- | --- |
//! | USDO server and client: expedited (up to 56 bytes) and segmented | [`usdo`] | 0x600 + client (requests), 0x580 + server (answers) |

pub mod usdo;
