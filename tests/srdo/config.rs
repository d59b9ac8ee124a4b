//! The configuration a node needs to enter operational: 0x13FE, the checksum in 0x13FF as
//! CiA 304 computes it, the parameter rules; writes that void it; the refusal and its reason.

use crate::support::*;
use duocan::cia304::srdo::config::{
    self, crc16_ccitt, default_cob_ids, signature, SrdoConfigError, SrdoProblem,
};
use duocan::node::NodeEventKind as K;
use duocan::od::ObjectDictionary;
use duocan::{AbortCode, Instant, Machine, NmtState};

#[test]
fn crc_is_ccitt_with_zero_start() {
    // The published check value of CRC-16 CCITT (polynomial 0x1021, start 0, no reflection).
    assert_eq!(crc16_ccitt(0, b"123456789"), 0x31C3);
    assert_eq!(crc16_ccitt(0, &[]), 0);
}

#[test]
fn checksum_covers_the_parameters_in_the_order_cia_304_gives() {
    let mut n = bare(P_ID);
    configure(&mut n, false, 50, 10, &mapping());
    let (p, m) = config::read(n.od(), 1).unwrap().unwrap();
    // direction, SCT (LE), SRVT, COB-ID 1 (LE), COB-ID 2 (LE), count, then sub + entry (LE).
    let mut bytes = vec![2, 50, 0, 10];
    bytes.extend_from_slice(&(NORMAL as u32).to_le_bytes());
    bytes.extend_from_slice(&(INVERTED as u32).to_le_bytes());
    bytes.push(4);
    for (k, raw) in [0x6000_0010u32, 0x6010_0010, 0x6001_0008, 0x6011_0008]
        .iter()
        .enumerate()
    {
        bytes.push(k as u8 + 1);
        bytes.extend_from_slice(&raw.to_le_bytes());
    }
    assert_eq!(signature(&p, &m), crc16_ccitt(0, &bytes));
    // The transmission type is not part of it; every other field is.
    let mut q = p;
    q.transmission_type = 1;
    assert_eq!(signature(&q, &m), signature(&p, &m));
    q = p;
    q.srvt_ms = 11;
    assert_ne!(signature(&q, &m), signature(&p, &m));
    assert_eq!(
        n.od().get_value::<u16>(config::CHECKSUMS, 1),
        Ok(signature(&p, &m))
    );
}

#[test]
fn default_identifiers_follow_the_node_id() {
    let id = |n| default_cob_ids(node_id(n));
    assert_eq!(id(1), Some((0x101, 0x102)));
    assert_eq!(id(2), Some((NORMAL, INVERTED)));
    assert_eq!(id(64), Some((0x17F, 0x180)));
    assert_eq!(id(65), None);
}

#[test]
fn a_valid_configuration_enters_operational() {
    let mut w = pair();
    assert!(w.nodes[CONSUMER].srdo_check().is_ok());
    start_all(&mut w);
    for n in &w.nodes {
        assert_eq!(n.nmt_state(), NmtState::Operational);
    }
}

fn refused(n: &mut crate::common::TestNode) -> SrdoConfigError {
    while n.poll_event().is_some() {}
    n.set_nmt_state(Instant::from_millis(1), NmtState::Operational);
    assert_eq!(
        n.nmt_state(),
        NmtState::PreOperational,
        "must stay out of operational"
    );
    let reason = std::iter::from_fn(|| n.poll_event())
        .find_map(|e| match e.kind {
            K::OperationalRefused { reason } => Some(reason),
            _ => None,
        })
        .expect("the refusal is reported");
    assert_eq!(n.srdo_check(), Err(reason));
    reason
}

fn booted_consumer() -> crate::common::TestNode {
    let mut n = bare(C_ID);
    configure(&mut n, false, SCT_MS, SRVT_MS, &mapping());
    n.boot(Instant::ZERO);
    n
}

#[test]
fn any_write_to_the_parameters_voids_the_valid_mark() {
    for (index, sub) in [
        (config::COMM, 3),
        (config::MAPPING, 1),
        (config::CHECKSUMS, 1),
    ] {
        let mut n = booted_consumer();
        let old = n.od().read(index, sub).unwrap().to_vec();
        // Even the same value written again: the configuration must be checked again.
        n.write(Instant::ZERO, index, sub, &old).unwrap();
        assert_eq!(n.od().get_value::<u8>(config::CONFIG_VALID, 0), Ok(0));
        let r = refused(&mut n);
        assert_eq!(
            (r.index, r.problem),
            (config::CONFIG_VALID, SrdoProblem::NotValid(0))
        );
        assert!(r.to_string().contains("0x13FE = 0x00"), "{r}");
    }
}

