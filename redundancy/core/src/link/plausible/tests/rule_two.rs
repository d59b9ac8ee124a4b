//! Rule 2: on one bus only, and its witnesses (a lower-priority heartbeat, the bus seen idle).

use super::*;

/// Every 12 ms from `from` to `until`: 0x10 beats on each bus `node` says (with the state it
/// gives), the witness 0x50 (lower priority) 300 µs later on each bus `witness` says.
fn beats(
    r: &mut Rig,
    (from, until): (u64, u64),
    node: impl Fn(u64, usize) -> Option<u8>,
    witness: impl Fn(u64, usize) -> bool,
) {
    let mut t = from;
    while t <= until {
        for port in 0..2 {
            if let Some(state) = node(t, port) {
                r.beat(ms(t), port, 0x10, state);
            }
            if witness(t, port) {
                r.beat(ms(t) + Duration::from_micros(300), port, 0x50, 0x7F);
            }
        }
        t += 12;
    }
}

/// Both nodes beat on both buses from 100 ms until `until`; 0x10 stops on `silent` at `stop`.
fn paired_then(r: &mut Rig, stop: u64, silent: Option<usize>, until: u64) {
    let node = |t, port| (!(silent == Some(port) && t >= stop)).then_some(5);
    beats(r, (100, until), node, |_, _| true);
}

#[test]
fn rule_two_one_bus_only_with_a_witness_on_the_other() {
    let mut r = Rig::new();
    // 0x10 no longer heard on bus 2 after 232 ms (its last heartbeat there); 0x50 (lower
    // priority) is.
    paired_then(&mut r, 244, Some(1), 400);
    let fall = ms(232) + W;
    let e: Vec<_> = r
        .events()
        .into_iter()
        .filter(|e| matches!(e.kind, LinkEventKind::Suspect { .. }))
        .collect();
    assert_eq!(
        e.iter().map(|e| (e.at, e.kind)).collect::<Vec<_>>(),
        [(
            fall,
            LinkEventKind::Suspect {
                node: n(0x10),
                why: Suspicion::OneBus { heard: 0 }
            }
        )]
    );
    assert_eq!(r.requests(), [(0x10, true)]);
    assert_eq!(r.p.one_bus(n(0x10)), Some(0));
    // Heard on bus 2 again: trusted.
    r.beat(ms(401), 1, 0x10, 5);
    assert_eq!(r.requests(), [(0x10, false)]);
    assert_eq!(r.p.one_bus(n(0x10)), None);
}

#[test]
fn rule_two_needs_a_lower_priority_witness_and_an_ok_port() {
    // The witness must have a lower priority: 0x50 stopping on bus 2 while 0x10 goes on there is
    // no evidence against 0x50 (a babbler between 0x710 and 0x750 would do the same). Here the
    // heartbeats are not shown as frames, so bus 2 is never seen idle (that witness is below).
    let mut r = Rig::new();
    beats(
        &mut r,
        (100, 400),
        |_, _| Some(5),
        |t, port| !(port == 1 && t >= 244),
    );
    assert!(r.requests().is_empty());
    assert_eq!(r.p.one_bus(n(0x50)), None);

    // Bus 2 cut: nothing on it, no witness, no verdict.
    let mut r = Rig::new();
    let up = |t, port| port == 0 || t < 244;
    beats(&mut r, (100, 400), |t, port| up(t, port).then_some(5), up);
    assert!(r.requests().is_empty());

    // Never heard on bus 2, where nodes may be on one bus by design: no impostor.
    let only_bus_1 = |_, port| (port == 0).then_some(5);
    let mut r = Rig::new();
    r.p = Plausibility::new(Some(W)).with_one_bus_members(true);
    for node in [0x10, 0x50] {
        assert!(r.p.watch(n(node), T));
    }
    beats(&mut r, (100, 400), only_bus_1, |_, _| true);
    assert!(r.requests().is_empty());

    // Where every member has a port on each bus (the default): bus 2 silent since it was
    // first heard (100 ms), 0x50 beating there: suspect one window later, exactly.
    let mut r = Rig::new();
    beats(&mut r, (100, 400), only_bus_1, |_, _| true);
    assert_eq!(r.requests(), [(0x10, true)]);
    let e: Vec<_> = r
        .events()
        .into_iter()
        .filter(|e| matches!(e.kind, LinkEventKind::Suspect { .. }))
        .map(|e| (e.at, e.kind))
        .collect();
    assert_eq!(
        e,
        [(
            ms(100) + W,
            LinkEventKind::Suspect {
                node: n(0x10),
                why: Suspicion::OneBus { heard: 0 }
            }
        )]
    );
}

