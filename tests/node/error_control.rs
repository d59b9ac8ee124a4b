//! What the bus sees of a node's error control: EMCY 0x8130 when a consumed heartbeat is lost
//! (with 0x1001 and 0x1003), its reset when the producer is back, and the heartbeat at once on
//! every state change. Exact instants on the zero-latency wire.

use crate::common::{node, Wire};
use duocan::emcy::register;
use duocan::node::NodeEventKind as K;
use duocan::od::{comm, ObjectDictionary};
use duocan::{Duration, Frame, Id, Instant, NmtCommand, NmtState, NmtTarget, NodeId};

const MASTER: usize = 0;
const SLAVE: usize = 1;
const S: NodeId = NodeId::must(5);

fn ms(v: u64) -> Instant {
    Instant::from_millis(v)
}

/// The master beats every 50 ms; the slave consumes it with 120 ms.
fn monitored() -> Wire {
    let mut w = Wire::new(vec![node(1, true), node(5, false)]);
    w.nodes[MASTER]
        .set(ms(0), comm::HEARTBEAT_PRODUCER, 0, 50u16)
        .unwrap();
    w.nodes[SLAVE]
        .set(ms(0), comm::HEARTBEAT_CONSUMER, 1, (1u32 << 16) | 120)
        .unwrap();
    w.boot_all();
    w
}

fn emcy(w: &Wire) -> Vec<(Instant, Vec<u8>)> {
    w.sent(SLAVE, 0x85)
        .into_iter()
        .map(|(t, f)| (t, f.data().to_vec()))
        .collect()
}

fn error_register(w: &Wire) -> u8 {
    w.nodes[SLAVE]
        .od()
        .get_value(comm::ERROR_REGISTER, 0)
        .unwrap()
}

#[test]
fn a_lost_heartbeat_is_emcy_0x8130_recorded_in_0x1003_and_reset_when_heard_again() {
    let mut w = monitored();
    w.run_until(ms(1000));
    // The master dies right after its heartbeat at 1000 ms.
    w.alive[MASTER] = false;
    w.run_until(ms(2000));
    let timeout = w.events[SLAVE]
        .iter()
        .find(|e| matches!(e.kind, K::HeartbeatTimeout { .. }))
        .unwrap();
    assert_eq!(timeout.at, ms(1120));
    // One EMCY at the timeout: 0x8130, generic + communication bits, the silent node's ID.
    assert_eq!(
        emcy(&w),
        [(ms(1120), vec![0x30, 0x81, 0x11, 0x01, 0, 0, 0, 0])]
    );
    assert_eq!(
        error_register(&w),
        register::GENERIC | register::COMMUNICATION
    );
    let od = w.nodes[SLAVE].od();
    assert_eq!(od.get_value::<u8>(comm::ERROR_HISTORY, 0), Ok(1));
    assert_eq!(od.get_value::<u32>(comm::ERROR_HISTORY, 1), Ok(0x8130));
    // Back: its next heartbeat (its grid continues at 2000 ms) ends the error.
    w.alive[MASTER] = true;
    w.run_until(ms(2100));
    assert_eq!(
        emcy(&w)[1..],
        [(ms(2000), vec![0; 8])],
        "the error reset, at the heartbeat that ends the loss"
    );
    assert_eq!(error_register(&w), 0);
    assert_eq!(
        w.nodes[SLAVE].od().get_value::<u8>(comm::ERROR_HISTORY, 0),
        Ok(1),
        "the history keeps it"
    );
}

#[test]
fn life_guarding_and_a_lost_heartbeat_are_one_0x8130_until_both_are_back() {
    let mut w = monitored();
    // Life guarding too: guard time 100 ms × 3; the master polls every 100 ms.
    w.nodes[SLAVE]
        .set(ms(0), comm::GUARD_TIME, 0, 100u16)
        .unwrap();
    w.nodes[SLAVE]
        .set(ms(0), comm::LIFE_TIME_FACTOR, 0, 3u8)
        .unwrap();
    assert!(w.nodes[MASTER].guard_node(ms(0), S, Duration::from_millis(100), 3));
    w.run_until(ms(1000));
    w.alive[MASTER] = false;
    w.run_until(ms(2000));
    // The heartbeat is missed first (1120 ms), life guarding later (last request 1000 ms +
    // 300 ms): one error, one EMCY.
    let lost: Vec<_> = w.events[SLAVE]
        .iter()
        .filter(|e| matches!(e.kind, K::HeartbeatTimeout { .. } | K::LifeGuardingLost))
        .map(|e| e.at)
        .collect();
    assert_eq!(lost, [ms(1120), ms(1300)]);
    assert_eq!(emcy(&w).len(), 1);
    // Heartbeat back at 2000 ms: life guarding still lost, the error stands.
    w.alive[MASTER] = true;
    w.run_until(ms(2000));
    let resumed = w.events[SLAVE]
        .iter()
        .find(|e| matches!(e.kind, K::HeartbeatResumed { .. }))
        .map(|e| e.at);
    assert_eq!(resumed, Some(ms(2000)));
    let life_back = w.events[SLAVE]
        .iter()
        .find(|e| e.kind == K::LifeGuardingResumed)
        .map(|e| e.at);
    // The guarding request due since 1100 ms goes out with the master's first timeout.
    assert_eq!(life_back, Some(ms(2000)));
    w.run_until(ms(2100));
    // The reset comes once both are back, and only once.
    assert_eq!(emcy(&w)[1..], [(ms(2000), vec![0; 8])]);
    assert_eq!(error_register(&w), 0);
}

