//! The demo's board replacement by LSS (`examples/demo`, [`crate::scenario::replacement`]):
//! the dead P2 board's slot is filled by a spare without node-ID; the active master finds it,
//! gives it node 0x12, and it boots and joins as standby. The exact simulated times of each
//! step, the node-ID, the audit record, the LSS frames against the protocol's prediction, and
//! that only the active master ever sent an LSS request.

use crate::scenario::analysis::Outcome;
use crate::scenario::replacement::Replacement;
use crate::scenario::station::{STRONG, WEAK};
use crate::scenario::{Act, Station, KILLED_PAIR, SPARE_SERIAL, TURNOUT};
use duocan::cia305::codec::{MASTER_TO_SLAVE, SLAVE_TO_MASTER};
use duocan::cia305::LssAddress;
use duocan::sim::{TraceRecord, TxOutcome};
use duocan::{Duration, Instant, NmtState, NodeId};
use duocan_redundancy::{Member, PairId};
use std::collections::BTreeMap;

/// The day's replacement, asserted (called from the day's test: one run of the station).
pub fn the_spare_is_given_its_node_id_by_lss_and_joins_as_standby(st: &Station, o: &Outcome) {
    let us = Instant::from_micros;
    assert_eq!(o.replacements.len(), 1);
    let r = &o.replacements[0];
    assert_eq!(
        (r.rack, r.pair, r.member, r.master),
        ("turnout rack", KILLED_PAIR, Member::A, WEAK)
    );
    assert_eq!(r.plugged, Instant::from_millis(11_300));
    let spare = LssAddress {
        vendor: 0xD0CA,
        product: 0x10,
        revision: 1,
        serial: SPARE_SERIAL,
    };
    let b = r.addressed.expect("the spare was addressed");
    assert_eq!(
        (b.pair, b.member, b.node, b.address),
        (
            PairId(KILLED_PAIR as u8),
            Member::A,
            NodeId::must(0x12),
            spare
        )
    );
    // The times, exact: the look on the LSS period's grid after the power-on, its answer ending
    // at the look's timeout (50 ms), the fastscan, the boot-up, the identity read, the join.
    assert_eq!(r.heard, Some(us(11_550_000)));
    assert_eq!(b.at, us(12_506_790));
    assert_eq!(r.booted, Some(us(12_507_154)));
    assert_eq!(r.identity_read, Some(us(12_508_126)));
    assert_eq!(r.joined, Some(us(12_510_516)));
    assert_eq!(r.scan_end, Some(us(12_556_790)));
    // The protocol's prediction for this identity: 136 requests, 121 answers, 14 timeouts of
    // 50 ms and 120 settle times of 2 ms; the scan took that plus its frames' time on the wire
    // (at most 270 µs each at 500 kbit/s), and each bus carried exactly those frames plus the
    // look's request and answer.
    let p = r.predicted;
    assert_eq!(
        (p.requests, p.answers, p.unanswered, p.answered, p.waiting),
        (136, 121, 14, 120, Duration::from_millis(940))
    );
    let scan = r.scan_end.unwrap() - r.heard.unwrap();
    assert_eq!(scan, Duration::from_micros(1_006_790));
    let frames = u64::from(p.requests + p.answers);
    assert!(scan >= p.waiting && scan <= p.waiting + Duration::from_micros(270 * frames));
    assert_eq!(r.lss_frames as u64, frames + 2);
    // The audit trail of the master that did it says so.
    let audit = r.audit.as_deref().unwrap();
    assert!(
        audit.contains("pair 1 member A")
            && audit.contains("serial 0x00026001")
            && audit.contains("given node 0x12 by LSS"),
        "{audit}"
    );
    // Standby at the end, with node 0x12, its own serial, configured from the DCF; its partner
    // B stays active.
    assert_eq!(r.end, (Some(NodeId::must(0x12)), NmtState::PreOperational));
    assert_eq!(r.active, Some(Member::B));
    let turnout = &st.racks[TURNOUT];
    let value = |i, s| turnout.board_value(&st.sim, KILLED_PAIR, Member::A, i, s);
    assert_eq!(value(0x1018, 4), Some(SPARE_SERIAL));
    assert_eq!((value(0x1017, 0), value(0x1015, 0)), (Some(20), Some(100)));
    assert!(r.held(), "{r:#?}");
    // The demo's self-check fails when any of it is not so.
    let broken = |f: fn(&mut Replacement)| {
        let mut x = r.clone();
        f(&mut x);
        x.held()
    };
    assert!(!broken(|x| x.end.1 = NmtState::Operational));
    assert!(!broken(|x| x.active = Some(Member::A)));
    assert!(!broken(|x| x.lss_frames += 1));
    assert!(!broken(|x| x.audit = None));
    assert!(!broken(|x| x.joined = None));
    assert!(!broken(
        |x| x.addressed.as_mut().unwrap().node = NodeId::must(0x22)
    ));
    assert!(o
        .lines
        .iter()
        .any(|l| l.at == b.at && l.text.contains("gave it P2's slot A: node 0x12")));

    only_the_active_master_sends_lss(st);
}

/// Every LSS request of the day is from the turnout rack's active master: the strong one while
/// the dead board's slot was vacant before it lost power, then the weak one; none from the
/// strong master once it is back as standby, none on the other racks. By command specifier:
/// the looks (identify non-configured, 0x4C) every 250 ms while the slot was vacant, then the
/// fastscan (0x51), the configure node-ID (0x11) and the switch back to waiting (0x04).
fn only_the_active_master_sends_lss(st: &Station) {
    let turnout = &st.racks[TURNOUT];
    let [bus1, _] = turnout.buses();
    let killed = st
        .happened
        .iter()
        .find(|h| matches!(h.act, Act::BoardKilled { .. }));
    let strong_off = st
        .happened
        .iter()
        .find(|h| h.act == Act::MasterKilled(STRONG));
    let (killed, strong_off) = (killed.unwrap().at, strong_off.unwrap().at);
    let mut sent: [BTreeMap<u8, usize>; 2] = Default::default();
    for rec in st.sim.trace() {
        let TraceRecord::Tx(x) = rec else { continue };
        if !matches!(x.outcome, TxOutcome::Delivered { .. }) {
            continue;
        }
        let id = x.frame.id();
        if id != MASTER_TO_SLAVE && id != SLAVE_TO_MASTER {
            continue;
        }
        assert!(
            turnout.buses().contains(&x.bus),
            "LSS on {}",
            st.sim.bus_name(x.bus)
        );
        if id != MASTER_TO_SLAVE || x.bus != bus1 {
            continue;
        }
        let from = x.sender.device;
        let w = if from == turnout.master_dev(STRONG) {
            assert!(x.end > killed && x.end < strong_off, "{}", x.end);
            STRONG
        } else {
            assert_eq!(from, turnout.master_dev(WEAK), "{}", x.end);
            assert!(x.end > strong_off, "{}", x.end);
            WEAK
        };
        *sent[w].entry(x.frame.data()[0]).or_default() += 1;
    }
    // The strong master looked at 7.25 … 8.25 s; the weak one at 8.5 … 11.5 s, the last look
    // answered by the spare; then one fastscan: 128 bit steps, 4 confirmations, the first and
    // the last reset.
    assert_eq!(sent[STRONG], BTreeMap::from([(0x4C, 5)]));
    assert_eq!(
        sent[WEAK],
        BTreeMap::from([(0x04, 1), (0x11, 1), (0x4C, 13), (0x51, 134)])
    );
}
