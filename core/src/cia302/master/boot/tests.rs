//! The boot process against scripted answers: the order of its accesses, and how each
//! failure maps to a CiA 302-2 error status letter.

use super::*;
use crate::cia301::sdo::{Direction, SdoError, SdoErrorKind};
use crate::cia302::master::config::{ExpectedIdentity, SlaveConfig};
use crate::frame::cob_id::NodeId;
use crate::od::abort::AbortCode;

const N: NodeId = NodeId::must(9);

fn run(
    cfg: &SlaveConfig,
    id: &ExpectedIdentity,
    mut answer: impl FnMut(Access<'_>) -> Result<[u8; 4], SdoError>,
) -> (Vec<(u16, u8, bool)>, Outcome) {
    let mut p = Process::new(cfg, cfg.stamp);
    let mut seen = Vec::new();
    loop {
        let a = p.access(cfg).unwrap();
        let (index, sub, write) = match a {
            Access::Read { index, sub } => (index, sub, false),
            Access::Write { index, sub, .. } => (index, sub, true),
        };
        seen.push((index, sub, write));
        let r = answer(a);
        let out = p.handle(cfg, id, r.as_ref().map(|b| &b[..]).map_err(|e| *e));
        if out != Outcome::Continue {
            assert_eq!(p.access(cfg), None);
            return (seen, out);
        }
    }
}

#[test]
fn reads_only_what_is_checked_then_configures_then_heartbeat() {
    let cfg = SlaveConfig::new(N)
        .write_u8(0x2000, 1, 7)
        .write_u32(0x2001, 0, 9)
        .heartbeat(100, 250);
    let id = ExpectedIdentity {
        vendor: 0x1234,
        serial: 42,
        ..Default::default()
    };
    let (seen, out) = run(&cfg, &id, |a| {
        Ok(match a {
            Access::Read { sub: 1, .. } => 0x1234u32,
            Access::Read { sub: 4, .. } => 42,
            _ => 0,
        }
        .to_le_bytes())
    });
    assert_eq!(out, Outcome::Done);
    assert_eq!(
        seen,
        [
            (0x1000, 0, false),
            (0x1018, 1, false),
            (0x1018, 4, false),
            (0x2000, 1, true),
            (0x2001, 0, true),
            (0x1017, 0, true)
        ]
    );
}

#[test]
fn mismatch_names_the_letter_and_both_values() {
    let cfg = SlaveConfig::new(N);
    let id = ExpectedIdentity {
        device_type: 0x191,
        product: 5,
        ..Default::default()
    };
    let (_, out) = run(&cfg, &id, |a| {
        Ok(match a {
            Access::Read { sub: 0, .. } => 0x191u32,
            _ => 6,
        }
        .to_le_bytes())
    });
    assert_eq!(
        out,
        Outcome::Mismatch(IdentityMismatch {
            status: ErrorStatus::M,
            index: 0x1018,
            sub: 2,
            expected: 5,
            actual: 6
        })
    );
}

#[test]
fn failures_map_to_letters() {
    let err = |index, sub, direction| SdoError {
        node: N,
        index,
        sub,
        direction,
        kind: SdoErrorKind::Client(AbortCode::TIMEOUT),
    };
    let cfg = SlaveConfig::new(N).write_u8(0x2000, 0, 1);
    let (_, out) = run(&cfg, &ExpectedIdentity::default(), |_| {
        Err(err(0x1000, 0, Direction::Upload))
    });
    assert!(matches!(
        out,
        Outcome::Failed {
            status: ErrorStatus::B,
            ..
        }
    ));
    let (seen, out) = run(&cfg, &ExpectedIdentity::default(), |a| match a {
        Access::Write { .. } => Err(err(0x2000, 0, Direction::Download)),
        _ => Ok([0; 4]),
    });
    assert_eq!(seen.len(), 2);
    assert!(matches!(
        out,
        Outcome::Failed {
            status: ErrorStatus::J,
            ..
        }
    ));
}

#[test]
fn short_identity_reply_is_refused() {
    let cfg = SlaveConfig::new(N);
    let mut p = Process::new(&cfg, cfg.stamp);
    let out = p.handle(&cfg, &ExpectedIdentity::default(), Ok(&[1, 2]));
    assert_eq!(
        out,
        Outcome::Failed {
            status: ErrorStatus::C,
            reason: BootError::BadReply {
                index: 0x1000,
                sub: 0,
                len: 2
            }
        }
    );
}

#[test]
fn pdo_step_runs_the_configurator_in_cia_order() {
    use crate::cia301::pdo::MapEntry;
    use crate::cia302::pdo_config::PdoConfig;
    use crate::frame::cob_id::CobId;
    let pdo = PdoConfig::new(CobId(0x189), 254)
        .event_timer(100)
        .mapping(&[MapEntry::new(0x2000, 1, 16)])
        .unwrap();
    let cfg = SlaveConfig::new(N).tpdo(1, pdo).write_u8(0x2001, 0, 1);
    let (seen, out) = run(&cfg, &ExpectedIdentity::default(), |a| {
        Ok(match a {
            Access::Read { index: 0x1800, .. } => 0x189u32,
            _ => 0,
        }
        .to_le_bytes())
    });
    assert_eq!(out, Outcome::Done);
    assert_eq!(
        seen,
        [
            (0x1000, 0, false),
            (0x1800, 1, false),
            (0x1800, 1, true),
            (0x1800, 2, true),
            (0x1800, 5, true),
            (0x1A00, 0, true),
            (0x1A00, 1, true),
            (0x1A00, 0, true),
            (0x1800, 1, true),
            (0x2001, 0, true),
        ]
    );
}

#[test]
fn pdo_refused_and_different_fails_with_j_naming_the_entry() {
    use crate::cia302::pdo_config::{PdoConfig, PdoConfigErrorKind};
    use crate::frame::cob_id::CobId;
    let cfg = SlaveConfig::new(N).tpdo(2, PdoConfig::new(CobId(0x289), 1));
    let refused = |index, sub| SdoError {
        node: N,
        index,
        sub,
        direction: Direction::Download,
        kind: SdoErrorKind::Server(AbortCode::READ_ONLY),
    };
    // The device refuses every write and its COB-ID is another one.
    let (_, out) = run(&cfg, &ExpectedIdentity::default(), |a| match a {
        Access::Write { index, sub, .. } => Err(refused(index, sub)),
        Access::Read { index: 0x1801, .. } => Ok(0x4000_0199u32.to_le_bytes()),
        Access::Read { .. } => Ok([0; 4]),
    });
    let Outcome::Failed {
        status: ErrorStatus::J,
        reason: BootError::Pdo(e),
    } = out
    else {
        panic!("{out:?}")
    };
    assert_eq!((e.node, e.index, e.sub), (N, 0x1801, 1));
    assert!(e.fallback);
    assert!(matches!(e.kind, PdoConfigErrorKind::Mismatch { .. }));
}

#[test]
fn pdo_number_out_of_range_fails_without_panicking() {
    use crate::cia302::pdo_config::PdoConfig;
    use crate::frame::cob_id::CobId;
    let cfg = SlaveConfig::new(N).rpdo(513, PdoConfig::new(CobId(0x209), 255));
    let mut p = Process::new(&cfg, cfg.stamp);
    let out = p.handle(&cfg, &ExpectedIdentity::default(), Ok(&[0; 4]));
    assert_eq!(
        out,
        Outcome::Failed {
            status: ErrorStatus::J,
            reason: BootError::NoSuchPdo { pdo: 513 }
        }
    );
    assert_eq!(p.access(&cfg), None);
}

#[test]
fn letters_and_descriptions() {
    assert_eq!(ErrorStatus::O.letter(), 'O');
    assert_eq!(
        ErrorStatus::C.to_string(),
        "error status C: device type 0x1000 differs from 0x1F84"
    );
    assert_eq!(
        ErrorStatus::N.identity_objects(),
        Some(((0x1018, 3), 0x1F87))
    );
}

#[test]
fn refused_writes_continue_and_are_counted_when_asked_for() {
    let refused = |index, sub| SdoError {
        node: N,
        index,
        sub,
        direction: Direction::Download,
        kind: SdoErrorKind::Server(AbortCode::READ_ONLY),
    };
    let cfg = SlaveConfig::new(N)
        .write_u8(0x2000, 0, 1)
        .write_u8(0x2001, 0, 2)
        .write_u8(0x2002, 0, 3)
        .heartbeat(100, 0)
        .with_write_aborts(crate::cia302::master::config::WriteAborts::Continue);
    let mut p = Process::new(&cfg, cfg.stamp);
    let id = ExpectedIdentity::default();
    let mut seen = Vec::new();
    let mut reported = Vec::new();
    while let Some(a) = p.access(&cfg) {
        let r = match a {
            Access::Write { index, sub, .. } if index == 0x2000 || index == 0x2002 => {
                Err(refused(index, sub))
            }
            Access::Write { index, sub, .. } => {
                seen.push((index, sub));
                Ok([0; 4])
            }
            Access::Read { .. } => Ok([0; 4]),
        };
        let out = p.handle(&cfg, &id, r.as_ref().map(|b| &b[..]).map_err(|e| *e));
        reported.extend(p.take_abort());
        if out != Outcome::Continue {
            assert_eq!(out, Outcome::Done);
            break;
        }
    }
    assert_eq!(seen, [(0x2001, 0), (0x1017, 0)]);
    assert_eq!(
        reported,
        [
            (0x2000, 0, AbortCode::READ_ONLY),
            (0x2002, 0, AbortCode::READ_ONLY)
        ]
    );
    // A slave that stops answering still fails the boot, with status J.
    let (_, out) = run(&cfg, &id, |a| match a {
        Access::Write { index, sub, .. } => Err(SdoError {
            kind: SdoErrorKind::Client(AbortCode::TIMEOUT),
            ..refused(index, sub)
        }),
        _ => Ok([0; 4]),
    });
    assert!(matches!(
        out,
        Outcome::Failed {
            status: ErrorStatus::J,
            ..
        }
    ));
}

#[test]
fn a_slave_holding_the_expected_stamp_is_not_written_again() {
    use crate::cia302::master::config::ConfigurationStamp;
    let stamp = ConfigurationStamp {
        date: 15_000,
        time: 3_600_000,
    };
    let cfg = SlaveConfig::new(N)
        .write_u8(0x2000, 0, 1)
        .heartbeat(100, 0)
        .with_stamp(stamp)
        .with_store(true);
    let holds = |date: u32, time: u32| {
        move |a: Access<'_>| match a {
            Access::Read { index: 0x1020, sub } => {
                Ok(if sub == 1 { date } else { time }.to_le_bytes())
            }
            _ => Ok([0; 4]),
        }
    };
    let id = ExpectedIdentity::default();
    let (seen, out) = run(&cfg, &id, holds(15_000, 3_600_000));
    assert_eq!(out, Outcome::Done);
    assert_eq!(
        seen,
        [(0x1000, 0, false), (0x1020, 1, false), (0x1020, 2, false)]
    );
    // Another time (or date): configured, stamped, stored, in that order.
    for (date, time) in [(15_000, 1), (1, 3_600_000)] {
        let (seen, out) = run(&cfg, &id, holds(date, time));
        assert_eq!(out, Outcome::Done);
        assert_eq!(
            seen,
            [
                (0x1000, 0, false),
                (0x1020, 1, false),
                (0x1020, 2, false),
                (0x2000, 0, true),
                (0x1017, 0, true),
                (0x1020, 1, true),
                (0x1020, 2, true),
                (0x1010, 1, true),
            ]
        );
    }
}