#[test]
fn reset_communication_ends_a_standing_heartbeat_error() {
    let mut w = monitored();
    w.run_until(ms(1000));
    w.alive[MASTER] = false;
    w.run_until(ms(1500));
    assert_eq!(emcy(&w).len(), 1);
    // Another master resets the slave's communication: monitoring starts over.
    w.now = ms(1500);
    w.deliver(Frame::from_array(Id::Standard(0), [0x82, 5]));
    let after: Vec<_> = w
        .log
        .iter()
        .filter(|(t, s, _)| *t == ms(1500) && *s == SLAVE)
        .map(|(_, _, f)| (f.id(), f.data().to_vec()))
        .collect();
    assert_eq!(
        after,
        [
            (Id::Standard(0x705), vec![0x00]),
            (Id::Standard(0x85), vec![0; 8])
        ],
        "boot-up, then the error reset"
    );
    assert_eq!(error_register(&w), 0);
}

#[test]
fn a_master_keeps_its_lost_slaves_to_itself_unless_told() {
    for announce in [false, true] {
        let mut m = node(1, true);
        let od = comm::standard_dictionary(1, comm::Identity::default());
        if announce {
            let cfg = duocan::NodeConfig::master(NodeId::must(1)).with_heartbeat_loss_emcy(true);
            m = duocan::Node::new(cfg, od);
        }
        let mut w = Wire::new(vec![m, node(5, false)]);
        w.nodes[SLAVE]
            .set(ms(0), comm::HEARTBEAT_PRODUCER, 0, 50u16)
            .unwrap();
        w.nodes[MASTER]
            .set(ms(0), comm::HEARTBEAT_CONSUMER, 1, (5u32 << 16) | 120)
            .unwrap();
        w.boot_all();
        w.run_until(ms(500));
        w.alive[SLAVE] = false;
        w.run_until(ms(1000));
        assert!(w.events[MASTER]
            .iter()
            .any(|e| matches!(e.kind, K::HeartbeatTimeout { node, .. } if node == S)));
        let sent = w.sent(MASTER, 0x81);
        assert_eq!(sent.len(), announce as usize, "announce: {announce}");
    }
}

#[test]
fn the_heartbeat_goes_out_at_once_on_every_state_change() {
    let mut w = Wire::new(vec![node(1, true), node(5, false)]);
    w.nodes[SLAVE]
        .set(ms(0), comm::HEARTBEAT_PRODUCER, 0, 100u16)
        .unwrap();
    w.boot_all();
    let command = |w: &mut Wire, t: u64, cmd| {
        w.run_until(ms(t));
        w.nodes[MASTER]
            .nmt_command(ms(t), cmd, NmtTarget::Node(S))
            .unwrap();
        w.flush();
    };
    command(&mut w, 30, NmtCommand::Start);
    command(&mut w, 250, NmtCommand::Stop);
    command(&mut w, 400, NmtCommand::EnterPreOperational);
    w.run_until(ms(450));
    w.nodes[SLAVE].set_nmt_state(ms(450), NmtState::Operational);
    w.flush();
    w.run_until(ms(560));
    let hb: Vec<_> = w
        .sent(SLAVE, 0x705)
        .into_iter()
        .map(|(t, f)| (t, f.data()[0]))
        .collect();
    // The boot-up announces the boot (no heartbeat on top of it); each later change goes out
    // at once and the 100 ms grid starts over from it.
    assert_eq!(
        hb,
        [
            (ms(0), 0x00),
            (ms(30), 0x05),
            (ms(130), 0x05),
            (ms(230), 0x05),
            (ms(250), 0x04),
            (ms(350), 0x04),
            (ms(400), 0x7F),
            (ms(450), 0x05),
            (ms(550), 0x05)
        ]
    );
    // Without a producer time, a state change sends nothing.
    let mut w = Wire::new(vec![node(1, true), node(5, false)]);
    w.boot_all();
    command(&mut w, 30, NmtCommand::Start);
    w.run_until(ms(500));
    assert_eq!(w.sent(SLAVE, 0x705).len(), 1, "the boot-up only");
}