#[test]
fn a_checksum_that_does_not_match_is_refused_with_both_values() {
    let mut n = booted_consumer();
    let good: u16 = n.od().get_value(config::CHECKSUMS, 1).unwrap();
    n.set(Instant::ZERO, config::CHECKSUMS, 1, good ^ 0x0100)
        .unwrap();
    n.set(Instant::ZERO, config::CONFIG_VALID, 0, config::VALID)
        .unwrap();
    let r = refused(&mut n);
    assert_eq!((r.srdo, r.index, r.sub), (1, config::CHECKSUMS, 1));
    let problem = SrdoProblem::Checksum {
        stored: good ^ 0x0100,
        computed: good,
    };
    assert_eq!(r.problem, problem);
}

/// Each parameter rule: the value written (then sealed with a matching checksum, so only the
/// rule can refuse it), and where the refusal points.
#[test]
fn parameters_out_of_range_are_refused_where_they_are() {
    let cases: [(u16, u8, u32, SrdoProblem); 7] = [
        (config::COMM, 2, 0, SrdoProblem::CycleTime),
        (config::COMM, 3, 0, SrdoProblem::ValidationTime),
        (config::COMM, 4, 1, SrdoProblem::TransmissionType),
        (config::COMM, 5, 0x104, SrdoProblem::CobId),
        (config::COMM, 6, 0x105, SrdoProblem::CobId),
        (config::COMM, 5, 0x181, SrdoProblem::CobId),
        (config::MAPPING, 2, 0x6010_0008, SrdoProblem::Length),
    ];
    for (index, sub, value, problem) in cases {
        let mut n = booted_consumer();
        let size = n.od().read(index, sub).unwrap().len();
        n.write(Instant::ZERO, index, sub, &value.to_le_bytes()[..size])
            .unwrap();
        seal(&mut n);
        let r = refused(&mut n);
        let at = if problem == SrdoProblem::Length {
            (config::MAPPING, 0)
        } else {
            (index, sub)
        };
        assert_eq!(
            (r.index, r.sub, r.problem),
            (at.0, at.1, problem),
            "{index:04X}sub{sub}"
        );
    }
}

#[test]
fn a_mapping_the_dictionary_cannot_serve_is_refused_with_its_abort_code() {
    // An object that does not exist, and one that is not mappable (0x1000).
    for (raw, code) in [
        (0x6500_0010u32, AbortCode::NO_OBJECT),
        (0x1000_0020, AbortCode::NOT_MAPPABLE),
    ] {
        let mut n = booted_consumer();
        n.set(Instant::ZERO, config::MAPPING, 1, raw).unwrap();
        seal(&mut n);
        let r = refused(&mut n);
        assert_eq!((r.sub, r.problem), (1, SrdoProblem::Mapping(code)));
    }
    // An odd count is refused at the count.
    let mut n = booted_consumer();
    n.set(Instant::ZERO, config::MAPPING, 0, 3u8).unwrap();
    seal_raw(&mut n);
    assert_eq!(refused(&mut n).problem, SrdoProblem::MappingCount);
}

/// Marks valid without recomputing (the checksum cannot be computed over an unreadable
/// configuration).
fn seal_raw(n: &mut crate::common::TestNode) {
    n.set(Instant::ZERO, config::CONFIG_VALID, 0, config::VALID)
        .unwrap();
}

#[test]
fn the_configuration_is_locked_while_operational() {
    let mut w = pair();
    start_all(&mut w);
    let n = &mut w.nodes[CONSUMER];
    for (index, sub) in [
        (config::COMM, 2),
        (config::MAPPING, 0),
        (config::CONFIG_VALID, 0),
    ] {
        let data = n.od().read(index, sub).unwrap().to_vec();
        assert_eq!(
            n.write(ms(5), index, sub, &data),
            Err(AbortCode::DEVICE_STATE)
        );
    }
    assert_eq!(
        n.od().get_value::<u8>(config::CONFIG_VALID, 0),
        Ok(config::VALID)
    );
}

#[test]
fn a_node_without_srdo_in_use_is_not_held_back() {
    // The objects exist, nothing is configured, 0x13FE is 0: no SRDO, no reason to refuse.
    let mut n = bare(C_ID);
    n.boot(Instant::ZERO);
    n.set_nmt_state(ms(1), NmtState::Operational);
    assert_eq!(n.nmt_state(), NmtState::Operational);
}

