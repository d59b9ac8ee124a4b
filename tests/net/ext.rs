//! What a core adds to the door's vocabulary: its own events in the stream
//! ([`NetEvent::Ext`]), the failover rule of the stream, and the errors of a master core.

use duocan::machine::{ErrorCause, PortReason, PortState};
use duocan::master::MasterError;
use duocan::net::{ExtEvent, Extension, NetError, NetEvent};
use duocan::{Instant, NodeId};
use std::fmt;

/// A core's own event: a node's alarm, a failover when `takeover`.
#[derive(Debug, PartialEq)]
pub struct Alarm {
    pub node: NodeId,
    pub takeover: bool,
    pub at: Instant,
}

impl fmt::Display for Alarm {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: alarm", self.node)
    }
}

impl Extension for Alarm {
    fn at(&self) -> Instant {
        self.at
    }
    fn node(&self) -> Option<NodeId> {
        Some(self.node)
    }
    fn is_failover(&self) -> bool {
        self.takeover
    }
    fn eq_dyn(&self, other: &dyn Extension) -> bool {
        (other as &dyn std::any::Any).downcast_ref::<Alarm>() == Some(self)
    }
}

/// Another core's event, equal to no alarm.
#[derive(Debug)]
struct Tick;

impl fmt::Display for Tick {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("tick")
    }
}

impl Extension for Tick {
    fn at(&self) -> Instant {
        Instant::ZERO
    }
    fn node(&self) -> Option<NodeId> {
        None
    }
    fn eq_dyn(&self, other: &dyn Extension) -> bool {
        (other as &dyn std::any::Any).is::<Tick>()
    }
}

pub fn alarm(node: u8, takeover: bool, at: Instant) -> NetEvent {
    NetEvent::Ext(ExtEvent::new(Alarm {
        node: NodeId::must(node),
        takeover,
        at,
    }))
}

#[test]
fn a_cores_event_answers_the_common_questions_and_comes_back_typed() {
    let at = Instant::from_millis(7);
    let e = alarm(5, false, at);
    assert_eq!(e.node(), NodeId::new(5));
    assert_eq!(e.at(), Some(at));
    assert_eq!(e.to_string(), "node 0x05: alarm");
    assert!(!e.is_failover());
    assert!(alarm(5, true, at).is_failover());
    let a = e.ext::<Alarm>().unwrap();
    assert_eq!((a.node.raw(), a.takeover), (5, false));
    assert!(e.ext::<Tick>().is_none());
    assert!(NetEvent::Lagged(1).ext::<Alarm>().is_none());
    // Equal when the same event; never equal to another type's.
    assert_eq!(e, alarm(5, false, at));
    assert_ne!(e, alarm(6, false, at));
    let tick = NetEvent::Ext(ExtEvent::new(Tick));
    assert_ne!(e, tick);
    assert_ne!(tick, e);
    assert_eq!(tick, tick.clone());
    assert!(format!("{e:?}").contains("Alarm"));
}

#[test]
fn a_bus_that_fails_is_a_failover_and_a_failed_recovery_is_not() {
    let state = |from, to| NetEvent::PortState {
        port: 1,
        from,
        to,
        reason: PortReason::Down(ErrorCause::InterfaceDown),
        at: Instant::ZERO,
    };
    assert!(state(PortState::Ok, PortState::Failed).is_failover());
    assert!(state(PortState::Suspect, PortState::Failed).is_failover());
    assert!(!state(PortState::Recovering, PortState::Failed).is_failover());
    assert!(!state(PortState::Failed, PortState::Recovering).is_failover());
    assert!(!state(PortState::Ok, PortState::Suspect).is_failover());
    assert!(!NetEvent::Lagged(3).is_failover());
}

#[test]
fn a_standby_master_and_a_masters_refusal_are_errors_of_the_door() {
    let e = NetError::from(MasterError::Standby);
    assert_eq!(e, NetError::Standby { node: None });
    assert!(e.to_string().contains("standby"), "{e}");
    let node = NodeId::must(0x10);
    let e = NetError::Standby { node: Some(node) };
    assert_eq!(e.node(), Some(node));
    assert!(e.to_string().starts_with("node 16: "), "{e}");
    let e = NetError::from(MasterError::OwnNode(node));
    assert_eq!(e, NetError::Master(MasterError::OwnNode(node)));
    assert_eq!(e.node(), Some(node));
    assert!(std::error::Error::source(&e).is_some());
    assert_eq!(NetError::Master(MasterError::QueueFull).node(), None);
}
