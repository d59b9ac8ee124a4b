//! The CiA 301 services of a node, frame by frame and with exact timing, on a zero-latency wire.

use crate::common::{node, Wire};
use duocan::emcy::register;
use duocan::node::{NodeEventKind as K, StateCause};
use duocan::od::ObjectAccess;
use duocan::od::{comm, ObjectDictionary};
use duocan::time_stamp::TimeOfDay;
use duocan::{
    AbortCode, Duration, Frame, Id, Instant, Machine, NmtCommand, NmtState, NmtTarget, NodeId,
};

const MASTER: usize = 0;
const SLAVE: usize = 1;
const S: NodeId = NodeId::must(5);

fn ms(v: u64) -> Instant {
    Instant::from_millis(v)
}

fn wire() -> Wire {
    Wire::new(vec![node(1, true), node(5, false)])
}

#[test]
fn boot_up_is_0x700_plus_id_with_state_zero_then_pre_operational() {
    let mut w = wire();
    w.boot_all();
    let boot = w.sent(SLAVE, 0x705);
    assert_eq!(boot.len(), 1);
    assert_eq!(boot[0].1.data(), &[0x00]);
    assert_eq!(w.nodes[SLAVE].nmt_state(), NmtState::PreOperational);
    assert_eq!(
        w.nodes[MASTER].nmt_state(),
        NmtState::Operational,
        "a master starts itself"
    );
    assert!(w.events[MASTER]
        .iter()
        .any(|e| e.kind == K::BootUp { node: S }));
    assert_eq!(
        w.nodes[MASTER].remote(S).map(|v| v.state),
        Some(NmtState::Initialising)
    );
}

#[test]
fn heartbeat_frames_and_producer_restart_on_0x1017_write() {
    let mut w = wire();
    w.boot_all();
    // A new producer time is announced at once and its grid starts there.
    w.nodes[SLAVE]
        .set(w.now, comm::HEARTBEAT_PRODUCER, 0, 100u16)
        .unwrap();
    w.run_until(ms(250));
    let hb: Vec<_> = w.sent(SLAVE, 0x705).into_iter().skip(1).collect();
    assert_eq!(
        hb.iter().map(|(t, _)| *t).collect::<Vec<_>>(),
        [ms(0), ms(100), ms(200)]
    );
    assert!(hb.iter().all(|(_, f)| f.data() == [0x7F]));
    // The same time written again leaves the grid alone.
    w.nodes[SLAVE]
        .set(ms(250), comm::HEARTBEAT_PRODUCER, 0, 100u16)
        .unwrap();
    w.run_until(ms(250));
    assert_eq!(w.sent(SLAVE, 0x705).len(), 4);
    // Writing 30 ms at 250 ms sends at once and restarts the grid from the write; the NMT
    // start in the same instant is announced at once too, and the grid starts over from it.
    w.nodes[SLAVE]
        .set(ms(250), comm::HEARTBEAT_PRODUCER, 0, 30u16)
        .unwrap();
    w.nodes[MASTER]
        .nmt_command(ms(250), NmtCommand::Start, NmtTarget::Node(S))
        .unwrap();
    w.flush();
    w.run_until(ms(311));
    let hb: Vec<_> = w.sent(SLAVE, 0x705).into_iter().skip(4).collect();
    let f = |state| Frame::from_array(Id::Standard(0x705), [state]);
    assert_eq!(
        hb,
        [
            (ms(250), f(0x7F)),
            (ms(250), f(0x05)),
            (ms(280), f(0x05)),
            (ms(310), f(0x05))
        ]
    );
}

