//! Building the gateway in two steps, as the firmware does: `Gateway::unstarted` (built in
//! place, silent) and `Gateway::start` (profile checked, dictionary loaded, node booted).

use duocan::od::ObjectDictionary;
use duocan::profile::railway::{DeviceAddress, RailwayProfile};
use duocan::{Instant, NmtState, NodeId};
use safety_gateway::dictionary::{Od, FIELD_TIMEOUT};
use safety_gateway::mock::{MockCan, Wire};
use safety_gateway::{Gateway, SetupError, ADDRESS, NODE_ID};

/// An unstarted gateway on three fresh wires, its profile built from `network`.
fn unstarted(
    network: &[(NodeId, DeviceAddress)],
) -> (Gateway<MockCan<'static>>, &'static [Wire; 3]) {
    let w: &'static [Wire; 3] = Box::leak(Box::new([Wire::new(), Wire::new(), Wire::new()]));
    let ends = w.each_ref().map(|wire| {
        let [end, _] = wire.ends();
        end
    });
    let profile = Box::leak(Box::new(RailwayProfile::with(network).unwrap()));
    let od = Box::leak(Box::new(Od::new()));
    (Gateway::unstarted(profile, od, ends, Instant::ZERO), w)
}

#[test]
fn an_unstarted_gateway_is_silent_and_starts_once() {
    let (mut gw, w) = unstarted(&[(NODE_ID, ADDRESS)]);
    assert_eq!(gw.node().nmt_state(), NmtState::Initialising);
    assert!(
        gw.node().od().get(FIELD_TIMEOUT, 0).is_err(),
        "the dictionary is empty until start"
    );
    assert_eq!(w[0].in_flight() + w[1].in_flight(), 0, "nothing sent");

    gw.start(Instant::ZERO).unwrap();
    assert_eq!(gw.node().nmt_state(), NmtState::PreOperational);
    assert!(gw.node().od().get(FIELD_TIMEOUT, 0).is_ok());
    assert!(
        gw.poll(Instant::ZERO).is_some(),
        "the heartbeat timer is armed"
    );
    assert_eq!(w[0].in_flight(), 1, "boot-up message on bus 1");
    assert_eq!(w[1].in_flight(), 1, "and on bus 2");

    assert_eq!(gw.start(Instant::ZERO), Err(SetupError::AlreadyStarted));
    assert_eq!(
        gw.node().nmt_state(),
        NmtState::PreOperational,
        "still running"
    );
    assert_eq!(w[0].in_flight(), 1, "no second boot-up");
}

#[test]
fn a_gateway_whose_profile_lacks_it_does_not_start() {
    let other = DeviceAddress::board_at(1, 4, 1, 2);
    let (mut gw, w) = unstarted(&[(NODE_ID, other)]);
    assert_eq!(
        gw.start(Instant::ZERO),
        Err(SetupError::NotInProfile {
            node: NODE_ID,
            address: ADDRESS
        })
    );
    assert_eq!(gw.node().nmt_state(), NmtState::Initialising, "not booted");
    assert_eq!(w[0].in_flight() + w[1].in_flight(), 0, "nothing sent");
}
