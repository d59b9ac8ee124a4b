//! Every public error type of the crate is a standard error that crosses threads: a user
//! function returning `Box<dyn Error + Send + Sync>` ends each call in `?` without `map_err`.

use duocan::cia302::pdo_config::{AccessError, MirrorError, PdoConfigError, PdoConfigErrorKind};
use duocan::frame::{FrameError, Malformed};
use duocan::master::{BootError, MasterError};
use duocan::node::QueueFull;
use duocan::od::parameters::{
    FileStorage, ImageError, MemoryStorage, MemoryStorageError, ParameterStorage, StorageError,
};
use duocan::od::BuildError;
use duocan::pdo::PdoError;
use duocan::profile::railway::safety::SafetyError;
use duocan::profile::railway::{AddressError, DeviceAddress, PayloadError, TableError};
use duocan::sdo::{Direction, SdoError, SdoErrorKind};
use duocan::{AbortCode, Frame, Id, NodeId};
use std::error::Error;

type BoxError = Box<dyn Error + Send + Sync>;

// Compile-time: each type is `Error + Send + Sync + 'static`.
const _: () = {
    const fn check<T: core::error::Error + Send + Sync + 'static>() {}
    check::<FrameError>();
    check::<Malformed>();
    check::<AbortCode>();
    check::<BuildError>();
    check::<StorageError>();
    check::<ImageError>();
    check::<MemoryStorageError>();
    check::<duocan::od::parameters::FileStorageError>();
    check::<SdoError>();
    check::<PdoError>();
    check::<duocan::cia304::srdo::config::SrdoConfigError>();
    check::<duocan::node::SrdoMarkError>();
    check::<QueueFull>();
    check::<AddressError>();
    check::<PayloadError>();
    check::<SafetyError>();
    check::<TableError>();
    check::<BootError>();
    check::<MasterError>();
    check::<AccessError>();
    check::<PdoConfigError>();
    check::<MirrorError>();
    check::<duocan::sim::SimError>();
    check::<duocan::capture::pcap::PcapError>();
    check::<duocan::capture::candump::ParseError>();
    check::<duocan::eds::EdsError>();
    check::<duocan::eds::ExportError>();
    check::<duocan::eds::LookupError>();
    check::<duocan::master::ConciseError>();
    check::<duocan::master::ProgramDownloadError>();
    check::<duocan::cia302::program::FlashError>();
    check::<duocan::cia305::LssError>();
    check::<duocan::cia305::LssFrameError>();
    check::<duocan::cia305::LssStoreError>();
};

#[cfg(feature = "udp")]
const _: () = {
    const fn check<T: core::error::Error + Send + Sync + 'static>() {}
    check::<duocan::port::udp::DecodeError>();
};

#[cfg(feature = "tokio")]
const _: () = {
    const fn check<T: core::error::Error + Send + Sync + 'static>() {}
    check::<duocan::port::PortError>();
    check::<duocan::runtime::StartError>();
    check::<duocan::runtime::RuntimeClosed>();
    check::<duocan::runtime::RuntimeError>();
    check::<duocan::net::NetError>();
};

/// What a user function does: `?` on the error, nothing else.
fn user<E: Error + Send + Sync + 'static>(r: Result<(), E>) -> Result<(), BoxError> {
    r?;
    Ok(())
}

/// `?` boxes `e`, keeps its message, and the box downcasts back to it.
fn boxes<E: Error + Send + Sync + PartialEq + std::fmt::Debug + Clone + 'static>(e: E) {
    let text = e.to_string();
    assert!(!text.is_empty(), "{e:?} says nothing");
    let boxed = user(Err(e.clone())).unwrap_err();
    assert_eq!(boxed.to_string(), text);
    assert_eq!(boxed.downcast_ref::<E>(), Some(&e));
}

fn sdo_error(kind: SdoErrorKind) -> SdoError {
    SdoError {
        node: NodeId::must(5),
        index: 0x2000,
        sub: 1,
        direction: Direction::Upload,
        kind,
    }
}