#[test]
fn nmt_commands_byte_for_byte_and_obeyed() {
    let mut w = wire();
    w.boot_all();
    let m = &mut w.nodes[MASTER];
    m.nmt_command(ms(0), NmtCommand::Start, NmtTarget::Node(S))
        .unwrap();
    m.nmt_command(ms(0), NmtCommand::Stop, NmtTarget::All)
        .unwrap();
    m.nmt_command(ms(0), NmtCommand::EnterPreOperational, NmtTarget::Node(S))
        .unwrap();
    m.nmt_command(
        ms(0),
        NmtCommand::ResetCommunication,
        NmtTarget::Node(NodeId::must(9)),
    )
    .unwrap();
    m.nmt_command(ms(0), NmtCommand::ResetNode, NmtTarget::Node(S))
        .unwrap();
    w.flush();
    let nmt: Vec<_> = w
        .sent(MASTER, 0x000)
        .into_iter()
        .map(|(_, f)| f.data().to_vec())
        .collect();
    assert_eq!(
        nmt,
        [
            vec![0x01, 5],
            vec![0x02, 0],
            vec![0x80, 5],
            vec![0x82, 9],
            vec![0x81, 5]
        ]
    );
    let changes: Vec<_> = w.events[SLAVE]
        .iter()
        .filter_map(|e| match e.kind {
            K::StateChanged { to, cause, .. } => Some((to, cause)),
            _ => None,
        })
        .collect();
    assert_eq!(
        changes,
        [
            (NmtState::PreOperational, StateCause::Boot),
            (
                NmtState::Operational,
                StateCause::Command(NmtCommand::Start)
            ),
            (NmtState::Stopped, StateCause::Command(NmtCommand::Stop)),
            (
                NmtState::PreOperational,
                StateCause::Command(NmtCommand::EnterPreOperational)
            ),
            (NmtState::Initialising, StateCause::Boot),
            (NmtState::PreOperational, StateCause::Boot),
        ]
    );
    assert_eq!(
        w.sent(SLAVE, 0x705).len(),
        2,
        "reset node sends a second boot-up"
    );
    assert_eq!(
        w.nodes[MASTER].nmt_state(),
        NmtState::Operational,
        "masters ignore NMT"
    );
}

#[test]
fn reset_communication_restores_communication_defaults_only() {
    let mut w = wire();
    w.boot_all();
    w.nodes[SLAVE]
        .set(ms(0), comm::HEARTBEAT_PRODUCER, 0, 77u16)
        .unwrap();
    w.nodes[MASTER]
        .nmt_command(ms(1), NmtCommand::ResetCommunication, NmtTarget::All)
        .unwrap();
    w.flush();
    assert_eq!(
        w.nodes[SLAVE]
            .od()
            .get_value::<u16>(comm::HEARTBEAT_PRODUCER, 0),
        Ok(0)
    );
    assert_eq!(w.nodes[SLAVE].nmt_state(), NmtState::PreOperational);
}

#[test]
fn heartbeat_consumer_fires_exactly_at_last_heartbeat_plus_consumer_time() {
    let mut w = wire();
    w.boot_all();
    w.nodes[SLAVE]
        .set(ms(0), comm::HEARTBEAT_PRODUCER, 0, 50u16)
        .unwrap();
    w.nodes[MASTER]
        .set(ms(0), comm::HEARTBEAT_CONSUMER, 1, (5u32 << 16) | 120)
        .unwrap();
    w.run_until(ms(1000));
    // Kill the slave right after its heartbeat at 1000 ms.
    w.alive[SLAVE] = false;
    w.run_until(ms(2000));
    let timeouts: Vec<_> = w.events[MASTER]
        .iter()
        .filter(|e| matches!(e.kind, K::HeartbeatTimeout { .. }))
        .collect();
    assert_eq!(timeouts.len(), 1);
    assert_eq!(
        timeouts[0].at,
        ms(1120),
        "last heartbeat 1000 ms + 120 ms, not a scan later"
    );
    assert_eq!(
        timeouts[0].kind,
        K::HeartbeatTimeout {
            node: S,
            last: ms(1000)
        }
    );
    assert!(w.nodes[MASTER].heartbeat_lost(S));
    w.alive[SLAVE] = true;
    w.run_until(ms(2050));
    // The revived producer's first beat is due at once (its grid point passed while it was away).
    assert!(w.events[MASTER]
        .iter()
        .any(|e| e.kind == K::HeartbeatResumed { node: S } && e.at == ms(2000)));
}

#[test]
fn duplicate_consumer_entry_gives_0x06040043() {
    let mut w = wire();
    w.boot_all();
    let m = w.nodes[MASTER].core_mut();
    m.write(
        ms(0),
        comm::HEARTBEAT_CONSUMER,
        1,
        &((5u32 << 16) | 100).to_le_bytes(),
    )
    .unwrap();
    assert_eq!(
        m.write(
            ms(0),
            comm::HEARTBEAT_CONSUMER,
            2,
            &((5u32 << 16) | 200).to_le_bytes()
        ),
        Err(AbortCode::PARAMETER_INCOMPATIBLE)
    );
    assert_eq!(
        w.nodes[MASTER]
            .od()
            .get_value::<u32>(comm::HEARTBEAT_CONSUMER, 2),
        Ok(0),
        "refused write left no trace"
    );
}

