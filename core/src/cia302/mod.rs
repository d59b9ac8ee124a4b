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
//! A master that boots one slave on the simulated bus: it hears the boot-up, checks the slave,
//! writes its configuration over SDO (here a 100 ms heartbeat) and starts it.
//!
//! ```
//! use duocan::master::{objects, BootPhase, Master, NetworkConfig, SlaveConfig};
//! use duocan::od::{comm, ObjectDictionary};
//! use duocan::sim::{BusConfig, SimNetwork};
//! use duocan::{Instant, NmtState, Node, NodeConfig, NodeId, Station};
//!
//! let seven = NodeId::must(7);
//! let net = NetworkConfig::new().slave(SlaveConfig::new(seven).mandatory().heartbeat(100, 250));
//! let od = objects::master_dictionary(1, comm::Identity::default());
//! let master = Master::new(NodeId::must(1), od, net)?;
//! let slave = Node::new(NodeConfig::slave(seven), comm::standard_dictionary(7, Default::default()));
//!
//! let mut sim = SimNetwork::new(1);
//! let bus = sim.add_bus(BusConfig::new("can0", 500_000));
//! let m = sim.add_device("master", Station::single(master), &[bus])?;
//! let s = sim.add_device("slave 7", Station::single(slave), &[bus])?;
//! sim.device_mut(m).machine.boot(Instant::ZERO);
//! sim.device_mut(s).machine.boot(Instant::ZERO);
//! sim.run_until(Instant::from_millis(50));
//!
//! assert_eq!(sim.device(m).machine.slave(seven).phase, BootPhase::Started);
//! let slave = &sim.device(s).machine;
//! assert_eq!(slave.nmt_state(), NmtState::Operational);
//! assert_eq!(slave.od().get_value::<u16>(comm::HEARTBEAT_PRODUCER, 0), Ok(100));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

#[cfg(feature = "alloc")]
pub mod master;
pub mod pdo_config;
pub mod program;
