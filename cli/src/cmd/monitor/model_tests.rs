use super::*;
use duocan::emcy::EmcyMessage;
use duocan::NodeId;

fn ms(t: u64) -> Instant {
    Instant::from_millis(t)
}

fn heartbeat(node: u8, state: u8) -> Frame {
    Frame::new(Id::Standard(0x700 + u16::from(node)), &[state]).unwrap()
}

fn master_frame(priority: u8, node: u8) -> Frame {
    Frame::new(Id::Standard(ACTIVE_MASTER_RESPONSE), &[priority, node]).unwrap()
}

fn state(node: u8, to: NmtState, at: u64) -> NetEvent {
    NetEvent::State {
        node: NodeId::must(node),
        from: None,
        to,
        at: ms(at),
    }
}

fn texts(m: &Model) -> Vec<String> {
    m.view(ms(0), "").events.into_iter().map(|e| e.1).collect()
}

/// The monitor's own observations among the lines (`monitor: …`).
fn observations(m: &Model) -> Vec<String> {
    let mut t = texts(m);
    t.retain(|l| l.starts_with("monitor: "));
    t
}

#[test]
fn heartbeat_age_is_the_time_since_the_last_heartbeat_frame() {
    let mut names = Names::new();
    names.insert(5, "duocan simulated node".into());
    let mut m = Model::new(names, vec![]);
    m.on_frame(ms(100), Some(0), true, &heartbeat(5, 0x05));
    m.on_event(&state(5, NmtState::Operational, 100));
    m.on_frame(ms(200), Some(0), true, &heartbeat(5, 0x05));
    let v = m.view(ms(280), "");
    assert_eq!(
        v.nodes,
        vec![NodeRow {
            node: 5,
            age_ms: Some(80),
            id: "0x05".into(),
            state: "operational".into(),
            hb_age: "80 ms".into(),
            emcy: "-".into(),
            name: "duocan simulated node".into(),
            heard_on: "-".into(),
        }]
    );
    assert_eq!(m.view(ms(12_480), "").nodes[0].hb_age, "12.2 s");
    // A frame sent by us, a remote frame or a two-byte frame on 0x705 is not a heartbeat.
    m.on_frame(ms(300), Some(0), false, &heartbeat(5, 0x05));
    m.on_frame(
        ms(300),
        Some(0),
        true,
        &Frame::remote(Id::Standard(0x705), 1).unwrap(),
    );
    m.on_frame(
        ms(300),
        Some(0),
        true,
        &Frame::new(Id::Standard(0x705), &[5, 0]).unwrap(),
    );
    assert_eq!(m.view(ms(300), "").nodes[0].hb_age, "100 ms");
}

#[test]
fn a_silent_heartbeat_is_observed_once_and_its_return_too() {
    let mut m = Model::new(Names::new(), vec![]);
    m.on_frame(ms(0), Some(0), true, &heartbeat(7, 0x05));
    m.on_frame(ms(100), Some(0), true, &heartbeat(7, 0x05));
    m.tick(ms(400)); // three periods: not yet
    assert!(observations(&m).is_empty());
    m.tick(ms(401));
    m.tick(ms(900));
    assert_eq!(
        observations(&m),
        ["monitor: node 0x07 heartbeat silent for 301 ms"]
    );
    assert_eq!(m.view(ms(900), "").nodes[0].hb_age, "800 ms silent");
    m.on_frame(ms(950), Some(0), true, &heartbeat(7, 0x05));
    assert_eq!(
        observations(&m)[1],
        "monitor: node 0x07 heartbeat heard again"
    );
    assert_eq!(m.view(ms(960), "").nodes[0].hb_age, "10 ms");
}

