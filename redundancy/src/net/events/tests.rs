//! The flat stream's view of the station's events: what arrives, typed, and what stays off.

use super::*;
use crate::logical::NetworkEvent;
use crate::supervisor::pairs::PairsEvent;
use crate::PairId;
use duocan::master::{BootError, ErrorStatus, IdentityMismatch};
use duocan::net::{CoreEvent, NetEvent};
use duocan::{Frame, Id};

/// The event of the door's stream a network event becomes.
fn flat(kind: NetworkEventKind) -> Option<NetEvent> {
    let e = NetworkEvent {
        at: Instant::from_millis(7),
        kind,
    };
    match super::super::core::core_event(e)? {
        CoreEvent::Net(e) => Some(e),
        _ => None,
    }
}

#[test]
fn discrepancy_and_its_clearing_reach_the_flat_stream() {
    let (a, b) = (
        Frame::from_array(Id::Standard(0x190), [1]),
        Frame::from_array(Id::Standard(0x1D0), [2]),
    );
    let e = flat(NetworkEventKind::Discrepancy {
        pair: PairId(1),
        function: 1,
        a,
        b,
    })
    .unwrap();
    assert_eq!(e.at(), Some(Instant::from_millis(7)));
    assert_eq!(
        e.to_string(),
        format!("pair 1 function 1: A sends {a}, B sends {b}")
    );
    assert!(matches!(
        e.ext(),
        Some(RedundantEvent::Link(LinkEvent {
            kind: LinkEventKind::Discrepancy { a: x, b: y, .. },
            ..
        })) if *x == a && *y == b
    ));
    let e = flat(NetworkEventKind::DiscrepancyCleared {
        pair: PairId(1),
        function: 1,
    })
    .unwrap();
    assert_eq!(e.to_string(), "pair 1 function 1: A and B agree again");
}

/// The supervisor's other reports reach the stream: a member joining and leaving its pair,
/// commands suspended, a replacement board addressed by LSS; typed as the supervisor
/// declares them, one line each.
#[test]
fn members_joining_and_leaving_suspensions_and_addressed_boards_reach_the_flat_stream() {
    use crate::supervisor::pairs::LossReason;
    let (at, node) = (Instant::from_millis(7), NodeId::must(0x50));
    let sup = |e| flat(NetworkEventKind::Other(StationEvent::Machine(e))).unwrap();
    let joined = PairsEvent::Joined {
        at,
        pair: PairId(0),
        member: Member::B,
        node,
    };
    let e = sup(SupervisorEvent::Pairs(joined));
    assert_eq!(e.ext(), Some(&RedundantEvent::Member(joined)));
    assert_eq!(e.to_string(), "pair 0 member B (node 0x50): joined");
    assert_eq!((e.node(), e.at()), (Some(node), Some(at)));
    let lost = PairsEvent::Lost {
        at,
        pair: PairId(0),
        member: Member::B,
        node,
        reason: LossReason::Rebooted,
    };
    let e = sup(SupervisorEvent::Pairs(lost));
    assert_eq!(
        e.to_string(),
        "pair 0 member B (node 0x50): lost, it booted again"
    );
    let until = Instant::from_millis(500);
    let e = sup(SupervisorEvent::FlyingMaster(FlyingEvent::Suspended {
        at,
        until,
    }));
    assert_eq!(
        e.to_string(),
        format!(
            "this master: NMT commands suspended until {until}, another active master suspected"
        )
    );
    assert_eq!(e.at(), Some(at));
    let address = duocan::cia305::LssAddress {
        vendor: 0xD0CA00,
        product: 0x305,
        revision: 1,
        serial: 2,
    };
    let b = BoardAddressed {
        at,
        pair: PairId(0),
        member: Member::B,
        node,
        address,
    };
    let e = sup(SupervisorEvent::Addressed(b));
    assert_eq!(e.ext(), Some(&RedundantEvent::Addressed(b)));
    assert_eq!(
        e.to_string(),
        format!("pair 0 member B: a board without node-ID ({address}) given node 0x50 by LSS")
    );
    assert_eq!(e.node(), Some(node));
}