#[test]
fn node_guarding_rtr_answers_toggle_and_timeout() {
    let mut w = wire();
    w.boot_all();
    assert!(w.nodes[MASTER].guard_node(ms(0), S, Duration::from_millis(100), 3));
    w.run_until(ms(250));
    let rtr = w.sent(MASTER, 0x705);
    assert_eq!(rtr.len(), 3);
    assert!(rtr.iter().all(|(_, f)| f.is_remote() && f.dlc() == 1));
    assert_eq!(
        rtr.iter().map(|(t, _)| *t).collect::<Vec<_>>(),
        [ms(0), ms(100), ms(200)]
    );
    let answers: Vec<u8> = w
        .sent(SLAVE, 0x705)
        .iter()
        .skip(1)
        .map(|(_, f)| f.data()[0])
        .collect();
    assert_eq!(
        answers,
        [0x7F, 0xFF, 0x7F],
        "toggle starts at 0 and alternates"
    );
    // A node answering with a stale toggle is detected.
    w.deliver(Frame::from_array(Id::Standard(0x705), [0x7F]));
    assert!(
        !w.events[MASTER]
            .iter()
            .any(|e| matches!(e.kind, K::GuardToggleError { .. })),
        "no request outstanding: ignored"
    );
    w.alive[SLAVE] = false;
    w.run_until(ms(300));
    w.deliver(Frame::from_array(Id::Standard(0x705), [0x7F])); // expected toggle 1
    assert!(w.events[MASTER]
        .iter()
        .any(|e| e.kind == K::GuardToggleError { node: S }));
    // Last valid answer at 200 ms; life time 300 ms → timeout at 500 ms.
    w.run_until(ms(600));
    let t: Vec<_> = w.events[MASTER]
        .iter()
        .filter(|e| e.kind == K::GuardingTimeout { node: S })
        .map(|e| e.at)
        .collect();
    assert_eq!(t, [ms(500)]);
}

#[test]
fn life_guarding_detects_a_silent_master_and_raises_emcy_0x8130() {
    let mut w = wire();
    w.boot_all();
    w.nodes[SLAVE]
        .set(ms(0), comm::GUARD_TIME, 0, 100u16)
        .unwrap();
    w.nodes[SLAVE]
        .set(ms(0), comm::LIFE_TIME_FACTOR, 0, 3u8)
        .unwrap();
    w.nodes[MASTER].guard_node(ms(0), S, Duration::from_millis(100), 3);
    w.run_until(ms(250));
    w.nodes[MASTER].unguard_node(S);
    w.run_until(ms(1000));
    let lost: Vec<_> = w.events[SLAVE]
        .iter()
        .filter(|e| e.kind == K::LifeGuardingLost)
        .map(|e| e.at)
        .collect();
    assert_eq!(lost, [ms(500)], "last request at 200 ms + 100 ms × 3");
    let emcy = w.sent(SLAVE, 0x85);
    assert_eq!(emcy.len(), 1);
    assert_eq!(
        emcy[0].1.data(),
        &[
            0x30,
            0x81,
            register::GENERIC | register::COMMUNICATION,
            0,
            0,
            0,
            0,
            0
        ]
    );
}

