//! The demo's scenario (`examples/demo`) run as a test: the numbers the demo prints are
//! computed from the run, and here they are asserted: no application message lost or doubled,
//! every failover within its bound, one active master per rack and one running board per pair
//! at the end; the spare that replaces the dead board is given its slot's node-ID by LSS and
//! joins as standby (`replacement.rs`, exact times); the turnout rack's buses are handed over
//! without a frame lost, a role change or a switch-over (`handover.rs`, exact times); the board
//! that stops by itself is replaced at the heartbeat that shows it (`stopped.rs`, exact times);
//! the SVG parses and has what it claims; the candump log and the pcap files read
//! back as the frames of the run. A run with both buses of a rack cut and a pair's standby off
//! shows that the analysis does count losses and fails the hand-over's and the stop's verdicts.

use crate::scenario::analysis::Analysis;
use crate::scenario::{Act, CONSUMER, MASTER_TIMEOUT, SCRIPT, STOPPED_PAIR};
use duocan::capture::candump;
use duocan::capture::pcap::PcapReader;
use duocan::sim::{TraceRecord, TxOutcome};
use duocan::{Duration, Instant};
use duocan_redundancy::Member;
use std::collections::HashMap;

/// The stations' devices are large bounded tables; debug builds copy them around while
/// building: more than a test thread's default stack.
fn big_stack(f: impl FnOnce() + Send + 'static) {
    std::thread::Builder::new()
        .stack_size(256 << 20)
        .spawn(f)
        .unwrap()
        .join()
        .unwrap();
}

#[test]
fn the_demo_day_loses_nothing_and_keeps_every_bound() {
    big_stack(day);
}