/// Every other report of the dual-bus layer reaches the stream too, typed as the layer
/// declares it, one line each.
#[test]
fn every_other_report_of_the_dual_bus_layer_reaches_the_flat_stream() {
    let kinds = [
        LinkEventKind::Lag {
            port: 1,
            lag: duocan::Duration::from_millis(12),
            window: duocan::Duration::from_millis(14),
        },
        LinkEventKind::LagCleared { port: 1 },
        LinkEventKind::Trusted {
            node: NodeId::must(0x10),
        },
    ];
    for kind in kinds {
        let l = LinkEvent {
            at: Instant::from_millis(7),
            kind,
        };
        let e = flat(NetworkEventKind::Other(StationEvent::Link(l))).unwrap();
        assert_eq!(e.ext(), Some(&RedundantEvent::Link(l)));
        assert_eq!(e.to_string(), kind.to_string());
        assert!(!e.to_string().contains('\n'));
        assert_eq!(e.at(), Some(Instant::from_millis(7)));
    }
}

/// The event of the stream a report of the master becomes.
fn master(kind: MasterEventKind) -> Option<NetEvent> {
    flat(NetworkEventKind::Other(StationEvent::Machine(
        SupervisorEvent::Master(MasterEvent {
            at: Instant::from_millis(7),
            kind,
        }),
    )))
}

/// The event of the stream a report of the master's node becomes.
fn node_report(kind: NodeEventKind) -> Option<NetEvent> {
    flat(NetworkEventKind::Other(StationEvent::Machine(
        SupervisorEvent::Node(NodeEvent {
            at: Instant::from_millis(7),
            kind,
        }),
    )))
}

#[test]
fn a_slave_the_boot_process_refused_or_failed_reaches_the_flat_stream() {
    let node = NodeId::must(0x12);
    let kind = MasterEventKind::IdentityMismatch {
        node,
        mismatch: IdentityMismatch {
            status: ErrorStatus::D,
            index: 0x1018,
            sub: 1,
            expected: 0x1234,
            actual: 0x4321,
        },
    };
    let mismatch = master(kind.clone()).unwrap();
    assert_eq!(mismatch.node(), Some(node));
    assert_eq!(
        mismatch
            .ext::<RedundantEvent>()
            .and_then(RedundantEvent::master),
        Some(&kind)
    );
    assert!(!mismatch.is_failover());
    let failed = master(MasterEventKind::ConfigFailed {
        node,
        status: ErrorStatus::J,
        reason: BootError::NoSuchPdo { pdo: 600 },
    })
    .unwrap();
    assert!(
        failed
            .to_string()
            .starts_with("node 0x12: not started, error status J"),
        "{failed}"
    );
    assert_eq!(failed.at(), Some(Instant::from_millis(7)));
}

/// What the master reports beyond failures, dropped before, arrives typed as the master
/// declares it, with its line: a slave configured and started, a boot failure with its CiA
/// 302-2 status, a lost slave's heartbeat back, a member refused, an LSS result.
#[test]
fn a_slave_configured_started_refused_or_back_and_lss_results_reach_the_flat_stream() {
    use crate::supervisor::JoinRefusal;
    use duocan::cia305::LssOutcome;
    use duocan::master::StartPolicy;
    let (at, node) = (Instant::from_millis(7), NodeId::must(0x12));
    let configured = MasterEventKind::SlaveConfigured {
        node,
        start: StartPolicy::Application,
    };
    let e = master(configured.clone()).unwrap();
    assert_eq!(
        e.ext(),
        Some(&RedundantEvent::Master(MasterEvent {
            at,
            kind: configured
        }))
    );
    assert_eq!(
        e.to_string(),
        "node 0x12: configured, the application starts it"
    );
    assert_eq!((e.node(), e.at()), (Some(node), Some(at)));
    let e = master(MasterEventKind::SlaveStarted {
        node,
        broadcast: false,
    })
    .unwrap();
    assert_eq!(e.to_string(), "node 0x12: started");
    let e = master(MasterEventKind::ConfigFailed {
        node,
        status: ErrorStatus::B,
        reason: BootError::NoSuchPdo { pdo: 600 },
    })
    .unwrap();
    assert!(
        matches!(
            e.ext::<RedundantEvent>().and_then(RedundantEvent::master),
            Some(MasterEventKind::ConfigFailed {
                status: ErrorStatus::B,
                ..
            })
        ),
        "{e:?}"
    );
    assert!(
        e.to_string().starts_with(
            "node 0x12: not started, error status B: no answer to the upload of 0x1000"
        ),
        "{e}"
    );

    let e = node_report(NodeEventKind::HeartbeatResumed { node }).unwrap();
    assert_eq!(
        e.ext::<RedundantEvent>()
            .and_then(RedundantEvent::node_event),
        Some(&NodeEventKind::HeartbeatResumed { node })
    );
    assert_eq!(e.to_string(), "node 0x12: heartbeat back");
    assert_eq!(e.node(), Some(node));

    let refused = NotJoined {
        at,
        pair: PairId(0),
        member: Member::B,
        node,
        why: JoinRefusal::Config {
            status: ErrorStatus::J,
            reason: BootError::NoSuchPdo { pdo: 600 },
        },
    };
    let e = flat(NetworkEventKind::Other(StationEvent::Machine(
        SupervisorEvent::NotJoined(refused),
    )))
    .unwrap();
    assert_eq!(e.ext(), Some(&RedundantEvent::NotJoined(refused)));
    assert!(
        e.to_string()
            .starts_with("pair 0 member B (node 0x12): not joined, error status J"),
        "{e}"
    );
    assert_eq!(e.node(), Some(node));

    let lss = LssMasterEvent {
        at,
        kind: LssMasterEventKind::Done(LssOutcome::NodeIdConfigured),
    };
    let e = flat(NetworkEventKind::Other(StationEvent::Machine(
        SupervisorEvent::Lss(lss),
    )))
    .unwrap();
    assert_eq!(e.ext(), Some(&RedundantEvent::Lss(lss)));
    assert_eq!(e.to_string(), "LSS: configure node-ID accepted");
    assert_eq!(e.at(), Some(at));
}