#[test]
fn sync_producer_with_and_without_counter() {
    let mut w = wire();
    w.boot_all();
    let m = &mut w.nodes[MASTER];
    m.set(ms(0), comm::SYNC_COB_ID, 0, 0x4000_0080u32).unwrap();
    m.set(ms(0), comm::SYNC_PERIOD, 0, 1_000u32).unwrap();
    assert_eq!(
        m.set(ms(0), comm::SYNC_OVERFLOW, 0, 3u8),
        Err(AbortCode::DEVICE_STATE),
        "only while period is 0"
    );
    w.run_until(ms(3));
    let s = w.sent(MASTER, 0x80);
    assert_eq!(
        s.iter().map(|(t, f)| (*t, f.dlc())).collect::<Vec<_>>(),
        [(ms(1), 0), (ms(2), 0), (ms(3), 0)]
    );
    let m = &mut w.nodes[MASTER];
    m.set(ms(3), comm::SYNC_PERIOD, 0, 0u32).unwrap();
    assert_eq!(
        m.set(ms(3), comm::SYNC_OVERFLOW, 0, 1u8),
        Err(AbortCode::VALUE_RANGE),
        "1 is reserved"
    );
    m.set(ms(3), comm::SYNC_OVERFLOW, 0, 3u8).unwrap();
    m.set(ms(3), comm::SYNC_PERIOD, 0, 1_000u32).unwrap();
    w.nodes[SLAVE]
        .set(ms(3), comm::SYNC_OVERFLOW, 0, 3u8)
        .unwrap();
    w.run_until(ms(8));
    let counters: Vec<_> = w
        .sent(MASTER, 0x80)
        .iter()
        .skip(3)
        .map(|(_, f)| f.data().to_vec())
        .collect();
    assert_eq!(counters, [vec![1], vec![2], vec![3], vec![1], vec![2]]);
    let seen: Vec<_> = w.events[SLAVE]
        .iter()
        .filter_map(|e| match e.kind {
            K::Sync {
                counter,
                produced: false,
            } => Some(counter),
            _ => None,
        })
        .collect();
    assert_eq!(seen.len(), 8);
    assert_eq!(&seen[3..], [Some(1), Some(2), Some(3), Some(1), Some(2)]);
    // Changing the producing COB-ID under way is refused.
    assert_eq!(
        w.nodes[MASTER].set(ms(8), comm::SYNC_COB_ID, 0, 0x4000_0081u32),
        Err(AbortCode::VALUE_RANGE)
    );
}

#[test]
fn time_producer_and_consumer() {
    let mut w = wire();
    w.boot_all();
    let tod = TimeOfDay {
        days: 14_000,
        ms: 3_600_000,
    };
    w.nodes[MASTER]
        .set(ms(0), comm::TIME_COB_ID, 0, 0x4000_0100u32)
        .unwrap();
    w.nodes[MASTER].set_time(ms(0), tod);
    w.nodes[SLAVE]
        .set(ms(0), comm::TIME_COB_ID, 0, 0x8000_0100u32)
        .unwrap();
    w.now = ms(500);
    assert!(w.nodes[MASTER].send_time(ms(500)));
    w.flush();
    let t = w.sent(MASTER, 0x100);
    assert_eq!(
        t[0].1.data(),
        &[0x74, 0xF0, 0x36, 0x00, 0xB0, 0x36],
        "3,600,500 ms; day 14,000"
    );
    assert_eq!(
        w.nodes[SLAVE].time_of_day(ms(1500)),
        Some(TimeOfDay {
            days: 14_000,
            ms: 3_601_500
        })
    );
}

#[test]
fn emcy_frame_register_history_and_reset() {
    let mut w = wire();
    w.boot_all();
    w.nodes[SLAVE].emcy_raise(ms(1), 0x5000, register::TEMPERATURE, [1, 2, 3, 4, 5]);
    w.nodes[SLAVE].emcy_raise(ms(1), 0x3100, register::VOLTAGE, [0; 5]);
    w.flush();
    let e = w.sent(SLAVE, 0x85);
    assert_eq!(e[0].1.data(), &[0x00, 0x50, 0x09, 1, 2, 3, 4, 5]);
    assert_eq!(e[1].1.data()[..3], [0x00, 0x31, 0x0D]);
    let od = w.nodes[SLAVE].od();
    assert_eq!(od.get_value::<u8>(comm::ERROR_REGISTER, 0), Ok(0x0D));
    assert_eq!(od.get_value::<u8>(comm::ERROR_HISTORY, 0), Ok(2));
    assert_eq!(
        od.get_value::<u32>(comm::ERROR_HISTORY, 1),
        Ok(0x3100),
        "newest first"
    );
    assert_eq!(od.get_value::<u32>(comm::ERROR_HISTORY, 2), Ok(0x5000));
    let got: Vec<_> = w.events[MASTER]
        .iter()
        .filter_map(|e| match e.kind {
            K::Emcy { node, msg } => Some((node, msg.code)),
            _ => None,
        })
        .collect();
    assert_eq!(got, [(S, 0x5000), (S, 0x3100)]);
    w.nodes[SLAVE].emcy_clear(ms(2), 0x5000);
    w.nodes[SLAVE].emcy_clear(ms(2), 0x3100);
    w.flush();
    assert_eq!(
        w.sent(SLAVE, 0x85).last().unwrap().1.data(),
        &[0; 8],
        "error reset"
    );
    let core = w.nodes[SLAVE].core_mut();
    assert_eq!(
        core.write(ms(3), comm::ERROR_HISTORY, 0, &[1]),
        Err(AbortCode::VALUE_RANGE)
    );
    core.write(ms(3), comm::ERROR_HISTORY, 0, &[0]).unwrap();
    assert_eq!(
        w.nodes[SLAVE].od().get_value::<u32>(comm::ERROR_HISTORY, 1),
        Ok(0)
    );
}