#[test]
fn a_self_starting_node_with_a_bad_configuration_stays_preoperational() {
    let cfg = duocan::NodeConfig::slave(node_id(C_ID)).with_auto_start(true);
    let od = duocan::od::comm::standard_dictionary(C_ID, Default::default());
    let mut n = with_config(duocan::Node::new(cfg, od));
    configure(&mut n, false, SCT_MS, SRVT_MS, &mapping());
    n.set(Instant::ZERO, config::COMM, 3, 9u8).unwrap(); // voids 0x13FE
    n.boot(Instant::ZERO);
    assert_eq!(n.nmt_state(), NmtState::PreOperational);
    let refusal = std::iter::from_fn(|| n.poll_event())
        .any(|e| matches!(e.kind, K::OperationalRefused { .. }));
    assert!(refusal);
}

#[test]
fn marking_valid_checks_first_and_writes_nothing_on_a_bad_configuration() {
    let mut n = bare(C_ID);
    let cfg = config::SrdoConfig::new(false, 0, SRVT_MS, NORMAL, mapping());
    n.configure_srdo(Instant::ZERO, 1, &cfg).unwrap();
    let e = n.srdo_mark_valid(Instant::ZERO).unwrap_err();
    let want = duocan::node::SrdoMarkError::Config(SrdoConfigError {
        srdo: 1,
        index: config::COMM,
        sub: 2,
        problem: SrdoProblem::CycleTime,
    });
    assert_eq!(e, want);
    assert!(e.to_string().contains("refresh time / SCT is 0"), "{e}");
    assert_eq!(n.od().get_value::<u8>(config::CONFIG_VALID, 0), Ok(0));
    // The writes a tool would make over SDO, in order, end with the checksum.
    let cfg = config::SrdoConfig::new(false, SCT_MS, SRVT_MS, NORMAL, mapping());
    let w: Vec<_> = config::writes(1, &cfg).collect();
    assert_eq!(w.len(), 6 + 1 + 4 + 1 + 1);
    let last = w.last().unwrap();
    assert_eq!((last.index, last.sub), (config::CHECKSUMS, 1));
    assert_eq!(
        last.data(),
        signature(&cfg.params, &cfg.mapping).to_le_bytes()
    );
}

/// Every frame the node has to send now, up to the first non-EMCY one.
fn emcys(n: &mut crate::common::TestNode) -> Vec<duocan::Frame> {
    std::iter::from_fn(|| n.poll_transmit())
        .filter(|f| f.id() == duocan::Id::Standard(0x80 + u16::from(C_ID)))
        .collect()
}

#[test]
fn the_refusal_is_an_emcy_naming_the_object_and_entering_operational_clears_it() {
    let mut n = booted_consumer();
    let _ = emcys(&mut n);
    let good: u16 = n.od().get_value(config::CHECKSUMS, 1).unwrap();
    n.set(Instant::ZERO, config::CHECKSUMS, 1, good ^ 0x0100)
        .unwrap();
    n.set(Instant::ZERO, config::CONFIG_VALID, 0, config::VALID)
        .unwrap();
    refused(&mut n);
    // 0x6300 data set error, register generic; SRDO 1, 0x13FF sub 1, problem 11 (checksum).
    let e = emcys(&mut n);
    assert_eq!(e.len(), 1, "{e:?}");
    assert_eq!(e[0].data(), [0x00, 0x63, 0x01, 1, 0xFF, 0x13, 1, 11]);
    assert_eq!(n.od().get_value::<u8>(0x1001, 0), Ok(0x01));
    // Asked again: refused again, no second EMCY for the same error.
    refused(&mut n);
    assert!(emcys(&mut n).is_empty());
    // The right checksum: operational, and the error is reset on the bus.
    n.set(Instant::ZERO, config::CHECKSUMS, 1, good).unwrap();
    n.set(Instant::ZERO, config::CONFIG_VALID, 0, config::VALID)
        .unwrap();
    n.set_nmt_state(Instant::from_millis(2), NmtState::Operational);
    assert_eq!(n.nmt_state(), NmtState::Operational);
    let e = emcys(&mut n);
    assert_eq!(e.len(), 1, "{e:?}");
    assert_eq!(e[0].data(), [0, 0, 0, 0, 0, 0, 0, 0]);
    assert_eq!(n.od().get_value::<u8>(0x1001, 0), Ok(0));
}