fn day() {
    let st = crate::scenario::run().unwrap();
    assert_eq!(
        st.happened.len(),
        SCRIPT.len(),
        "every act of the script ran"
    );
    for h in &st.happened {
        if matches!(h.act, Act::BoardKilled { .. } | Act::BoardReplaced { .. }) {
            assert_eq!(
                h.member,
                Some(Member::A),
                "the active board of P2 was A: {h:?}"
            );
        }
    }
    let a = Analysis::new(&st);
    let o = a.outcome();
    crate::replacement::the_spare_is_given_its_node_id_by_lss_and_joins_as_standby(&st, &o);
    crate::handover::the_turnout_buses_are_handed_over_without_loss(&st, &o);
    crate::stopped::the_board_that_stops_by_itself_is_replaced_at_its_heartbeat(&st, &o);
    assert!(
        o.verdicts(&st).iter().all(|v| v.1),
        "{:#?}",
        o.verdicts(&st)
    );

    // Application messages end to end: everything executed once, answered, delivered once.
    let t = o.total();
    println!("{:#?}", o.traffic);
    assert_eq!(t.commands, 90);
    assert_eq!(t.executed_once, t.commands);
    assert_eq!(t.answered, t.commands);
    assert_eq!(t.delivered, t.reports);
    assert!(t.reports > 200, "{} state changes", t.reports);
    assert_eq!(
        (t.lost_total(), t.duplicates_total(), t.wrong, t.rejected),
        (0, 0, 0, 0)
    );
    // Commands met the failures: P2's command went to the dead A, then to B.
    assert!(t.resends >= 1, "{t:?}");
    let turnout = &o.traffic[crate::scenario::TURNOUT].1;
    assert!(turnout.resends >= 1);

    // Every measured reaction within its bound, and each expected one measured.
    for f in &o.failovers {
        assert!(f.within(), "{f:?} took {}", f.took());
    }
    let find = |what: &str| -> Vec<&crate::scenario::analysis::Failover> {
        o.failovers
            .iter()
            .filter(|f| f.what.contains(what))
            .collect()
    };
    let pair = find("P2: board B started");
    assert_eq!(pair.len(), 1);
    // Exactly the consumer time after the last heartbeat, plus the NMT frame on the wire.
    assert!(pair[0].took() > CONSUMER && pair[0].took() <= CONSUMER + Duration::from_millis(1));
    let takeovers = find("weak master active after the strong");
    assert_eq!(takeovers.len(), 4, "one per rack");
    for f in takeovers {
        assert!(
            f.took() >= MASTER_TIMEOUT && f.took() <= MASTER_TIMEOUT + Duration::from_millis(1)
        );
    }
    assert_eq!(find("SYNC gap over the takeover").len(), 4);
    // The signal rack's bus 1 cut, and the turnout rack's buses handed over: bus 2, then bus 1.
    assert_eq!(find("bus 1 failed").len(), 4);
    assert_eq!(find("bus 2 failed").len(), 2);
    assert_eq!(find("bus 2 in use again").len(), 2);
    assert_eq!(find("SYNC gap over the hand-over").len(), 1);
    assert_eq!(
        find("T9: board B started after A's heartbeat saying").len(),
        1
    );
    assert_eq!(find("strong master active after the weak").len(), 1);
    assert_eq!(find("stepped down after the heal").len(), 1);

    // The end: one active master per rack, one running board per pair, the one the table names;
    // P2 stays on B (non-revertive), the misc rack on the strong master (it won the conflict).
    for e in &o.ends {
        assert_eq!(e.active.len(), 1, "{}: {:?}", e.name, e.active);
        for p in &e.pairs {
            assert_eq!(p.running.len(), 1, "{} {}", e.name, p.label);
            assert_eq!(p.table, Some(p.running[0]), "{} {}", e.name, p.label);
        }
        assert_eq!(e.unanswered, 0, "{}", e.name);
        assert!(
            e.status.contains("bus 1 ok") && e.status.contains("bus 2 ok"),
            "{}",
            e.status
        );
    }
    // Every board holds what its rack's DCF configures (0x1015 100, 0x1017 20): the masters
    // wrote it.
    assert_eq!(crate::scenario::devices::configured(&st), (72, 72));
    let turnout = &st.racks[crate::scenario::TURNOUT];
    assert_eq!(
        turnout.board_value(&st.sim, 3, Member::B, 0x1015, 0),
        Some(100)
    );
    assert_eq!(
        turnout.board_value(&st.sim, 3, Member::B, 0x1017, 0),
        Some(20)
    );
    assert_eq!(
        o.ends[crate::scenario::TURNOUT].pairs[crate::scenario::KILLED_PAIR].running,
        [Member::B]
    );
    assert_eq!(
        o.ends[crate::scenario::MISC].active,
        [crate::scenario::station::STRONG]
    );
    assert_eq!(
        o.ends[crate::scenario::TURNOUT].active,
        [crate::scenario::station::WEAK]
    );

    // The files.
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("demo");
    let chart = a.chart();
    let paths = crate::scenario::outputs::write_all(&st, &chart, &dir).unwrap();

    // SVG: parses; four networks, each with bus 1/bus 2, a lane per pair, both masters, and its
    // faults; the cut bus shows a failed span, the split buses a suspect one.
    let text = std::fs::read_to_string(&paths.svg).unwrap();
    let doc = roxmltree::Document::parse(&text).expect("valid XML");
    let class = |n: &roxmltree::Node, c: &str| {
        n.attribute("class")
            .is_some_and(|v| v.split_whitespace().any(|x| x == c))
    };
    let networks: Vec<_> = doc.descendants().filter(|n| class(n, "network")).collect();
    assert_eq!(networks.len(), 4);
    let mut faults = 0;
    for (net, (rack, pairs)) in networks
        .iter()
        .zip(st.racks.iter().zip(crate::scenario::PAIRS))
    {
        assert!(net.attribute("data-name").unwrap().starts_with(rack.name()));
        let lanes: Vec<_> = net.descendants().filter(|n| class(n, "lane")).collect();
        assert_eq!(lanes.len(), 2 + pairs + 2, "{}", rack.name());
        let kinds = |k: &str| {
            lanes
                .iter()
                .filter(|l| l.attribute("data-kind") == Some(k))
                .count()
        };
        assert_eq!(
            (kinds("bus"), kinds("pair"), kinds("master")),
            (2, pairs, 2)
        );
        for l in &lanes {
            assert!(
                l.descendants().any(|n| class(&n, "span")),
                "spans in every lane"
            );
        }
        let master_spans: Vec<_> = lanes
            .iter()
            .filter(|l| l.attribute("data-kind") == Some("master"))
            .flat_map(|l| l.descendants().filter(|n| class(n, "state-active")))
            .collect();
        assert!(!master_spans.is_empty());
        faults += net.descendants().filter(|n| class(n, "fault")).count();
    }
    // Per rack: its own faults plus the strong master's loss and return.
    let own = SCRIPT
        .iter()
        .filter(|(_, a)| !matches!(a, Act::MasterKilled(_) | Act::MasterBack(_)))
        .count();
    assert_eq!(faults, own + 4 * 2);
    let bus_has = |rack: usize, bus: &str, state: &str| {
        networks[rack]
            .descendants()
            .filter(|n| class(n, "lane") && n.attribute("data-label") == Some(bus))
            .any(|l| l.descendants().any(|n| class(&n, state)))
    };
    let bus1_has = |rack: usize, state: &str| bus_has(rack, "bus 1", state);
    assert!(bus_has(crate::scenario::TURNOUT, "bus 2", "state-failed"));
    assert!(!bus_has(crate::scenario::SIGNAL, "bus 2", "state-failed"));
    assert!(bus1_has(crate::scenario::SIGNAL, "state-failed"));
    assert!(bus1_has(crate::scenario::TURNOUT, "state-failed"));
    assert!(bus1_has(crate::scenario::MISC, "state-suspect"));
    assert!(!bus1_has(crate::scenario::TRACK, "state-failed"));

    // The candump log holds every delivered frame of the run, and reads back as them.
    let delivered: Vec<_> = st
        .sim
        .trace()
        .iter()
        .filter_map(|r| match r {
            TraceRecord::Tx(x) if matches!(x.outcome, TxOutcome::Delivered { .. }) => Some(x),
            _ => None,
        })
        .collect();
    let entries: Vec<_> = candump::CandumpReader::open(&paths.candump)
        .unwrap()
        .map(|e| e.unwrap())
        .collect();
    assert_eq!(entries.len(), delivered.len());
    assert_eq!(entries.len() as u64, o.frames);
    for (e, x) in entries.iter().zip(&delivered) {
        assert_eq!(e.interface, st.sim.bus_name(x.bus));
        assert_eq!(e.record.frame(), Some(&x.frame));
        assert_eq!(
            e.timestamp_us,
            crate::scenario::outputs::EPOCH_US + x.end.as_micros()
        );
    }
    let per_bus: HashMap<&str, usize> = entries.iter().fold(HashMap::new(), |mut m, e| {
        *m.entry(e.interface.as_str()).or_default() += 1;
        m
    });
    assert_eq!(per_bus.len(), 8, "{per_bus:?}");

    // One pcap per bus of the CANopen racks, with that bus's frames.
    assert_eq!(paths.pcaps.len(), 4);
    for p in &paths.pcaps {
        let bus = p.file_stem().unwrap().to_str().unwrap();
        let mut r = PcapReader::new(std::fs::File::open(p).unwrap()).unwrap();
        let mut n = 0;
        while let Some(_packet) = r.next_packet().unwrap() {
            n += 1;
        }
        assert_eq!(n, per_bus[bus], "{bus}");
    }
    assert!(o.lines.iter().any(|l| l.at == Instant::from_millis(4_250)));
}