#[test]
fn a_boot_up_is_a_new_life_judged_afresh() {
    let mut r = Rig::new();
    paired_then(&mut r, 244, Some(1), 400);
    assert_eq!(r.requests(), [(0x10, true)]);
    // It boots (a reset after its failover) and goes on on bus 1 only: a life begun with a
    // boot-up is judged once heard on both buses, trusted (a board cut off one bus is not
    // reset at every boot).
    r.beat(ms(405), 0, 0x10, 0);
    assert_eq!(r.requests(), [(0x10, false)]);
    beats(
        &mut r,
        (417, 700),
        |_, port| (port == 0).then_some(0x7F),
        |_, _| true,
    );
    assert!(r.requests().is_empty());
    // Heard nowhere for a window, it appears again on bus 1 only (no boot-up: an impostor, or
    // a master's first sight of it): judged from its appearance.
    beats(
        &mut r,
        (800, 1_000),
        |_, port| (port == 0).then_some(0x7F),
        |_, _| true,
    );
    assert_eq!(r.requests(), [(0x10, true)]);
}

#[test]
fn heartbeats_a_late_receive_path_hands_over_after_a_deadline_begin_a_life() {
    // Both nodes beat on both buses until 300 ms; 0x10 then goes on on bus 1 only, which arms
    // a deadline at 336 ms. At it, 0x50's last heartbeats are a window old: heard nowhere, its
    // life ends. Then a receive path running behind hands over 0x50's heartbeats stamped
    // 312 ms on: each within a window of the one before, and yet a new life begins (before,
    // none did: the node was never judged again until it fell silent for a window).
    let mut r = Rig::new();
    paired_then(&mut r, 301, Some(1), 300);
    r.beat(ms(312), 0, 0x10, 5);
    r.beat(ms(324), 0, 0x10, 5);
    r.run(ms(340));
    let life = |r: &Rig| r.p.entry(n(0x50)).unwrap().life;
    assert_eq!(life(&r), NEVER);
    // Stamped 312 ms, handed over now (no clock step: the stamps of a late receive path).
    r.p.on_heartbeat(ms(312), 0, n(0x50), &hb(0x50, 0x7F), &r.health, &mut r.out);
    assert_eq!(life(&r), 312_000);
}

#[test]
fn heard_nowhere_ends_the_suspicion_and_the_pairing() {
    let mut r = Rig::new();
    paired_then(&mut r, 244, Some(1), 400);
    assert_eq!(r.requests(), [(0x10, true)]);
    // The impostor on bus 1 stops too: at its last heartbeat + W, nothing left to doubt.
    beats(&mut r, (412, 600), |_, _| None, |_, _| true);
    assert_eq!(r.requests(), [(0x10, false)]);
    let trusted = r
        .events()
        .into_iter()
        .find(|e| matches!(e.kind, LinkEventKind::Trusted { .. }))
        .unwrap();
    assert_eq!(trusted.at, ms(400) + W);
}

/// What else a bus carries, every 100 µs tick: nothing, a frame received, or one of the layer's
/// own frames handed over (not confirmed).
#[derive(Clone, Copy, PartialEq)]
enum Other {
    None,
    Received,
    Handed,
}

/// 0x10 and 0x50 beating every 12 ms on both buses from `from` to `until` (ms), as the layer
/// sees them: each heartbeat is a frame on its bus too (rule 2's idle witness); 0x50 stops on
/// bus 2 at 244 ms; `other` adds frames that are no watched heartbeat.
fn with_frames(r: &mut Rig, (from, until): (u64, u64), other: impl Fn(u64, usize) -> Other) {
    let mut t = from * 1000;
    while t <= until * 1000 {
        for port in 0..2 {
            match other(t, port) {
                Other::Received => r.p.on_frame(us(t), port, &r.health),
                Other::Handed => r.p.on_handed(us(t), port),
                Other::None => {}
            }
            for (node, state, lag) in [(0x10, 5, 0), (0x50, 0x7F, 300)] {
                let silent = node == 0x50 && port == 1 && t >= 244_000;
                if t % 12_000 == lag && !silent {
                    r.run(us(t));
                    r.p.on_frame(us(t), port, &r.health);
                    r.beat(us(t), port, node, state);
                }
            }
        }
        t += 100;
    }
    r.run(us(t));
}