#[test]
fn a_heartbeat_sent_at_once_on_a_state_change_is_no_period() {
    // Every 500 ms; an NMT command 50 ms after a heartbeat, answered at once with the new
    // state (as CANopenNode's canopend does), then every 500 ms again from there.
    let mut m = Model::new(Names::new(), vec![]);
    for t in [0, 500, 1_000] {
        m.on_frame(ms(t), Some(0), true, &heartbeat(4, 0x7F));
    }
    m.on_frame(ms(1_050), Some(0), true, &heartbeat(4, 0x05));
    m.tick(ms(1_300));
    assert!(observations(&m).is_empty(), "{:?}", observations(&m));
    m.on_frame(ms(1_550), Some(0), true, &heartbeat(4, 0x05));
    // A device that keeps its own time instead: the next one 450 ms after the change.
    m.on_frame(ms(1_600), Some(0), true, &heartbeat(4, 0x04));
    m.on_frame(ms(2_000), Some(0), true, &heartbeat(4, 0x04));
    m.tick(ms(2_200));
    assert!(observations(&m).is_empty(), "{:?}", observations(&m));
    // Its steady period is still what counts: silent after three of them.
    m.on_frame(ms(2_500), Some(0), true, &heartbeat(4, 0x04));
    m.tick(ms(4_001));
    assert_eq!(
        observations(&m),
        ["monitor: node 0x04 heartbeat silent for 1501 ms"]
    );
}

#[test]
fn a_state_its_heartbeat_told_is_logged_once_whether_the_event_came_before_or_after() {
    let mut m = Model::new(Names::new(), vec![]);
    // Node 4: its heartbeat only (the network's event came before the monitor listened).
    m.on_frame(ms(1), Some(0), true, &heartbeat(4, 0x05));
    // Node 5: the heartbeat, then the event; node 7: the event, then the heartbeat; node 6:
    // a boot-up, the line of its own event.
    m.on_frame(ms(2), Some(0), true, &heartbeat(5, 0x04));
    m.on_event(&state(5, NmtState::Stopped, 2));
    m.on_event(&state(7, NmtState::PreOperational, 3));
    m.on_frame(ms(3), Some(0), true, &heartbeat(7, 0x7F));
    m.on_frame(ms(4), Some(0), true, &heartbeat(6, 0x00));
    assert_eq!(
        texts(&m),
        [
            "node 0x04: operational",
            "node 0x05: stopped",
            "node 0x07: pre-operational"
        ]
    );
}

#[test]
fn pair_roles_follow_the_members_states_and_a_failover_is_observed() {
    let mut m = Model::new(Names::new(), vec![(0x10, 0x50), (0x11, 0x51)]);
    m.on_event(&state(0x10, NmtState::Operational, 10));
    m.on_event(&state(0x50, NmtState::PreOperational, 10));
    let v = m.view(ms(20), "");
    assert_eq!(
        v.pairs,
        vec![
            PairRow {
                members: [0x10, 0x50],
                pair: "0x10/0x50".into(),
                active: "0x10".into(),
                standby: "0x50".into()
            },
            PairRow {
                members: [0x11, 0x51],
                pair: "0x11/0x51".into(),
                active: "not heard".into(),
                standby: "-".into()
            },
        ]
    );
    // The active member stops: the standby takes over.
    m.on_event(&state(0x10, NmtState::Stopped, 30));
    assert_eq!(m.view(ms(30), "").pairs[0].active, "none");
    m.on_event(&state(0x50, NmtState::Operational, 35));
    let v = m.view(ms(40), "");
    assert_eq!(
        (v.pairs[0].active.as_str(), v.pairs[0].standby.as_str()),
        ("0x50", "-")
    );
    m.on_event(&state(0x10, NmtState::PreOperational, 50));
    assert_eq!(m.view(ms(50), "").pairs[0].standby, "0x10");
    m.on_event(&state(0x10, NmtState::Operational, 60));
    assert_eq!(m.view(ms(60), "").pairs[0].active, "both");
    let log: Vec<_> = texts(&m)
        .into_iter()
        .filter(|t| t.starts_with("monitor:"))
        .collect();
    assert_eq!(
        log,
        [
            "monitor: pair 0x10/0x50: 0x10 active",
            "monitor: pair 0x10/0x50: no active member",
            "monitor: pair 0x10/0x50: failover: 0x50 active (was 0x10)",
            "monitor: pair 0x10/0x50: both members operational",
        ]
    );
    // Back to the one active member it had before both: not a failover.
    m.on_event(&state(0x10, NmtState::PreOperational, 70));
    assert_eq!(
        texts(&m).last().unwrap(),
        "monitor: pair 0x10/0x50: 0x50 active"
    );
}

