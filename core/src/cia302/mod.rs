//! Layer 7, CiA 302: what a network manager does to the other nodes (`alloc`).
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
//!
//! A master that boots one slave on one wire: it hears the boot-up, checks the slave, writes
//! its configuration over SDO (here a 100 ms heartbeat) and starts it. The loop is what any
//! driver (`duocan`'s simulator, its tokio runtime, a board's main loop) does with the two
//! devices: what one sends the other receives, and time runs to the next deadline.
//!
//! ```
//! use duocan_core::master::{objects, BootPhase, Master, MasterConfig, SlaveConfig};
//! use duocan_core::od::{comm, ObjectDictionary};
//! use duocan_core::{Device, Instant, NmtState, Node, NodeConfig, NodeId, Station};
//!
//! /// Runs two devices on one wire (port 0 of each, no delay) until `until`.
//! fn run(a: &mut impl Device, b: &mut impl Device, mut now: Instant, until: Instant) {
//!     while now <= until {
//!         let mut busy = true;
//!         while busy {
//!             busy = false;
//!             while let Some((_, f)) = a.poll_transmit() { b.handle_rx(now, 0, &f); busy = true; }
//!             while let Some((_, f)) = b.poll_transmit() { a.handle_rx(now, 0, &f); busy = true; }
//!             while a.poll_event().is_some() || b.poll_event().is_some() {}
//!         }
//!         let Some(next) = a.poll_timeout().into_iter().chain(b.poll_timeout()).min() else { break };
//!         now = next;
//!         a.handle_timeout(now);
//!         b.handle_timeout(now);
//!     }
//! }
//!
//! let seven = NodeId::must(7);
//! let net = MasterConfig::new().slave(SlaveConfig::new(seven).mandatory().heartbeat(100, 250));
//! let od = objects::master_dictionary(1, comm::Identity::default());
//! let mut master = Station::single(Master::new(NodeId::must(1), od, net)?);
//! let slave = Node::new(NodeConfig::slave(seven), comm::standard_dictionary(7, Default::default()));
//! let mut slave = Station::single(slave);
//!
//! master.machine.boot(Instant::ZERO);
//! slave.machine.boot(Instant::ZERO);
//! run(&mut master, &mut slave, Instant::ZERO, Instant::from_millis(50));
//!
//! assert_eq!(master.machine.slave(seven).phase, BootPhase::Started);
//! assert_eq!(slave.machine.nmt_state(), NmtState::Operational);
//! assert_eq!(slave.machine.od().get_value::<u16>(comm::HEARTBEAT_PRODUCER, 0), Ok(100));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

#[cfg(feature = "alloc")]
pub mod master;
pub mod pdo_config;
pub mod program;
