//! The clock contract in the channel policies (CiA 302-6, ECSS bus toggle), and every mode at
//! the end of time and back. Driven sans-IO as in [`super::clock`].

use super::clock::{d, heartbeat, lagging, ms, tpdo, traffic, Rig, HOUR};
use duocan::machine::{BusLink, LinkRequest, PortStatus};
use duocan::{Duration, Instant, NodeId};
use duocan_redundancy::{
    Cia3026Config, DualBusConfig, EcssConfig, LinkEventKind, LinkMode, Member, PortReason,
    PortState, SwitchReason,
};

fn cia302_6(cfg: Cia3026Config) -> Rig {
    Rig::new(DualBusConfig::default().with_mode(LinkMode::Cia302_6(cfg)))
}

#[test]
fn the_cia302_6_evaluation_window_keeps_its_time_after_a_step_back() {
    // Power-on evaluation over 1 s from the node's boot-up an hour into the clock.
    let mut r = cia302_6(Cia3026Config::default());
    let t0 = Instant::ZERO + HOUR;
    r.send(t0, heartbeat(5, 0));
    // Producer 0x10 beats twice on the default channel, then the clock steps back an hour.
    for t in [100, 200] {
        for p in 0..2 {
            r.rx(
                t0 + d(t) + Duration::from_micros(p * 100),
                p as usize,
                heartbeat(0x10, 5),
            );
        }
    }
    r.step(t0 + d(500), ms(500));
    r.run(ms(2000));
    let switches = r.kinds_where(|k| matches!(k, LinkEventKind::Channel { .. }));
    assert_eq!(
        switches,
        [(
            ms(1000),
            LinkEventKind::Channel {
                from: 0,
                to: 1,
                reason: SwitchReason::PowerOnEvaluation {
                    node: NodeId::must(0x10),
                    count: 2
                }
            }
        )],
        "the window ends 1 s after the boot-up, in the new time line"
    );
}

#[test]
fn the_cia302_6_transmit_delay_keeps_its_time_after_a_step_back() {
    // A frame without an outcome 5 ms after its hand-over counts as failed; one failure
    // reaches the threshold.
    let cfg = Cia3026Config::default()
        .with_max_tx_delay(d(5))
        .with_error_threshold(4)
        .with_eval_power_on(Duration::ZERO);
    let mut r = cia302_6(cfg);
    let t0 = Instant::ZERO + HOUR;
    r.send(t0, heartbeat(5, 0));
    r.status(t0 + d(1), 0, PortStatus::TxOk);
    r.send(t0 + d(10), tpdo(5, 1));
    r.step(t0 + d(12), ms(12));
    r.run(ms(100));
    assert_eq!(
        r.kinds(),
        [
            (ms(15), LinkEventKind::DefaultDisabled { counter: 4 }),
            (
                ms(15),
                LinkEventKind::Channel {
                    from: 0,
                    to: 1,
                    reason: SwitchReason::TxErrors { counter: 4 }
                }
            ),
        ]
    );
}

#[test]
fn the_ecss_toggle_keeps_its_timing_after_a_step_back() {
    // A slave of master 1, whose heartbeat is expected every 50 ms; toggles every 2 periods, at
    // most 4 times.
    let cfg = DualBusConfig::default().with_mode(LinkMode::EcssToggle(EcssConfig::slave(
        NodeId::must(1),
        d(50),
    )));
    let mut r = Rig::new(cfg);
    let t0 = Instant::ZERO + HOUR;
    r.send(t0, heartbeat(5, 0));
    r.rx(t0 + d(40), 0, heartbeat(1, 5));
    r.step(t0 + d(60), ms(60));
    r.run(ms(1000));
    let toggle = |at, from, to, ctoggle| (ms(at), LinkEventKind::Toggle { from, to, ctoggle });
    assert_eq!(
        r.kinds(),
        [
            (
                ms(90),
                LinkEventKind::MasterLost {
                    master: NodeId::must(1),
                    bus: 0
                }
            ),
            toggle(140, 0, 1, 1),
            toggle(240, 1, 0, 2),
            toggle(340, 0, 1, 3),
            toggle(440, 1, 0, 4),
            // The fourth toggle is the last: "no master" comes with it.
            (ms(440), LinkEventKind::NoMaster { bus: 0, ctoggle: 4 }),
        ],
        "lost 50 ms after its last heartbeat at 40 ms in the new time line"
    );
    assert_eq!(r.machine.first(), Some(&LinkRequest::EnterPreOperational));
}

/// A slave of master 1 (heartbeat expected every 50 ms) toggling every 2 periods, 3 times: the
/// search ends on bus 2.
fn ecss_slave() -> Rig {
    let ecss = EcssConfig::slave(NodeId::must(1), d(50)).with_ntoggle(3);
    Rig::new(DualBusConfig::default().with_mode(LinkMode::EcssToggle(ecss)))
}

