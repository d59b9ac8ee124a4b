//! Layer 6, CiA 302: what a network manager does to the other nodes (`alloc`).
//!
//! - [`master`]: the CiA 302-2 NMT master: boot-up of the network, identity check, slave
//!   configuration, mandatory slaves, boot time, request NMT (0x1F82), active/standby hooks.
//! - [`program`]: program download on the node's side (CiA 302-3 0x1F50/0x1F51/0x1F56/0x1F57),
//!   served by a program store the application implements.
//! - [`pdo_config`]: configuring a slave's PDOs over SDO in CiA order, and mirroring them in the
//!   master's own dictionary.
//!
//! Both run on a [node](crate::node) and its CiA 301 services; nothing below this layer knows
//! that a master exists.

#[cfg(feature = "alloc")]
pub mod master;
pub mod pdo_config;
pub mod program;