#[test]
fn rule_two_for_the_highest_node_id_the_other_bus_seen_idle_is_the_witness() {
    // 0x50 has no lower-priority heartbeat to witness for it. It stops on bus 2 after
    // 240.3 ms; bus 2 goes on carrying 0x10 every 12 ms, gaps far longer than the frame time
    // (2 ms): idle after 0x50's heartbeat was due there (1.5 periods after its last: 258.3 ms),
    // before 0x10's heartbeat at 264 ms. Suspect at its last heartbeat there + W, exactly.
    let mut r = Rig::new();
    with_frames(&mut r, (96, 400), |_, _| Other::None);
    let e: Vec<_> = r
        .events()
        .into_iter()
        .filter(|e| matches!(e.kind, LinkEventKind::Suspect { .. }))
        .map(|e| (e.at, e.kind))
        .collect();
    assert_eq!(
        e,
        [(
            us(240_300) + W,
            LinkEventKind::Suspect {
                node: n(0x50),
                why: Suspicion::OneBus { heard: 0 }
            }
        )]
    );
    assert_eq!(r.requests(), [(0x50, true)]);
    // The last gap, 384 → 396 ms: idle until the frame time before 396 ms at least.
    assert_eq!(r.p.idle_seen(1), Some(us(394_000)));
}

#[test]
fn a_bus_never_idle_is_no_witness_nor_are_gaps_the_layers_own_frames_may_fill() {
    // Bus 2 carries a frame every 1.9 ms besides the heartbeats (a higher-priority load that
    // could starve 0x750): never a gap longer than the frame time, no verdict.
    let busy = |t: u64, p: usize| p == 1 && t.is_multiple_of(1_900);
    let mut r = Rig::new();
    with_frames(&mut r, (96, 400), |t, p| {
        if busy(t, p) {
            Other::Received
        } else {
            Other::None
        }
    });
    assert!(r.requests().is_empty());
    assert_eq!(r.p.idle_seen(1), None);

    // The same gaps filled with this layer's own frames, which its driver does not confirm:
    // each is taken to use the bus for the frame time from its hand-over. No verdict either.
    let mut r = Rig::new();
    with_frames(&mut r, (96, 400), |t, p| {
        if busy(t, p) {
            Other::Handed
        } else {
            Other::None
        }
    });
    assert!(r.requests().is_empty());
    assert_eq!(r.p.idle_seen(1), None);

    // A driver that confirms: a gap that closes while an own frame is unconfirmed does not
    // count (the frame may be in it); confirmed, the frame is one seen on the bus.
    let mut r = Rig::new();
    r.p.on_frame(ms(100), 1, &r.health);
    r.handed(ms(100), 1);
    r.confirmed(ms(101), 1, PortStatus::TxOk);
    r.handed(ms(101), 1);
    r.p.on_frame(ms(110), 1, &r.health);
    assert_eq!(r.p.idle_seen(1), None);
    r.confirmed(ms(111), 1, PortStatus::TxOk);
    r.p.on_frame(ms(120), 1, &r.health);
    assert_eq!(r.p.idle_seen(1), Some(ms(118)));
    // A confirmation ends a gap as a received frame does (the gap before a SYNC this layer
    // sends: every gap of a cyclic network may end so), merged with the received frames in
    // the order of their ends: counted once the received frames have passed it.
    r.handed(ms(130), 1);
    r.confirmed(us(130_100), 1, PortStatus::TxOk);
    assert_eq!(r.p.idle_seen(1), Some(ms(118)));
    r.p.on_frame(us(130_300), 1, &r.health);
    assert_eq!(r.p.idle_seen(1), Some(us(128_100)));
    // Two own frames: their ends follow each other, the gap before the first is idle.
    r.handed(ms(140), 1);
    r.handed(ms(140), 1);
    r.confirmed(us(140_100), 1, PortStatus::TxOk);
    r.confirmed(us(140_200), 1, PortStatus::TxOk);
    r.p.on_frame(us(140_400), 1, &r.health);
    assert_eq!(r.p.idle_seen(1), Some(us(138_100)));
    // A receive path running 5 ms behind: its frames come after the confirmation of a frame
    // that ended later on the wire. Merged in the order of their ends, the gaps are those of
    // the wire: 140.4 → 145 idle, 145 → 150.1 (own) idle, 150.1 → 150.9 and on busy.
    r.handed(ms(150), 1);
    r.confirmed(us(150_100), 1, PortStatus::TxOk);
    r.p.on_frame(us(145_000), 1, &r.health);
    assert_eq!(r.p.idle_seen(1), Some(us(143_000)));
    r.p.on_frame(us(150_900), 1, &r.health);
    assert_eq!(r.p.idle_seen(1), Some(us(148_100)));
    // A received frame that ends a gap while an own frame handed over before it waits for its
    // outcome: that frame may have been on the bus since its hand-over, which ends the gap
    // (the gap before a SYNC that waited behind another frame; not counted at all, a cyclic
    // network's master saw no idle bus for a second).
    r.handed(ms(155), 1);
    r.p.on_frame(ms(160), 1, &r.health);
    assert_eq!(r.p.idle_seen(1), Some(ms(153)));
    r.confirmed(us(160_100), 1, PortStatus::TxOk);
    r.p.on_frame(ms(161), 1, &r.health);
    // Handed over within the frame time of the last end: no witness.
    r.handed(us(162_900), 1);
    r.p.on_frame(ms(170), 1, &r.health);
    assert_eq!(r.p.idle_seen(1), Some(ms(153)));
}