#[test]
fn an_ecss_search_keeps_its_instants_after_a_step_back_in_the_middle() {
    let mut r = ecss_slave();
    let t0 = Instant::ZERO + HOUR;
    r.send(t0, heartbeat(5, 0));
    r.rx(t0 + d(40), 0, heartbeat(1, 5));
    // Lost at 1 h + 90 ms, first toggle at 1 h + 140 ms; the clock steps back an hour at
    // 1 h + 200 ms, between the first and the second toggle (due at 1 h + 240 ms).
    r.step(t0 + d(200), ms(200));
    r.run(ms(10_000));
    let toggle = |at, from, to, ctoggle| (ms(at), LinkEventKind::Toggle { from, to, ctoggle });
    let lost = LinkEventKind::MasterLost {
        master: NodeId::must(1),
        bus: 0,
    };
    assert_eq!(
        r.kinds(),
        [
            // Reported before the step, at their instants in the old time line.
            (t0 + d(90), lost),
            (
                t0 + d(140),
                LinkEventKind::Toggle {
                    from: 0,
                    to: 1,
                    ctoggle: 1
                }
            ),
            // 40 ms after the step, as they were 40 ms after it in the old time line.
            toggle(240, 1, 0, 2),
            toggle(340, 0, 1, 3),
            (ms(340), LinkEventKind::NoMaster { bus: 1, ctoggle: 3 }),
        ]
    );
    let ecss = r.l.ecss().unwrap();
    assert_eq!((ecss.bdefault(), ecss.ctoggle()), (1, 3));
    // The dictionary is told: Ctoggle at each toggle, and with the last one Bdefault bus 2
    // (the layer writes sub 1 before sub 4).
    let status: Vec<_> = r
        .machine
        .iter()
        .filter_map(|m| match m {
            LinkRequest::SetStatus { sub, value, .. } => Some((*sub, *value)),
            _ => None,
        })
        .collect();
    assert_eq!(status, [(4, 1), (4, 2), (1, 1), (4, 3)]);
}

#[test]
fn a_jump_ahead_over_an_ecss_search_reports_each_step_once_at_its_instant() {
    let mut r = ecss_slave();
    r.send(ms(0), heartbeat(5, 0));
    r.rx(ms(40), 0, heartbeat(1, 5));
    // The driver sleeps through the whole search and wakes up a day later: one call.
    r.l.handle_timeout(ms(86_400_000));
    r.drain();
    assert_eq!(r.l.poll_timeout(), None, "nothing left due");
    let toggle = |at, from, to, ctoggle| (ms(at), LinkEventKind::Toggle { from, to, ctoggle });
    assert_eq!(
        r.kinds(),
        [
            (
                ms(90),
                LinkEventKind::MasterLost {
                    master: NodeId::must(1),
                    bus: 0
                }
            ),
            toggle(140, 0, 1, 1),
            toggle(240, 1, 0, 2),
            toggle(340, 0, 1, 3),
            (ms(340), LinkEventKind::NoMaster { bus: 1, ctoggle: 3 }),
        ]
    );
    // The master heard on bus 2 a day later ends it there.
    r.rx(ms(86_400_010), 1, heartbeat(1, 5));
    assert_eq!(
        r.kinds().last(),
        Some(&(
            ms(86_400_010),
            LinkEventKind::MasterFound {
                master: NodeId::must(1),
                bus: 1
            }
        ))
    );
}

/// Every mode with something held, taken to the end of time and back.
#[test]
fn at_the_end_of_time_nothing_stays_due_and_the_clock_comes_back() {
    let modes = [
        LinkMode::ActiveActive,
        LinkMode::Cia302_6(Cia3026Config::default().with_max_tx_delay(d(5))),
        LinkMode::EcssToggle(EcssConfig::slave(NodeId::must(1), d(50))),
    ];
    for mode in modes {
        let mut r = Rig::new(DualBusConfig::default().with_mode(mode));
        r.l.add_pair(NodeId::must(0x10), NodeId::must(0x11), Some(Member::A))
            .unwrap();
        assert!(r.l.watch(NodeId::must(0x10), d(100)));
        let t0 = Instant::ZERO + HOUR;
        r.send(t0, heartbeat(5, 0));
        lagging(&mut r, t0, 25, 0, d(15));
        r.rx(t0 + d(300), 0, tpdo(0x10, 1));
        r.rx(t0 + d(300), 0, tpdo(0x11, 2));
        r.rx(t0 + d(301), 0, heartbeat(0x10, 5));
        r.send(t0 + d(302), tpdo(5, 7));
        let mut calls = 0;
        while r.l.poll_timeout().is_some() {
            r.l.handle_timeout(Instant::MAX);
            r.drain();
            calls += 1;
            assert!(
                calls <= 3,
                "{mode:?}: still due at the end of time: {:?}",
                r.l.poll_timeout()
            );
        }
        // Frames at the end of time are handled and leave nothing due either.
        r.rx(Instant::MAX, 0, tpdo(5, 1));
        r.rx(Instant::MAX, 1, tpdo(5, 1));
        r.l.handle_timeout(Instant::MAX);
        r.drain();
        assert_eq!(r.l.poll_timeout(), None, "{mode:?}");
        // The clock comes back to 10 s, and bus 2 has died: its last frame, at the end of time,
        // was at 10 s in the new time line.
        r.events.clear();
        r.step(Instant::MAX, ms(10_000));
        if mode == LinkMode::ActiveActive {
            traffic(&mut r, ms(10_010), 50, 0, false);
            r.run(ms(11_000));
            let failed = r
                .port_events(1)
                .into_iter()
                .find(|(_, to, _)| *to == PortState::Failed);
            assert_eq!(
                failed,
                Some((
                    ms(10_300),
                    PortState::Failed,
                    PortReason::Silence { silent: d(300) }
                ))
            );
        }
    }
}