#[test]
fn emcy_inhibit_time_is_honoured() {
    let mut w = wire();
    w.boot_all();
    w.nodes[SLAVE]
        .set(ms(0), comm::EMCY_INHIBIT, 0, 50u16)
        .unwrap(); // 5 ms
    for c in [0x1000u16, 0x2000, 0x3000] {
        w.nodes[SLAVE].emcy_raise(ms(0), c, 0, [0; 5]);
    }
    w.run_until(ms(20));
    let times: Vec<_> = w.sent(SLAVE, 0x85).iter().map(|(t, _)| *t).collect();
    assert_eq!(times, [ms(0), ms(5), ms(10)]);
}

#[test]
fn sdo_side_writes_give_the_cia_abort_codes() {
    let mut w = wire();
    w.boot_all();
    let c = w.nodes[SLAVE].core_mut();
    assert_eq!(
        c.write(ms(0), comm::ERROR_REGISTER, 0, &[1]),
        Err(AbortCode::READ_ONLY)
    );
    assert_eq!(
        c.write(ms(0), comm::IDENTITY, 1, &[1, 0, 0, 0]),
        Err(AbortCode::READ_ONLY)
    );
    assert_eq!(
        c.write(ms(0), comm::HEARTBEAT_PRODUCER, 0, &[1]),
        Err(AbortCode::LENGTH_TOO_LOW)
    );
    assert_eq!(
        c.write(ms(0), comm::HEARTBEAT_PRODUCER, 0, &[1, 2, 3]),
        Err(AbortCode::LENGTH_TOO_HIGH)
    );
    assert_eq!(c.write(ms(0), 0x6000, 0, &[1]), Err(AbortCode::NO_OBJECT));
    assert_eq!(
        c.write(ms(0), comm::HEARTBEAT_PRODUCER, 1, &[1, 0]),
        Err(AbortCode::NO_SUB_INDEX)
    );
    assert_eq!(c.read(comm::IDENTITY, 1), Ok(&0x1234u32.to_le_bytes()[..]));
    assert_eq!(
        c.write(ms(0), comm::EMCY_COB_ID, 0, &0x86u32.to_le_bytes()),
        Err(AbortCode::VALUE_RANGE),
        "valid COB-ID must be invalidated first"
    );
    c.write(ms(0), comm::EMCY_COB_ID, 0, &0x8000_0085u32.to_le_bytes())
        .unwrap();
    c.write(ms(0), comm::EMCY_COB_ID, 0, &0x86u32.to_le_bytes())
        .unwrap();
    w.nodes[SLAVE].emcy_raise(ms(1), 0x1000, 0, [0; 5]);
    w.flush();
    assert_eq!(w.sent(SLAVE, 0x86).len(), 1, "EMCY follows the new COB-ID");
}