#[test]
fn the_master_is_the_node_of_the_latest_active_master_response() {
    let mut m = Model::new(Names::new(), vec![]);
    assert_eq!(m.view(ms(0), "").master, "-");
    m.on_frame(ms(10), Some(0), true, &heartbeat(1, 0x05));
    m.on_frame(ms(20), Some(0), true, &master_frame(0, 1));
    assert_eq!(
        m.view(ms(90), "").master,
        "0x01 (priority 0), heartbeat 80 ms"
    );
    // Repeated: not a new observation. A malformed one (node 0, one byte) is ignored.
    m.on_frame(ms(30), Some(0), true, &master_frame(0, 1));
    m.on_frame(ms(31), Some(0), true, &master_frame(0, 0));
    m.on_frame(
        ms(32),
        Some(0),
        true,
        &Frame::new(Id::Standard(0x71), &[2]).unwrap(),
    );
    m.on_frame(ms(40), Some(1), true, &master_frame(1, 2));
    assert_eq!(m.view(ms(90), "").master, "0x02 (priority 1), heartbeat -");
    assert_eq!(
        observations(&m),
        [
            "monitor: active master 0x01, priority 0",
            "monitor: active master now 0x02 (was 0x01), priority 1"
        ]
    );
}

#[test]
fn emcy_ports_reach_and_the_filter() {
    let mut m = Model::new(Names::new(), vec![]);
    let port = |name: &str, state: &str| PortInfo {
        name: name.into(),
        state: state.into(),
        rx: 10,
        tx: 0,
        errors: 0,
    };
    let three = vec![port("can0", "ok"), port("can1", "ok"), port("can2", "ok")];
    m.set_ports(three);
    let emcy = EmcyMessage {
        code: 0x8130,
        register: 0x11,
        data: [0; 5],
    };
    m.on_event(&state(5, NmtState::Operational, 1));
    m.on_event(&state(6, NmtState::Operational, 1));
    m.on_event(&NetEvent::Emcy {
        node: NodeId::must(6),
        msg: emcy,
        at: ms(2),
    });
    m.on_event(&NetEvent::Reach {
        node: NodeId::must(6),
        heard: duocan::net::HeardOn::from([false, true]),
        at: ms(3),
    });
    m.on_event(&NetEvent::PortState {
        port: 0,
        from: duocan::machine::PortState::Ok,
        to: duocan::machine::PortState::Failed,
        reason: duocan::machine::PortReason::Down(duocan::machine::ErrorCause::InterfaceDown),
        at: ms(4),
    });
    let v = m.view(ms(5), "emcy");
    assert_eq!(v.nodes.len(), 1);
    assert_eq!(v.nodes[0].id, "0x06");
    assert_eq!(v.nodes[0].emcy, "0x8130 life guard or heartbeat error");
    assert_eq!(v.nodes[0].heard_on, "bus 2");
    assert_eq!(v.known, 2);
    assert_eq!(
        v.events,
        [(
            ms(2),
            "node 0x06: EMCY 0x8130 life guard or heartbeat error".into()
        )]
    );
    let v = m.view(ms(5), "0x05");
    assert_eq!(v.nodes.len(), 1);
    assert_eq!(v.events, [(ms(1), "node 0x05: operational".into())]);
    // At most two ports; a port's state changes at once with its event.
    assert_eq!(v.ports, [port("can0", "failed"), port("can1", "ok")]);
    assert_eq!(
        m.view(ms(5), "bus 1").events,
        [(ms(4), "bus 1: failed (port down: interface down)".into())]
    );
}

#[test]
fn on_two_ports_a_heartbeats_copy_is_not_a_period() {
    let mut m = Model::new(Names::new(), vec![]);
    // Boot-up, then the first heartbeat 5 ms later: not a period either.
    m.on_frame(ms(0), Some(0), true, &heartbeat(9, 0));
    m.on_frame(ms(5), Some(0), true, &heartbeat(9, 0x7F));
    m.on_frame(ms(5), Some(1), true, &heartbeat(9, 0x7F));
    for t in [205, 405] {
        m.on_frame(ms(t), Some(0), true, &heartbeat(9, 0x7F));
        m.on_frame(ms(t + 1), Some(1), true, &heartbeat(9, 0x7F));
    }
    m.tick(ms(900));
    assert!(observations(&m).is_empty(), "{:?}", observations(&m));
    assert_eq!(m.view(ms(900), "").nodes[0].hb_age, "494 ms");
    m.tick(ms(1_007));
    assert_eq!(
        observations(&m),
        ["monitor: node 0x09 heartbeat silent for 601 ms"]
    );
    // The state comes from the heartbeat itself (its toggle bit aside).
    assert_eq!(m.view(ms(0), "").nodes[0].state, "pre-operational");
    m.on_frame(ms(1_010), Some(1), true, &heartbeat(9, 0x85));
    assert_eq!(m.view(ms(0), "").nodes[0].state, "operational");
}

