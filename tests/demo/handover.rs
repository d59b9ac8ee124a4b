//! The demo's bus hand-over (`examples/demo`, [`crate::scenario::handover`]): the turnout
//! rack's bus 2 is cut at 2.6 s and repaired at 4.6 s in the instant bus 1 is cut, and bus 1 is
//! repaired at 6.2 s. Exact simulated times from the wire: each computer uses bus 2 again at the
//! end of the first frame on it after the repair, trusts it a probation period later, and fails
//! bus 1 exactly the silence limit after the last frame it received on it. Nothing is lost or
//! doubled, the strong master stays the one active master, no pair switches over, SYNC keeps its
//! period.

use crate::scenario::analysis::Outcome;
use crate::scenario::handover::HandOver;
use crate::scenario::station::{STRONG, WEAK};
use crate::scenario::{Station, BOARD_HB, SILENCE_LIMIT, SYNC, TURNOUT};
use duocan::sim::{TraceRecord, TxOutcome, TxRecord};
use duocan::{Duration, Frame, Id, Instant};

const ONE_MS: Duration = Duration::from_millis(1);

fn sync() -> Frame {
    Frame::new(Id::Standard(0x80), &[]).unwrap()
}

/// The day's hand-over, asserted (called from the day's test: one run of the station).
pub fn the_turnout_buses_are_handed_over_without_loss(st: &Station, o: &Outcome) {
    let ms = Instant::from_millis;
    assert_eq!(o.hand_overs.len(), 1);
    let h = &o.hand_overs[0];
    assert_eq!(
        (h.rack, h.repaired, h.first_cut, h.swap, h.restored),
        ("turnout rack", 1, ms(2_600), ms(4_600), Some(ms(6_200)))
    );
    let turnout = &st.racks[TURNOUT];
    let [bus1, bus2] = turnout.buses();
    let delivered: Vec<&TxRecord> = st
        .sim
        .trace()
        .iter()
        .filter_map(|r| match r {
            TraceRecord::Tx(x) if matches!(x.outcome, TxOutcome::Delivered { .. }) => Some(x),
            _ => None,
        })
        .collect();

    // Bus 2 in use again at both computers at the end of the first frame on it after the
    // repair (received, or their own acknowledged), whatever the back-off of a port failed
    // for two seconds; ok a probation period (a guard period) of frames later.
    let first = delivered
        .iter()
        .find(|x| x.bus == bus2 && x.end > h.swap)
        .unwrap()
        .end;
    assert!(first - h.swap < ONE_MS, "{first}");
    assert_eq!(h.revived, [Some(first); 2]);
    for t in h.trusted {
        let t = t.unwrap();
        assert!(
            t >= first + BOARD_HB && t <= first + BOARD_HB + ONE_MS,
            "{t}"
        );
    }
    // Bus 1 failed at each computer exactly the silence limit after the last frame it received
    // on it before the cut.
    for w in [STRONG, WEAK] {
        let me = turnout.master_dev(w);
        let last = delivered
            .iter()
            .filter(|x| x.bus == bus1 && x.end <= h.swap && x.sender.device != me)
            .map(|x| x.end)
            .max()
            .unwrap();
        assert_eq!(h.failed[w], Some(last + SILENCE_LIMIT), "{w}");
    }

    // Nothing lost: no CAN frame (the wire of bus 1 was idle at the cut), no application
    // message; 8 commands (two points a second from 3 s to 6 s) executed once and answered,
    // every state change delivered once.
    assert_eq!(h.lost, []);
    let t = h.traffic;
    assert_eq!(
        (t.commands, t.executed_once, t.answered, t.wrong),
        (8, 8, 8, 0)
    );
    assert!(t.reports >= 8 && t.delivered == t.reports, "{t:?}");
    assert_eq!(
        (t.lost_total(), t.duplicates_total(), t.rejected),
        (0, 0, 0)
    );
    // The strong master the one active master throughout; no role change at either computer,
    // no pair switch-over, no board reset.
    assert_eq!(h.active, Some(STRONG));
    assert!(h.still_active);
    assert_eq!((h.master_changes, h.switch_overs, h.resets), (0, 0, 0));
    // SYNC on its period: no SYNC was lost, so no gap beyond one period and a frame's wait.
    assert!(
        h.sync_gap >= SYNC && h.sync_gap < SYNC + ONE_MS,
        "{}",
        h.sync_gap
    );
    assert!(h.held(), "{h:#?}");

    // The reactions are in the list the demo prints, each within its bound.
    let listed = |what: &str| o.failovers.iter().filter(|f| f.what.contains(what)).count();
    assert_eq!(listed("bus 2 in use again at the"), 2);
    assert!(o.lines.iter().any(|l| l.at == h.swap
        && l.depth == 0
        && l.text.contains("repairs bus 2 and cuts bus 1")));

    // The demo's self-check fails when any of it is not so.
    let broken = |f: fn(&mut HandOver)| {
        let mut x = h.clone();
        f(&mut x);
        x.held()
    };
    assert!(!broken(
        |x| x.revived[WEAK] = x.revived[WEAK].map(|t| t + BOARD_HB)
    ));
    assert!(!broken(|x| x.failed[STRONG] = None));
    assert!(!broken(|x| x.lost.push((x.swap, String::new(), sync()))));
    assert!(!broken(|x| x.master_changes = 1));
    assert!(!broken(|x| x.still_active = false));
    assert!(!broken(|x| x.switch_overs = 1));
    assert!(!broken(|x| x.resets = 1));
    assert!(!broken(|x| x.traffic.lost += 1));
    assert!(!broken(|x| x.traffic.duplicates += 1));
    assert!(!broken(|x| x.sync_gap = HandOver::SYNC_BOUND + ONE_MS));
}

/// The analysis sees a hand-over that goes wrong: here both turnout buses are down for a while
/// after the swap (called from the day's test with both buses cut, `run.rs`).
pub fn a_hand_over_with_both_buses_down_loses_frames(o: &Outcome) {
    let h = &o.hand_overs[0];
    assert!(!h.lost.is_empty());
    assert!(h.traffic.lost_total() > 0, "{:?}", h.traffic);
    assert!(!h.held());
}