#[test]
fn each_error_ends_a_call_in_the_question_mark() {
    // Real failures where one call makes them.
    let frame = Frame::new(Id::Standard(0x181), &[0; 9]);
    boxes(frame.unwrap_err());
    let address = DeviceAddress::new(16, 0, 0, 0, 0);
    boxes(address.unwrap_err());
    // The rest as values.
    boxes(Malformed::UnexpectedRemote);
    boxes(AbortCode::NO_OBJECT);
    boxes(BuildError::Duplicate {
        index: 0x2000,
        sub: 0,
    });
    boxes(sdo_error(SdoErrorKind::Busy));
    boxes(PdoError::NoSuchPdo { pdo: 9 });
    boxes(QueueFull);
    boxes(PayloadError::DataTooLong { len: 9 });
    boxes(SafetyError::UnknownObject { index: 0x1000 });
    boxes(TableError::AddressTaken {
        address: DeviceAddress::new(1, 1, 1, 1, 0).unwrap(),
        by: NodeId::must(3),
    });
    boxes(BootError::NoSuchPdo { pdo: 600 });
    let concise = duocan::master::ConciseDcf::parse(&[1, 0]).unwrap_err();
    assert_eq!(
        concise.to_string(),
        "concise DCF, at byte 0: needs 4 more bytes, 2 left"
    );
    boxes(concise);
    boxes(BootError::ConciseDcf(concise));
    boxes(duocan::cia302::program::FlashError::DataFormatError);
    let program = duocan::master::ProgramDownloadError {
        node: NodeId::must(6),
        step: duocan::master::ProgramStep::Download,
        kind: duocan::master::ProgramErrorKind::Sdo(sdo_error(SdoErrorKind::Server(
            AbortCode::CANNOT_STORE,
        ))),
        resumed: true,
    };
    let text = program.to_string();
    assert!(text.contains("step download (0x1F50)"), "{text}");
    assert!(text.contains("the old program runs again"), "{text}");
    assert_eq!(program.code(), Some(AbortCode::CANNOT_STORE));
    boxes(program);
    boxes(MasterError::Busy(NodeId::must(6)));
    boxes(MasterError::Standby);
    boxes(AccessError::NoAnswer(None));
    boxes(PdoConfigError {
        node: NodeId::must(5),
        index: 0x1400,
        sub: 1,
        fallback: false,
        kind: PdoConfigErrorKind::BadReply { len: 0 },
    });
    boxes(MirrorError::NoMapping);
    let lss =
        duocan::cia305::LssResponse::decode(&Frame::new(Id::Standard(0x7E4), &[0x44]).unwrap());
    boxes(lss.unwrap_err());
    boxes(duocan::cia305::LssError::Timeout(
        duocan::cia305::LssService::Store,
    ));
    boxes(duocan::cia305::LssError::Malformed {
        service: duocan::cia305::LssService::Fastscan,
        error: duocan::cia305::LssFrameError::Length(1),
    });
    boxes(duocan::cia305::LssStoreError::Corrupt);
    boxes(MemoryStorage::<4>::new().store(&[0; 5]).unwrap_err());
    boxes(StorageError::TooLarge {
        needed: 600,
        capacity: 512,
    });
    boxes(ImageError::BadMagic);
    boxes(duocan::sim::SimError::PortCount { ports: 2, buses: 1 });
    boxes(duocan::capture::candump::parse_line("not a candump line").unwrap_err());
    let eds = duocan::eds::Description::parse(
        b"[FileInfo]\nFileName",
        "device.eds",
        &duocan::eds::ImportOptions::strict(),
    );
    boxes(eds.unwrap_err());
    boxes(duocan::eds::ExportError::Unrepresentable {
        index: 0x2000,
        sub: 0,
        why: "the string holds a control character",
    });
    let od = duocan::od::comm::standard_dictionary(5, Default::default());
    boxes(duocan::eds::find(&od, "no such name").unwrap_err());
    // Not `Clone`: boxed by hand.
    let e = duocan::capture::pcap::decode_packet(&[1, 2]).unwrap_err();
    let text = e.to_string();
    assert_eq!(user(Err(e)).unwrap_err().to_string(), text);
    let dir = std::env::temp_dir().join(format!("duocan-no-such-dir-{}", std::process::id()));
    let e = FileStorage::new(dir.join("params"))
        .store(b"x")
        .unwrap_err();
    let text = e.to_string();
    assert!(text.contains("cannot create"), "{text}");
    assert_eq!(user(Err(e)).unwrap_err().to_string(), text);
}

