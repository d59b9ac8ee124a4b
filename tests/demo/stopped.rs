//! The demo's board that stops by itself (`examples/demo`, [`crate::scenario::stopped`]): at
//! 9.69 s the application of T9's active board A on the track-circuit rack puts it in
//! pre-operational, 10 ms before a train enters T9; it goes on beating. Exact simulated times
//! from the wire: the weak master (active since the strong one lost power) switches the pair to
//! B at the end of A's first heartbeat saying pre-operational, B's NMT start is on the wire
//! within a millisecond of it, A is reset, boots and rejoins as standby; B reports the train
//! and the weak master gets it once.

use crate::scenario::analysis::Outcome;
use crate::scenario::board::BoardEvent;
use crate::scenario::interlocking::IlEvent;
use crate::scenario::station::{board_node, WEAK};
use crate::scenario::stopped::{Stopped, START_BOUND};
use crate::scenario::{Station, STOPPED_PAIR, TRACK};
use duocan::profile::railway::safety::TrackCircuit;
use duocan::sim::{TraceRecord, TxOutcome, TxRecord};
use duocan::{Instant, NmtCommand, NmtState};
use duocan_redundancy::supervisor::pairs::{LossReason, RoleReason};
use duocan_redundancy::Member;

/// The day's stop, asserted (called from the day's test: one run of the station).
pub fn the_board_that_stops_by_itself_is_replaced_at_its_heartbeat(st: &Station, o: &Outcome) {
    let ms = Instant::from_millis;
    let pre = NmtState::PreOperational;
    assert_eq!(o.stops.len(), 1);
    let s = &o.stops[0];
    assert_eq!(
        (s.rack, s.pair, s.label.as_str(), s.member, s.state, s.at),
        (
            "track-circuit rack",
            STOPPED_PAIR,
            "T9",
            Member::A,
            pre,
            ms(9_690)
        )
    );
    assert_eq!(s.master, Some(WEAK));
    let track = &st.racks[TRACK];
    let [bus1, _] = track.buses();
    let (a, b) = (
        board_node(STOPPED_PAIR, Member::A),
        board_node(STOPPED_PAIR, Member::B),
    );
    let on_bus1: Vec<&TxRecord> = st
        .sim
        .trace()
        .iter()
        .filter_map(|r| match r {
            TraceRecord::Tx(x)
                if x.bus == bus1 && matches!(x.outcome, TxOutcome::Delivered { .. }) =>
            {
                Some(x)
            }
            _ => None,
        })
        .collect();

    // A announces its state at once: its first heartbeat saying pre-operational, within a
    // millisecond of the stop.
    let a_dev = track.board_dev(STOPPED_PAIR, Member::A);
    let hb = track.heartbeat_id(a);
    let v = on_bus1
        .iter()
        .find(|x| x.end > s.at && x.sender.device == a_dev && x.frame.id() == hb)
        .unwrap();
    assert_eq!(v.frame.data(), [pre.code()]);
    let v = v.end;
    assert_eq!(s.shown, Some(v));
    assert!(v - s.at < START_BOUND, "{v}");
    // The pair switches to B at exactly that heartbeat, and A is lost then, as not operational.
    let role = s.role.unwrap();
    assert_eq!(
        (role.at, role.from, role.to, role.reason),
        (
            v,
            Some(Member::A),
            Some(Member::B),
            RoleReason::ActiveNotOperational { state: pre }
        )
    );
    assert_eq!(s.lost, Some((v, LossReason::NotOperational { state: pre })));
    // On the wire: the weak master starts B within a millisecond of the heartbeat, then resets
    // A; no other NMT command on the rack until the end of the day.
    let weak = track.master_dev(WEAK);
    let nmt: Vec<(Instant, &[u8])> = on_bus1
        .iter()
        .filter(|x| x.end > s.at && x.frame.id() == track.nmt_id())
        .inspect(|x| assert_eq!(x.sender.device, weak))
        .map(|x| (x.end, x.frame.data()))
        .collect();
    assert_eq!(nmt.len(), 2, "{nmt:?}");
    assert_eq!(nmt[0].1, [NmtCommand::Start.code(), b.raw()]);
    assert_eq!(nmt[1].1, [NmtCommand::ResetNode.code(), a.raw()]);
    let (start, reset) = (nmt[0].0, nmt[1].0);
    assert!(start > v && start - v <= START_BOUND, "{start} vs {v}");
    assert_eq!((s.started, s.reset), (Some(start), Some(reset)));
    // A boots (its boot-up right after the reset), is configured and rejoins as standby; the
    // pair stays on B.
    let boot = on_bus1
        .iter()
        .find(|x| x.end > reset && x.sender.device == a_dev && x.frame.id() == hb)
        .unwrap();
    assert_eq!(boot.frame.data(), [0]);
    assert_eq!(s.booted, Some(boot.end));
    let joined = s.rejoined.unwrap();
    assert!(joined > boot.end, "{joined}");
    assert_eq!(s.end, (vec![Member::B], Some(Member::B), pre));
    let audit = s.audit.as_deref().unwrap();
    assert!(
        audit.contains(
            "active A -> B: active member pre-operational without a command of this master"
        ),
        "{audit}"
    );

    // The train enters T9 at 9.7 s: B, running since its start, reports it then, and the weak
    // master gets it once; nothing of the rack lost or doubled.
    let seq = track
        .board_events(&st.sim, STOPPED_PAIR, Member::B)
        .into_iter()
        .find_map(|(at, e)| match e {
            BoardEvent::Reported { seq, code } if code == TrackCircuit::Occupied as u8 => {
                assert_eq!(at, ms(9_700));
                Some(seq)
            }
            _ => None,
        })
        .unwrap();
    let got = track
        .master_events(&st.sim, WEAK)
        .iter()
        .filter(
            |(_, e)| matches!(e, IlEvent::Report { from, seq: n, .. } if *from == b && *n == seq),
        )
        .count();
    assert_eq!(got, 1);
    let t = s.traffic;
    assert!(t.reports >= 2 && t.delivered == t.reports, "{t:?}");
    assert_eq!((t.lost_total(), t.duplicates_total(), t.wrong), (0, 0, 0));
    assert!(s.held(), "{s:#?}");
    let listed: Vec<_> = o
        .failovers
        .iter()
        .filter(|f| f.what.contains("T9: board B started after A's heartbeat"))
        .collect();
    assert_eq!(listed.len(), 1);
    assert_eq!((listed[0].from, listed[0].at), (v, start));

    // The demo's self-check fails when any of it is not so.
    let broken = |f: fn(&mut Stopped)| {
        let mut x = s.clone();
        f(&mut x);
        x.held()
    };
    assert!(!broken(|x| x.started = x.started.map(|t| t + START_BOUND)));
    assert!(!broken(|x| x.role.as_mut().unwrap().at = x.at));
    assert!(!broken(
        |x| x.role.as_mut().unwrap().reason = RoleReason::Manual
    ));
    assert!(!broken(|x| x.lost = None));
    assert!(!broken(|x| x.audit = None));
    assert!(!broken(|x| x.rejoined = None));
    assert!(!broken(|x| x.end.0 = vec![Member::A, Member::B]));
    assert!(!broken(|x| x.end.1 = Some(Member::A)));
    assert!(!broken(|x| x.traffic.lost += 1));
}

/// The analysis sees a stop that goes wrong: here the pair's standby is off, so nothing takes
/// over (called from the day's test with T9's B powered off before the stop, `run.rs`).
pub fn a_stop_with_no_standby_fails(o: &Outcome) {
    let s = &o.stops[0];
    assert_eq!(s.started, None);
    assert!(!s.held());
}