#[test]
fn a_rack_cut_off_on_both_buses_and_a_pair_without_standby_show_as_failures() {
    big_stack(|| {
        // Both turnout buses cut while P7 and P8 finish their throw (reports at 5.4 s), in the
        // middle of the scripted hand-over; T9's standby B off before its A stops by itself.
        let st = crate::scenario::run_with(|sim, racks| {
            let buses = racks[crate::scenario::TURNOUT].buses();
            sim.at(Instant::from_millis(5_390), move |sim| {
                buses.iter().for_each(|b| sim.bus_down(*b))
            });
            sim.at(Instant::from_millis(5_700), move |sim| {
                buses.iter().for_each(|b| sim.bus_up(*b))
            });
            let standby = racks[crate::scenario::TRACK].board_dev(STOPPED_PAIR, Member::B);
            sim.at(Instant::from_millis(9_000), move |sim| {
                sim.power_off(standby)
            });
        })
        .unwrap();
        let o = Analysis::new(&st).outcome();
        let turnout = &o.traffic[crate::scenario::TURNOUT].1;
        assert!(turnout.lost_total() > 0, "{turnout:?}");
        crate::handover::a_hand_over_with_both_buses_down_loses_frames(&o);
        crate::stopped::a_stop_with_no_standby_fails(&o);
        assert!(o.verdicts(&st).iter().any(|v| !v.1));
        // The other racks are untouched.
        assert_eq!(o.traffic[crate::scenario::SIGNAL].1.lost_total(), 0);
    });
}