#[test]
fn wrapping_errors_name_their_cause() {
    let inner = sdo_error(SdoErrorKind::Server(AbortCode::READ_ONLY));
    let boot = BootError::Sdo(inner);
    let source = boot.source().expect("the SDO error is the cause");
    assert_eq!(source.downcast_ref::<SdoError>(), Some(&inner));
    // The SDO error's own cause is the abort code.
    let code = source.source().expect("the abort code is the cause");
    assert_eq!(
        code.downcast_ref::<AbortCode>(),
        Some(&AbortCode::READ_ONLY)
    );
    let refused = MasterError::Refused {
        index: 0x1F81,
        sub: 5,
        code: AbortCode::VALUE_RANGE,
    };
    assert!(refused.source().is_some());
    assert!(MasterError::Standby.source().is_none());
    assert!(AccessError::Aborted(AbortCode::NO_OBJECT)
        .source()
        .is_some());
    let corrupt = StorageError::Corrupt(ImageError::BadMagic);
    assert_eq!(
        corrupt
            .source()
            .and_then(|s| s.downcast_ref::<ImageError>()),
        Some(&ImageError::BadMagic)
    );
}

#[cfg(feature = "tokio")]
#[test]
fn runtime_errors_are_flat() {
    use duocan::runtime::{RuntimeClosed, RuntimeError};
    let inner = sdo_error(SdoErrorKind::Client(AbortCode::TIMEOUT));
    // `?` turns each part into the one runtime error…
    fn through(e: SdoError) -> Result<(), RuntimeError> {
        Err(e)?
    }
    fn closed() -> Result<(), RuntimeError> {
        Err(RuntimeClosed)?
    }
    let e = through(inner).unwrap_err();
    assert_eq!(e, RuntimeError::Sdo(inner));
    assert_eq!(e.to_string(), inner.to_string());
    assert_eq!(
        e.source().and_then(|s| s.downcast_ref::<SdoError>()),
        Some(&inner)
    );
    assert_eq!(closed().unwrap_err(), RuntimeError::Closed);
    // …which a user function boxes with `?` again.
    boxes(e);
    boxes(RuntimeError::Closed);
    boxes(RuntimeError::from(AbortCode::NO_OBJECT));
    boxes(RuntimeError::from(QueueFull));
    // Not `Clone`: boxed by hand.
    let e = duocan::port::PortError::new("can9", duocan::port::PortErrorKind::Closed, "closed");
    let text = e.to_string();
    assert_eq!(user(Err(e)).unwrap_err().to_string(), text);
}

#[cfg(feature = "tokio")]
#[test]
fn the_front_door_error_names_node_object_and_remedy() {
    use duocan::net::{Awaited, NetError};
    let inner = sdo_error(SdoErrorKind::Client(AbortCode::TIMEOUT));
    let e = NetError::Sdo(inner);
    assert_eq!(e.to_string(), inner.to_string());
    assert_eq!(
        e.source().and_then(|s| s.downcast_ref::<SdoError>()),
        Some(&inner)
    );
    assert!(e.is_no_answer());
    let node = NodeId::new(5).unwrap();
    let wrong = NetError::WrongSize {
        node,
        index: 0x1018,
        sub: 1,
        expected: 2,
        got: 4,
    };
    assert_eq!(
        wrong.to_string(),
        "node 5, object 0x1018 sub 1: the node sent 4 byte(s) but the type read needs 2: read it as a type of 4 byte(s) (see the node's EDS)"
    );
    let t = NetError::Timeout {
        node,
        awaited: Awaited::BootUp,
        after: std::time::Duration::from_millis(1500),
    };
    assert!(
        t.to_string()
            .starts_with("node 5: no boot-up within 1500 ms: check"),
        "{t}"
    );
    assert_eq!(t.node(), Some(node));
    for e in [
        e,
        wrong,
        t,
        NetError::Closed,
        NetError::NoSuchNode(0),
        NetError::ListenOnly { node: None },
    ] {
        boxes(e);
    }
}
