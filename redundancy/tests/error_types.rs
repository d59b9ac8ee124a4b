//! Every public error type of the crate is a standard error that crosses threads: a user
//! function returning `Box<dyn Error + Send + Sync>` ends each call in `?` without `map_err`.

use duocan::master::MasterError;
use duocan::sdo::{Direction, SdoError, SdoErrorKind};
use duocan::{AbortCode, NodeId};
use duocan_redundancy::link::config::ConfigError;
use duocan_redundancy::link::same_function::PairError;
use duocan_redundancy::supervisor::fd_guarding::{GuardingOnFd, GuardingSource};
use duocan_redundancy::supervisor::flying_master::{FlyingMasterError, MasterRole};
use duocan_redundancy::supervisor::pairs::PairsError;
use duocan_redundancy::{AddPairError, JoinRefusal, NetworkError, PairId, RedundantError, Role};
use std::error::Error;

type BoxError = Box<dyn Error + Send + Sync>;

// Compile-time: each type is `Error + Send + Sync + 'static`.
const _: () = {
    const fn check<T: core::error::Error + Send + Sync + 'static>() {}
    check::<ConfigError>();
    check::<PairError>();
    check::<PairsError>();
    check::<AddPairError>();
    check::<FlyingMasterError>();
    check::<JoinRefusal>();
    check::<NetworkError>();
    check::<RedundantError>();
    check::<GuardingOnFd>();
};

/// What a user function does: `?` on the error, nothing else.
fn user<E: Error + Send + Sync + 'static>(r: Result<(), E>) -> Result<(), BoxError> {
    r?;
    Ok(())
}

/// `?` boxes `e`, keeps its message, and the box downcasts back to it.
fn boxes<E: Error + Send + Sync + PartialEq + std::fmt::Debug + Copy + 'static>(e: E) {
    let text = e.to_string();
    assert!(!text.is_empty(), "{e:?} says nothing");
    let boxed = user(Err(e)).unwrap_err();
    assert_eq!(boxed.to_string(), text);
    assert_eq!(boxed.downcast_ref::<E>(), Some(&e));
}

fn sdo_error() -> SdoError {
    SdoError {
        node: NodeId::must(0x10),
        index: 0x1018,
        sub: 1,
        direction: Direction::Upload,
        kind: SdoErrorKind::Busy,
    }
}

#[test]
fn each_error_ends_a_call_in_the_question_mark() {
    boxes(ConfigError::Missing {
        index: 0x1F60,
        sub: 1,
        abort: AbortCode::NO_OBJECT,
    });
    boxes(PairError::Full);
    boxes(PairsError::NoPair(PairId(3)));
    boxes(AddPairError::Master(
        NodeId::must(0x10),
        MasterError::Standby,
    ));
    boxes(FlyingMasterError::WrongRole(MasterRole::Standby(None)));
    boxes(JoinRefusal::Master(MasterError::Standby));
    boxes(NetworkError::Standby);
    boxes(NetworkError::Sdo(sdo_error()));
    boxes(NetworkError::Closed);
    boxes(GuardingOnFd {
        node: NodeId::must(0x10),
        source: GuardingSource::MasterGuards { guard_time_ms: 100 },
    });
}

#[test]
fn wrapping_errors_name_their_cause() {
    let e = NetworkError::from(sdo_error());
    assert_eq!(e, NetworkError::Sdo(sdo_error()));
    assert_eq!(
        e.source().and_then(|s| s.downcast_ref::<SdoError>()),
        Some(&sdo_error())
    );
    let e = AddPairError::from(PairsError::Full);
    assert_eq!(
        e.source().and_then(|s| s.downcast_ref::<PairsError>()),
        Some(&PairsError::Full)
    );
    assert!(NetworkError::Standby.source().is_none());
}

#[cfg(feature = "tokio")]
#[test]
fn a_stopped_runtime_is_a_network_error() {
    fn closed() -> Result<(), NetworkError> {
        Err(duocan::runtime::RuntimeClosed)?
    }
    assert_eq!(closed(), Err(NetworkError::Closed));
}

#[test]
fn the_front_door_error_ends_a_call_in_the_question_mark_and_keeps_its_cause() {
    // Not `Copy` (a port's name is a string): boxed by hand.
    for e in [
        RedundantError::BadNodeId {
            role: Role::PairMember,
            id: 0,
        },
        RedundantError::ZeroDuration {
            setting: "heartbeat",
        },
        RedundantError::Port {
            port: 1,
            name: "can1".into(),
            why: "no such device".into(),
        },
        RedundantError::Closed,
    ] {
        let text = e.to_string();
        let boxed = user(Err(e.clone())).unwrap_err();
        assert_eq!(boxed.to_string(), text);
        assert_eq!(boxed.downcast_ref::<RedundantError>(), Some(&e));
    }
    // A refusal of the network converts with `?`, its cause kept (a transfer failure too).
    fn refused() -> Result<(), RedundantError> {
        Err(NetworkError::Standby)?
    }
    let e = refused().unwrap_err();
    assert_eq!(
        e.source().and_then(|s| s.downcast_ref::<NetworkError>()),
        Some(&NetworkError::Standby)
    );
    assert_eq!(
        RedundantError::from(NetworkError::Sdo(sdo_error())),
        RedundantError::Network(NetworkError::Sdo(sdo_error()))
    );
    assert_eq!(
        RedundantError::from(NetworkError::Closed),
        RedundantError::Closed
    );
    assert_eq!(
        RedundantError::from(NetworkError::Sdo(sdo_error())).node(),
        Some(NodeId::must(0x10))
    );
    // The front door's error converts with `?` too, node and cause kept; a closed network is
    // one error whichever door says so.
    #[cfg(feature = "tokio")]
    {
        use duocan::net::NetError;
        fn door() -> Result<(), RedundantError> {
            Err(NetError::Sdo(sdo_error()))?
        }
        let e = door().unwrap_err();
        assert_eq!(e, RedundantError::Net(NetError::Sdo(sdo_error())));
        assert_eq!(e.node(), Some(NodeId::must(0x10)));
        assert_eq!(e.to_string(), sdo_error().to_string());
        assert!(e.source().is_some());
        assert_eq!(
            RedundantError::from(NetError::Closed),
            RedundantError::Closed
        );
    }
}
