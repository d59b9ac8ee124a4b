//! What a node built without an optional service does (the crate features `sdo-block`,
//! `time` and `guarding`): it answers as a CiA 301 device without that service, and never panics. Run by
//! `cargo test -p duocan-core --no-default-features --features std --lib left_out` (CI's feature
//! matrix); a default build compiles none of these.

/// A started slave on the standard dictionary, its boot-up and events drained.
#[cfg(any(
    not(feature = "sdo-block"),
    not(feature = "time"),
    not(feature = "guarding")
))]
fn slave() -> crate::Node<crate::od::DynamicDictionary> {
    use crate::od::comm;
    use crate::{Instant, Machine, Node, NodeConfig, NodeId};
    let mut node = Node::new(
        NodeConfig::slave(NodeId::must(5)),
        comm::standard_dictionary(5, comm::Identity::default()),
    );
    node.boot(Instant::ZERO);
    while node.poll_transmit().is_some() {}
    while node.poll_event().is_some() {}
    node
}

#[cfg(not(feature = "sdo-block"))]
#[test]
fn left_out_sdo_block_requests_are_aborted_as_an_unknown_command() {
    use crate::sdo::SdoServerConfig;
    use crate::{Frame, Id, Instant, Machine};
    assert!(!SdoServerConfig::default().block);
    let mut node = slave();
    let mut ask = |d: [u8; 8]| {
        node.handle_frame(
            Instant::from_millis(10),
            &Frame::from_array(Id::Standard(0x605), d),
        );
        // (A heartbeat the write of 0x1017 starts may go out beside the answer.)
        let answers: Vec<Frame> = core::iter::from_fn(|| node.poll_transmit())
            .filter(|f| f.id() == Id::Standard(0x585))
            .collect();
        assert_eq!(answers.len(), 1, "{answers:?}");
        <[u8; 8]>::try_from(answers[0].data()).unwrap()
    };
    // 0x05040001: client/server command specifier not valid or unknown, naming the entry.
    let abort = [0x80, 0x17, 0x10, 0x00, 0x01, 0x00, 0x04, 0x05];
    // Block download initiate (with CRC and size) and block upload initiate of 0x1017.
    assert_eq!(ask([0xC6, 0x17, 0x10, 0x00, 2, 0, 0, 0]), abort);
    assert_eq!(ask([0xA4, 0x17, 0x10, 0x00, 127, 0, 0, 0]), abort);
    // What would follow in a block transfer is no transfer at all: refused the same way.
    let end = ask([0xC9, 0, 0, 0, 0, 0, 0, 0]);
    assert_eq!(end[0], 0x80);
    assert_eq!(&end[4..], &[0x01, 0x00, 0x04, 0x05]);
    // Expedited and segmented transfer work as ever: write and read back 0x1017.
    assert_eq!(ask([0x2B, 0x17, 0x10, 0x00, 100, 0, 0, 0])[0], 0x60);
    assert_eq!(
        ask([0x40, 0x17, 0x10, 0x00, 0, 0, 0, 0]),
        [0x4B, 0x17, 0x10, 0x00, 100, 0, 0, 0]
    );
    assert!(node.sdo_server().is_idle());
}

#[cfg(not(feature = "time"))]
#[test]
fn left_out_time_is_neither_produced_nor_consumed() {
    use crate::nmt::{command_frame, NmtCommand, NmtTarget};
    use crate::node::NodeEventKind;
    use crate::od::{comm, ObjectDictionary};
    use crate::time_stamp::TimeOfDay;
    use crate::{Duration, Frame, Id, Instant, Machine, NodeId};
    let mut node = slave();
    let t0 = Instant::from_millis(1);
    // Producer on 0x100, a clock and a period: a build with TIME would send every 10 ms.
    node.set(t0, comm::TIME_COB_ID, 0, 0x4000_0100u32).unwrap();
    let tod = TimeOfDay { days: 1, ms: 5 };
    node.set_time(t0, tod);
    node.set_time_period(t0, Duration::from_millis(10));
    let start = command_frame(
        Id::Standard(0),
        NmtCommand::Start,
        NmtTarget::Node(NodeId::must(5)),
    );
    node.handle_frame(t0, &start);
    while node.poll_transmit().is_some() {}
    assert!(!node.send_time(t0));
    assert_eq!(node.poll_timeout(), None, "no TIME deadline");
    node.handle_timeout(Instant::from_millis(100));
    assert_eq!(node.poll_transmit(), None);
    // Consumer on 0x100: a TIME frame is not taken (no event, the local clock unchanged).
    node.set(t0, comm::TIME_COB_ID, 0, 0x8000_0100u32).unwrap();
    while node.poll_event().is_some() {}
    let other = TimeOfDay { days: 9, ms: 0 };
    node.handle_frame(
        Instant::from_millis(200),
        &Frame::new(Id::Standard(0x100), &other.to_bytes()).unwrap(),
    );
    assert!(core::iter::from_fn(|| node.poll_event())
        .all(|e| !matches!(e.kind, NodeEventKind::Time { .. })));
    // The entry stays a plain entry: what was written reads back.
    assert_eq!(node.od().get_u32(comm::TIME_COB_ID, 0), Some(0x8000_0100));
    assert_eq!(
        node.time_of_day(Instant::from_millis(1)),
        Some(tod),
        "the local clock is the one set"
    );
}

#[cfg(not(feature = "guarding"))]
#[test]
fn left_out_guarding_requests_go_unanswered_and_life_guarding_never_runs() {
    use crate::node::NodeEventKind;
    use crate::od::{comm, ObjectDictionary};
    use crate::{Frame, Id, Instant, Machine};
    let mut node = slave();
    let t0 = Instant::from_millis(1);
    // Guard time 100 ms × 3: a build with guarding would lose its life at 300 ms unpolled.
    node.set(t0, comm::GUARD_TIME, 0, 100u16).unwrap();
    node.set(t0, comm::LIFE_TIME_FACTOR, 0, 3u8).unwrap();
    let before = node.stats().unhandled;
    for k in 1..=3 {
        let at = Instant::from_millis(100 * k);
        node.handle_frame(at, &Frame::remote(Id::Standard(0x705), 1).unwrap());
        assert_eq!(node.poll_transmit(), None, "no guarding answer");
    }
    assert_eq!(node.stats().unhandled, before + 3);
    // No life guarding deadline; time passing loses nothing.
    assert_eq!(node.poll_timeout(), None);
    node.handle_timeout(Instant::from_millis(5_000));
    assert!(core::iter::from_fn(|| node.poll_event()).all(|e| !matches!(
        e.kind,
        NodeEventKind::LifeGuardingLost | NodeEventKind::LifeGuardingResumed
    )));
    assert_eq!(node.poll_transmit(), None, "no EMCY");
    // The entries stay plain entries: what was written reads back.
    assert_eq!(node.od().get_u32(comm::GUARD_TIME, 0), Some(100));
    assert_eq!(node.od().get_u32(comm::LIFE_TIME_FACTOR, 0), Some(3));
}
