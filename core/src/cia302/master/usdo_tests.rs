//! A CiA 302 master on a CANopen FD network serves USDO (CiA 1301) from its dictionary, as
//! its node would alone: the [`Machine`] passes CAN FD frames to the node.

use super::*;
use crate::frame::instant::Instant;
use crate::machine::{Device, SinglePort, Station};
use crate::node::usdo_tests::Bus;
use crate::od::abort::AbortCode;

const ME: NodeId = NodeId::must(1);

/// The master (node 1, FD as `fd`) with no slaves, booted, on an FD port.
fn master(fd: bool) -> Station<SinglePort, Master<crate::od::DynamicDictionary>> {
    let od = objects::master_dictionary(ME.raw(), comm::Identity::default());
    let config = MasterConfig::new();
    let sdo = MasterSdoClient::with_sessions(DEFAULT_LIMIT, config.sdo_sessions);
    let m = Master::with_parts(
        NodeConfig::master(ME).with_fd(fd),
        od,
        Predefined,
        sdo,
        config,
    )
    .unwrap();
    let mut st = Station::new(SinglePort::fd(), m);
    st.machine.boot(Instant::ZERO);
    while st.poll_transmit().is_some() {}
    st
}

#[test]
fn a_master_serves_usdo_from_its_dictionary() {
    let mut bus = Bus::serving(master(true), ME);
    assert!(bus.dev.fd_capable());
    // 0x1000, the device type: the master's own entry.
    let want = bus
        .dev
        .machine
        .node()
        .od()
        .get(0x1000, 0)
        .unwrap()
        .data
        .to_vec();
    assert_eq!(bus.read(0x1000), Ok(want));
    // A write is stored: the heartbeat producer time.
    assert_eq!(bus.write(0x1017, &200u16.to_le_bytes()), Ok(()));
    assert_eq!(bus.read(0x1017), Ok(200u16.to_le_bytes().to_vec()));
    assert_eq!(bus.write(0x6789, &[1]), Err(AbortCode::NO_OBJECT));
    assert!(bus
        .answers
        .iter()
        .all(|f| f.id() == crate::frame::Id::Standard(0x581)));
    let u = bus.dev.machine.node().usdo_server().unwrap().stats();
    assert_eq!((u.completed, u.aborted), (3, 1));
}

#[test]
fn a_classic_master_leaves_fd_frames_alone() {
    let mut st = master(false);
    let req = crate::frame::FdFrame::new(crate::frame::Id::Standard(0x601), &[0; 12]).unwrap();
    st.handle_rx_fd(Instant::from_millis(1), 0, &req, Instant::from_millis(1));
    assert_eq!(st.poll_transmit_fd(), None);
    assert!(st.machine.node().usdo_server().is_none());
}