#[test]
fn the_log_is_a_ring_and_the_plain_output_reads_it_in_order() {
    let mut m = Model::new(Names::new(), vec![]);
    for i in 0..EVENTS_KEPT as u64 + 5 {
        m.on_event(&NetEvent::BootUp {
            node: NodeId::must(5),
            at: ms(i),
        });
    }
    assert_eq!(m.view(ms(0), "").dropped, 5);
    assert_eq!(m.view(ms(0), "").events.len(), EVENTS_KEPT);
    let (lines, missed) = m.log_since(0);
    assert_eq!((lines.len(), missed), (EVENTS_KEPT, 5));
    assert_eq!(lines[0].seq, 6);
    let (lines, missed) = m.log_since(m.seq() - 1);
    assert_eq!((lines.len(), missed), (1, 0));
    assert_eq!(lines[0].kind, "boot-up");
    m.clear_log();
    assert_eq!(m.log_since(0).0.len(), 0);
    // Nodes outside 1-127 never enter the table.
    m.on_frame(
        ms(1),
        None,
        true,
        &Frame::new(Id::Standard(0x700), &[5]).unwrap(),
    );
    assert_eq!(m.node_ids(), [5]);
}

#[test]
fn ages_and_clock_times_read_well() {
    assert_eq!(age_text(80_400), "80 ms");
    assert_eq!(age_text(12_345_000), "12.3 s");
    assert_eq!(age_text(3_600_000_000), "60 min");
    assert_eq!(clock_text(1_700_000_000_123), "22:13:20.123");
}

#[test]
fn the_module_doc_example() {
    let mut m = Model::new(Names::new(), vec![(0x10, 0x50)]);
    m.on_frame(
        Instant::from_millis(5),
        Some(0),
        true,
        &heartbeat(0x10, 0x05),
    );
    m.on_frame(
        Instant::from_millis(5),
        Some(0),
        true,
        &heartbeat(0x50, 0x7F),
    );
    let view = m.view(Instant::from_millis(105), "");
    assert_eq!(view.nodes[0].hb_age, "100 ms");
    assert_eq!(
        (
            view.pairs[0].active.as_str(),
            view.pairs[0].standby.as_str()
        ),
        ("0x10", "0x50")
    );
}

#[test]
fn a_silent_active_member_is_no_longer_active_and_its_standby_taking_over_is_a_failover() {
    let mut m = Model::new(Names::new(), vec![(0x10, 0x50)]);
    for t in [0, 100, 200] {
        m.on_frame(ms(t), Some(0), true, &heartbeat(0x10, 0x05));
        m.on_frame(ms(t), Some(0), true, &heartbeat(0x50, 0x7F));
    }
    // 0x10 stops beating; 0x50 beats on.
    m.on_frame(ms(300), Some(0), true, &heartbeat(0x50, 0x7F));
    m.on_frame(ms(400), Some(0), true, &heartbeat(0x50, 0x7F));
    m.tick(ms(501));
    let v = m.view(ms(501), "");
    assert_eq!(
        v.nodes[0].state, "operational",
        "its last word, shown as it is"
    );
    assert_eq!(v.nodes[0].hb_age, "301 ms silent");
    assert_eq!(v.pairs[0].active, "none");
    m.on_frame(ms(520), Some(0), true, &heartbeat(0x50, 0x05));
    assert_eq!(
        observations(&m),
        [
            "monitor: pair 0x10/0x50: 0x10 active",
            "monitor: pair 0x10/0x50: no active member",
            "monitor: node 0x10 heartbeat silent for 301 ms",
            "monitor: pair 0x10/0x50: failover: 0x50 active (was 0x10)",
        ]
    );
}