/// What another event already says, and what comes once per frame or per cycle, stays off
/// the stream (the rule of the module's doc); everything else of the node reaches it.
#[test]
fn duplicates_and_per_frame_reports_stay_off_the_flat_stream() {
    let node = NodeId::must(0x12);
    for kind in [
        MasterEventKind::SlaveBootUp { node },
        MasterEventKind::ActiveChanged { active: true },
        MasterEventKind::ProgramProgress {
            node,
            done: 7,
            total: 70,
        },
    ] {
        assert_eq!(master(kind.clone()), None, "{kind:?}");
    }
    for kind in [
        NodeEventKind::Sync {
            counter: None,
            produced: true,
        },
        NodeEventKind::ObjectWritten {
            index: 0x1017,
            sub: 0,
            by: duocan::node::Writer::Sdo,
        },
        NodeEventKind::HeartbeatTimeout {
            node,
            last: Instant::ZERO,
        },
    ] {
        assert_eq!(node_report(kind), None, "{kind:?}");
    }
    let e = node_report(NodeEventKind::GuardToggleError { node }).unwrap();
    assert_eq!(
        e.to_string(),
        "node 0x12: guarding toggle bit did not alternate"
    );
}

#[test]
fn a_member_never_heard_reaches_the_flat_stream() {
    let node = NodeId::must(0x50);
    let e = flat(NetworkEventKind::Other(StationEvent::Machine(
        SupervisorEvent::Pairs(PairsEvent::Missing {
            at: Instant::from_millis(7),
            pair: PairId(0),
            member: Member::B,
            node,
            since: Instant::from_millis(2),
        }),
    )))
    .unwrap();
    assert_eq!(
        e,
        NetEvent::NotHeard {
            node,
            since: Instant::from_millis(2),
            at: Instant::from_millis(7)
        }
    );
    assert_eq!(
        (e.node(), e.at()),
        (Some(node), Some(Instant::from_millis(7)))
    );
    assert_eq!(e.to_string(), "node 0x50: not heard for 5 ms");
}

#[test]
fn reach_says_which_bus_in_words() {
    let node = NodeId::must(0x7A);
    let line = |heard| {
        flat(NetworkEventKind::Reach { node, heard })
            .unwrap()
            .to_string()
    };
    assert_eq!(line([false, true]), "node 0x7a: heard on bus 2 only");
    assert_eq!(line([true, false]), "node 0x7a: heard on bus 1 only");
    assert_eq!(line([true, true]), "node 0x7a: heard on both buses");
    assert_eq!(line([false, false]), "node 0x7a: heard on no bus");
}