#[test]
fn without_0x1020_the_slave_is_configured_and_a_refused_write_skips_stamp_and_store() {
    use crate::cia302::master::config::{ConfigurationStamp, WriteAborts};
    let cfg = SlaveConfig::new(N)
        .write_u8(0x2000, 0, 1)
        .write_u8(0x2001, 0, 1)
        .with_stamp(ConfigurationStamp { date: 1, time: 2 })
        .with_store(true)
        .with_write_aborts(WriteAborts::Continue);
    let refuse = |index, sub, direction| SdoError {
        node: N,
        index,
        sub,
        direction,
        kind: SdoErrorKind::Server(AbortCode::NO_OBJECT),
    };
    let (seen, out) = run(&cfg, &ExpectedIdentity::default(), |a| match a {
        Access::Read { index: 0x1020, sub } => Err(refuse(0x1020, sub, Direction::Upload)),
        Access::Write {
            index: 0x2000, sub, ..
        } => Err(refuse(0x2000, sub, Direction::Download)),
        _ => Ok([0; 4]),
    });
    assert_eq!(out, Outcome::Done);
    assert_eq!(
        seen,
        [
            (0x1000, 0, false),
            (0x1020, 1, false),
            (0x2000, 0, true),
            (0x2001, 0, true),
        ]
    );
    // The written data of the stamp and the store: the expected values and "save".
    let cfg = cfg.with_write_aborts(WriteAborts::Stop);
    let mut data = Vec::new();
    let _ = run(&cfg, &ExpectedIdentity::default(), |a| {
        if let Access::Write {
            index,
            sub,
            data: d,
        } = a
        {
            data.push((index, sub, d.to_vec()));
        }
        Ok([9; 4])
    });
    assert_eq!(
        data[2..],
        [
            (0x1020, 1, 1u32.to_le_bytes().to_vec()),
            (0x1020, 2, 2u32.to_le_bytes().to_vec()),
            (0x1010, 1, b"save".to_vec()),
        ]
    );
}