#[test]
fn own_frame_ends_wait_in_bounded_memory_for_the_received_frames() {
    // Forty own frames every 10 ms and nothing received: 32 ends wait, the older ones are
    // merged without their gaps (no received frame has passed them: no witness).
    let mut r = Rig::new();
    r.p.on_frame(ms(100), 1, &r.health);
    for k in 0..40 {
        r.handed(ms(105 + 10 * k), 1);
        r.confirmed(us(105_100 + 10_000 * k), 1, PortStatus::TxOk);
    }
    assert_eq!(r.p.idle_seen(1), None);
    // A received frame after them all: the 32 waiting ends merge in order, each gap idle.
    r.p.on_frame(ms(500), 1, &r.health);
    assert_eq!(r.p.idle_seen(1), Some(ms(498)));
}

#[test]
fn own_frames_a_flush_discarded_leave_no_gap_in_doubt_for_ever() {
    // A driver that confirms; two own frames wait when port health forgets them (the port goes
    // down, or its queue is flushed after a stall behind a babble: the driver never confirms
    // them). Gaps after that count again.
    let mut r = Rig::new();
    r.p.on_frame(ms(100), 1, &r.health);
    r.handed(ms(100), 1);
    r.confirmed(ms(101), 1, PortStatus::TxOk);
    r.handed(ms(102), 1);
    r.handed(ms(102), 1);
    r.p.on_frame(ms(110), 1, &r.health);
    assert_eq!(r.p.idle_seen(1), None);
    r.health
        .on_status(ms(111), 1, PortStatus::Down(ErrorCause::BusOff), &mut r.out);
    r.p.on_frame(ms(130), 1, &r.health);
    assert_eq!(r.p.idle_seen(1), Some(ms(128)));
}

#[test]
fn rule_two_counts_the_silence_from_the_ports_return_to_ok() {
    // Bus 2 cut from 254 to 300 ms while 0x10 and 0x50 beat every 12 ms (0x50 just before
    // 0x10): the heartbeats sent meanwhile are lost; port health calls the port suspect at the
    // first frame of this station's that goes unacknowledged (a suspicion for silence alone
    // would not do: a bus with little traffic is often silent for a while).
    let mut r = Rig::new();
    r.health = Health::new(
        HealthConfig::from_guard_period(Duration::from_millis(20)),
        Duration::from_millis(10),
    );
    let cut = |t: u64, port: usize| port == 1 && (254..300).contains(&t);
    let mut t = 100;
    while t <= 340 {
        for (dt, port, node) in [(0, 0, 0x50), (0, 1, 0x50), (300, 0, 0x10), (400, 1, 0x10)] {
            let at = ms(t) + Duration::from_micros(dt);
            r.health.handle_timeout(at, &mut r.out);
            if t == 256 && port == 1 && node == 0x50 {
                // This station's own frame on bus 2 goes unacknowledged: the cut.
                let nack = PortStatus::TxFailed(duocan_core::machine::ErrorCause::NoAck);
                r.health.on_status(at, 1, nack, &mut r.out);
            }
            if !cut(t, port) {
                r.beat(at, port, node, 5);
                r.health
                    .on_rx(at, at, port, RxOutcome::Delivered, &mut r.out);
            }
        }
        t += 12;
    }
    let states: Vec<_> = r
        .events()
        .into_iter()
        .filter_map(|e| match e.kind {
            LinkEventKind::Port { port: 1, to, .. } => Some(to),
            _ => None,
        })
        .collect();
    assert_eq!(states, [PortState::Suspect, PortState::Ok]);
    // 0x10's last heartbeat on bus 2 before the cut at 242 ms, W = 36 ms. At 302 ms 0x50 shows
    // bus 2 back and ok, and 0x10 is heard on bus 1: its heartbeat on bus 2 is not late, it
    // comes 400 µs after 0x50's. The silence was the cut's: no verdict.
    assert!(r.requests().is_empty());
    assert_eq!(r.p.one_bus(n(0x10)), None);
}