#[test]
fn malformed_frames_are_reported_and_change_nothing() {
    let mut w = wire();
    w.boot_all();
    let before = w.nodes[SLAVE].nmt_state();
    let bad = [
        Frame::new(Id::Standard(0), &[1]).unwrap(), // NMT, wrong DLC
        Frame::new(Id::Standard(0), &[1, 5, 0]).unwrap(), // NMT, too long
        Frame::remote(Id::Standard(0), 2).unwrap(), // NMT as RTR
        Frame::new(Id::Standard(0), &[0x07, 5]).unwrap(), // NMT, unknown command
        Frame::new(Id::Standard(0x709), &[0x05, 1]).unwrap(), // heartbeat, wrong DLC
        Frame::new(Id::Standard(0x709), &[0x33]).unwrap(), // heartbeat, unknown state
        Frame::new(Id::Standard(0x89), &[0x00, 0x10]).unwrap(), // EMCY too short
        Frame::remote(Id::Standard(0x89), 8).unwrap(), // EMCY as RTR
        Frame::new(Id::Standard(0x705), &[0x7F]).unwrap(), // data on our own guarding id
    ];
    for f in bad {
        w.deliver(f);
    }
    let malformed = w.events[SLAVE]
        .iter()
        .filter(|e| matches!(e.kind, K::Malformed { .. }))
        .count();
    assert_eq!(malformed, 8);
    assert_eq!(w.nodes[SLAVE].stats().malformed, 8);
    assert_eq!(w.nodes[SLAVE].nmt_state(), before);
    // A heartbeat from an unknown, unconfigured node is information, not an error.
    w.deliver(Frame::new(Id::Standard(0x70A), &[0x05]).unwrap());
    assert_eq!(
        w.nodes[MASTER].remote(NodeId::must(10)).map(|v| v.state),
        Some(NmtState::Operational)
    );
}

#[test]
fn sdo_is_refused_in_stopped_services_follow_state() {
    let mut w = wire();
    w.boot_all();
    w.nodes[MASTER]
        .nmt_command(ms(0), NmtCommand::Stop, NmtTarget::Node(S))
        .unwrap();
    w.flush();
    assert_eq!(w.nodes[SLAVE].core().nmt_state(), NmtState::Stopped);
    // EMCY is not sent in stopped; it waits.
    w.nodes[SLAVE].emcy_raise(ms(1), 0x1000, 0, [0; 5]);
    w.flush();
    assert!(w.sent(SLAVE, 0x85).is_empty());
    w.nodes[MASTER]
        .nmt_command(ms(2), NmtCommand::EnterPreOperational, NmtTarget::Node(S))
        .unwrap();
    w.flush();
    w.run_until(ms(3));
    assert_eq!(w.sent(SLAVE, 0x85).len(), 1);
}

#[test]
fn no_deadline_in_the_past_is_left_behind() {
    // A stopped producer must not leave a due SYNC that makes the driver spin.
    let mut w = wire();
    w.boot_all();
    w.nodes[SLAVE]
        .set(ms(0), comm::SYNC_COB_ID, 0, 0x4000_0080u32)
        .unwrap();
    w.nodes[SLAVE]
        .set(ms(0), comm::SYNC_PERIOD, 0, 1_000u32)
        .unwrap();
    w.nodes[MASTER]
        .nmt_command(ms(0), NmtCommand::Stop, NmtTarget::Node(S))
        .unwrap();
    w.flush();
    w.run_until(ms(10));
    let next = w.nodes[SLAVE].poll_timeout().unwrap();
    assert!(next > ms(10));
    assert!(w.sent(SLAVE, 0x80).is_empty(), "no SYNC while stopped");
}

#[test]
fn many_timeouts_at_one_instant_are_all_reported() {
    let mut nodes = vec![node(1, true)];
    nodes.extend((2..=25).map(|id| node(id, false)));
    let mut w = Wire::new(nodes);
    w.boot_all();
    for i in 1..w.nodes.len() {
        let id = w.nodes[i].id().raw() as u32;
        w.nodes[i]
            .set(ms(0), comm::HEARTBEAT_PRODUCER, 0, 100u16)
            .unwrap();
        w.nodes[MASTER]
            .set(ms(0), comm::HEARTBEAT_CONSUMER, i as u8, (id << 16) | 150)
            .unwrap();
    }
    w.run_until(ms(100));
    for a in w.alive.iter_mut().skip(1) {
        *a = false;
    }
    w.run_until(ms(400));
    let t: Vec<_> = w.events[MASTER]
        .iter()
        .filter(|e| matches!(e.kind, K::HeartbeatTimeout { .. }))
        .map(|e| e.at)
        .collect();
    assert_eq!(
        t,
        vec![ms(250); 24],
        "every silent node, all at last heartbeat + 150 ms"
    );
}
