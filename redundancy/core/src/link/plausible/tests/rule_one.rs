//! Rule 1: far faster than the period, per bus; the duplicate's and the babble's verdicts.

use super::*;

#[test]
fn rule_one_is_five_plus_four_thirds_of_the_periods_in_any_span() {
    // T = 12 ms: a span of 9 ms may hold 5 + 4·9/36 = 6 heartbeats, not 7.
    let mut r = Rig::new();
    for k in 0..6 {
        assert!(!r.beat(us(100_000 + k * 1_800), 0, 0x10, 5));
    }
    assert!(r.requests().is_empty());
    // A seventh within those 9 ms: too fast, dropped, handed up, reported.
    assert!(r.beat(us(109_000), 0, 0x10, 5));
    assert_eq!(r.requests(), [(0x10, true)]);
    assert_eq!(r.p.is_suspect(n(0x10)), Some(true));
    assert!(r.p.too_fast(n(0x10), 0) && !r.p.too_fast(n(0x10), 1));
    let e = r.events();
    assert_eq!(e.len(), 1);
    assert_eq!(
        (e[0].at, e[0].kind),
        (
            us(109_000),
            LinkEventKind::Suspect {
                node: n(0x10),
                why: Suspicion::TooFast { port: 0 }
            }
        )
    );
    // The other bus is judged on its own.
    assert!(!r.beat(us(109_100), 1, 0x10, 5));
}

#[test]
fn the_verdict_ends_when_the_bucket_has_drained_and_the_rate_is_reported() {
    let mut r = Rig::new();
    // A babble: 40 frames 100 µs apart from 1 s.
    let mut dropped = 0;
    for k in 0..40 {
        dropped += r.beat(us(1_000_000 + k * 100), 0, 0x10, 5) as usize;
    }
    // Flagged at the sixth (an empty bucket holds five at once), the rest dropped.
    assert_eq!(dropped, 35);
    let v = us(1_000_500);
    assert_eq!(r.requests(), [(0x10, true)]);
    r.events();
    // One period later: the 35 frames in [v, v + T): a babble at 35 / 12 ms.
    r.run(v + T);
    let e = r.events();
    assert_eq!(
        e.iter().map(|e| (e.at, e.kind)).collect::<Vec<_>>(),
        [(
            v + T,
            LinkEventKind::Babbling {
                node: n(0x10),
                id: Id::Standard(0x710),
                port: 0,
                rate: 35 * 1_000_000 / 12_000,
                allowed: 83,
                since: v
            }
        )]
    );
    // The bucket, capped at 6 drains of 9 ms after the last frame, empties 54 ms after it.
    let last = us(1_003_900);
    r.run(last + Duration::from_millis(54) - Duration::from_micros(1));
    assert!(r.requests().is_empty());
    r.run(last + Duration::from_millis(54));
    assert_eq!(r.requests(), [(0x10, false)]);
    assert_eq!(
        r.events()
            .iter()
            .map(|e| (e.at, e.kind))
            .collect::<Vec<_>>(),
        [(
            last + Duration::from_millis(54),
            LinkEventKind::Trusted { node: n(0x10) }
        )]
    );
    assert!(!r.beat(last + Duration::from_millis(60), 0, 0x10, 5));
}

#[test]
fn a_second_device_at_the_same_period_is_a_duplicate_not_a_babble() {
    let mut r = Rig::new();
    let mut t = 1_000_000;
    let mut first = None;
    for _ in 0..20 {
        for (off, state) in [(0, 5), (5_000, 0x7F)] {
            if r.beat(us(t + off), 1, 0x10, state) && first.is_none() {
                first = Some(us(t + off));
            }
        }
        t += 12_000;
    }
    let v = first.expect("flagged");
    // Within 8 periods of both beating.
    assert!(v <= us(1_000_000) + T.saturating_mul(8), "{v}");
    r.run(us(t));
    let dup = r
        .events()
        .into_iter()
        .find(|e| matches!(e.kind, LinkEventKind::DuplicateNode { .. }))
        .unwrap();
    assert_eq!(
        (dup.at, dup.kind),
        (
            v + T,
            LinkEventKind::DuplicateNode {
                node: n(0x10),
                port: 1,
                rate: 2 * 1_000_000 / 12_000,
                allowed: 83,
                since: v
            }
        )
    );
}

#[test]
fn a_burst_of_the_nodes_own_heartbeats_is_no_duplicate_though_it_is_too_fast() {
    // A node beating every 12 ms, on bus 1 alone, stalled by a loaded host: it sends the six
    // heartbeats it owes at once, and its next one late again. Too fast for the bucket, but
    // in the period after the verdict only the verdict's own heartbeat: no second device.
    let mut r = Rig::new();
    let mut stamps: Vec<u64> = (0..5).map(|k| 1_000_000 + k * 12_000).collect();
    stamps.extend((0..6).map(|j| 1_132_000 + j)); // owed since 1.060 s
    stamps.extend((0..18).map(|k| 1_146_000 + k * 12_000));
    let dropped: Vec<u64> = stamps
        .iter()
        .copied()
        .filter(|&t| r.beat(us(t), 0, 0x10, 5))
        .collect();
    let v = us(dropped[0]);
    assert_eq!(
        v,
        us(1_132_005),
        "the sixth of the burst is the first too many"
    );
    r.run(us(1_400_000));
    let e = r.events();
    let told = |k: LinkEventKind| e.iter().any(|e| e.kind == k);
    assert!(told(LinkEventKind::Suspect {
        node: n(0x10),
        why: Suspicion::TooFast { port: 0 }
    }));
    assert!(told(LinkEventKind::Trusted { node: n(0x10) }));
    // No rate reported: one heartbeat in [v, v + T) is no more than the period allows.
    assert!(
        !e.iter().any(|e| matches!(
            e.kind,
            LinkEventKind::DuplicateNode { .. } | LinkEventKind::Babbling { .. }
        )),
        "{e:?}"
    );
}

#[test]
fn a_second_device_at_twice_the_period_is_reported_whatever_its_phase() {
    // A node beating every 12 ms on bus 1 and a second device with its node-ID every 24 ms:
    // 1.5 heartbeats a period. In the period after the verdict the second device may not beat
    // (a verdict at the node's heartbeat just after the device's): that period is measured
    // again while the verdict holds, and the duplicate reported from one that shows it.
    for offset in (1_000..24_000).step_by(1_000) {
        let mut r = Rig::new();
        let mut beats: Vec<u64> = (0..200).map(|k| 1_000_000 + k * 12_000).collect();
        beats.extend((0..100).map(|k| 1_000_000 + offset + k * 24_000));
        beats.sort_unstable();
        for t in beats {
            r.beat(us(t), 0, 0x10, 5);
        }
        r.run(us(3_500_000));
        let dup = r.events().into_iter().find_map(|e| match e.kind {
            LinkEventKind::DuplicateNode { rate, allowed, .. } => Some((rate, allowed)),
            _ => None,
        });
        assert_eq!(
            dup,
            Some((2 * 1_000_000 / 12_000, 83)),
            "offset {offset} µs: two heartbeats in the period measured"
        );
    }
}

#[test]
fn a_duplicate_on_both_buses_is_told_as_such_and_the_node_alone_after_it_is_trusted_at_its_third_beat(
) {
    // A second device beats 0x10's heartbeat on both buses, 5 ms after the node's own, from
    // 1 s to 1.3 s; the node beats on alone at its period after that.
    let mut r = Rig::new();
    let mut dropped = vec![];
    let mut t = 1_000_000;
    while t < 1_600_000 {
        for p in 0..2 {
            if r.beat(us(t + p as u64 * 300), p, 0x10, 5) {
                dropped.push(t + p as u64 * 300);
            }
        }
        if t < 1_300_000 {
            for p in 0..2 {
                r.beat(us(t + 5_000 + p as u64 * 300), p, 0x10, 5);
            }
        }
        if t == 1_300_000 {
            // A master resets the node meanwhile: its boot-up is no second device.
            for p in 0..2 {
                r.beat(us(t + 10_000 + p as u64 * 300), p, 0x10, 0);
            }
        }
        t += 12_000;
    }
    let reqs: Vec<_> = core::iter::from_fn(|| r.out.machine.pop()).collect();
    assert_eq!(
        reqs,
        [
            LinkRequest::NodeSuspect {
                node: n(0x10),
                suspect: true,
                duplicated: true
            },
            LinkRequest::NodeSuspect {
                node: n(0x10),
                suspect: false,
                duplicated: false
            }
        ]
    );
    // The duplicate's last heartbeat at 1,293 ms; the node's 1,300 is 7 ms after it (less than
    // 3T/4 = 9 ms: a second device, for all the rule can tell). The boot-up at 1,310 and the
    // node's 1,312 after it (a new state each) count neither way; 1,324 and 1,336 are a
    // period after the one before (still dropped), and 1,348, the third, passes on each bus.
    // The drain alone would have held them 18 periods.
    assert_eq!(dropped.last(), Some(&1_336_300), "{dropped:?}");
    let trusted: Vec<_> = r
        .events()
        .into_iter()
        .filter(|e| matches!(e.kind, LinkEventKind::Trusted { .. }))
        .map(|e| e.at)
        .collect();
    assert_eq!(trusted, [us(1_348_000)]);
}

#[test]
fn a_duplicate_saying_another_state_keeps_the_verdict_for_as_long_as_it_beats() {
    // The node says pre-operational, the other device operational: every heartbeat changes the
    // state, so no window completes and the verdict holds, all 40 periods.
    let mut r = Rig::new();
    let mut t = 1_000_000;
    let mut passed_late = vec![];
    for k in 0..40 {
        for p in 0..2 {
            if !r.beat(us(t + p as u64 * 300), p, 0x10, 0x7F) && k > 10 {
                passed_late.push(t);
            }
        }
        for p in 0..2 {
            r.beat(us(t + 5_000 + p as u64 * 300), p, 0x10, 5);
        }
        t += 12_000;
    }
    assert!(passed_late.is_empty(), "{passed_late:?}");
    assert!(!r
        .events()
        .iter()
        .any(|e| matches!(e.kind, LinkEventKind::Trusted { .. })));
}

#[test]
fn a_duplicate_on_one_bus_while_the_other_speaks_for_the_node_is_no_verdict_until_it_falls_silent()
{
    // 0x10 beats on both buses every 12 ms from 100 ms; a second device beats 0x10 on bus 1
    // only, 5 ms after each, from 400 ms; the real node stops beating on bus 2 after 796 ms.
    let mut r = Rig::new();
    let mut dropped = Vec::new();
    let mut t = 100;
    while t <= 1_000 {
        if t <= 796 {
            r.beat(ms(t), 1, 0x10, 5);
        }
        if r.beat(ms(t), 0, 0x10, 5) {
            dropped.push(t);
        }
        if t >= 400 && r.beat(ms(t) + Duration::from_millis(5), 0, 0x10, 5) {
            dropped.push(t);
        }
        if t == 784 {
            // Bus 1 too fast for 0x10 (its frames dropped), bus 2 speaks for it: trusted.
            assert!(
                !dropped.is_empty() && dropped[0] <= 400 + 8 * 12,
                "{dropped:?}"
            );
            assert!(r.p.too_fast(n(0x10), 0) && !r.p.too_fast(n(0x10), 1));
            assert_eq!(r.p.is_suspect(n(0x10)), Some(false));
            assert!(r.requests().is_empty());
            assert!(!r.events().iter().any(|e| matches!(
                e.kind,
                LinkEventKind::Suspect { .. } | LinkEventKind::Trusted { .. }
            )));
        }
        t += 12;
    }
    // Suspect 1.5 periods (18 ms) after its last heartbeat on bus 2, to the microsecond.
    let v = ms(796 + 18) + Duration::from_micros(1);
    assert_eq!(r.requests(), [(0x10, true)]);
    let suspect: Vec<_> = r
        .events()
        .into_iter()
        .filter(|e| matches!(e.kind, LinkEventKind::Suspect { .. }))
        .map(|e| (e.at, e.kind))
        .collect();
    assert_eq!(
        suspect[0],
        (
            v,
            LinkEventKind::Suspect {
                node: n(0x10),
                why: Suspicion::TooFast { port: 0 }
            }
        )
    );
    // Heard on bus 2 again: it speaks for the node, which is trusted at once.
    r.beat(ms(1_010), 1, 0x10, 5);
    assert_eq!(r.requests(), [(0x10, false)]);
    assert!(r
        .events()
        .iter()
        .any(|e| e.at == ms(1_010) && matches!(e.kind, LinkEventKind::Trusted { .. })));
}

#[test]
fn a_duplicate_on_one_bus_while_the_other_ports_reader_runs_behind_is_no_verdict() {
    // As above, with the node beating on bus 2 all along, but that port's reader 72 ms behind:
    // it hands each heartbeat over 72 ms after its stamp, so bus 2 is shown only up to 72 ms
    // before the present, and that is no silence. (Judged silent, the node was suspect by bus
    // 1 alone, an impostor, not a duplicate: a master reset its board, and the duplicate then
    // beat alone for it.)
    let mut r = Rig::new();
    r.health.rx_delay(1, Duration::from_millis(72));
    let mut t = 100;
    while t <= 1_000 {
        r.beat(ms(t), 0, 0x10, 5);
        if t >= 400 {
            r.beat(ms(t) + Duration::from_millis(5), 0, 0x10, 5);
        }
        // What bus 2 carried 72 ms ago comes now, stamped as it was.
        if t >= 172 {
            let late = ms(t - 72);
            r.p.on_heartbeat(late, 1, n(0x10), &hb(0x10, 5), &r.health, &mut r.out);
        }
        t += 12;
    }
    assert!(r.p.too_fast(n(0x10), 0) && !r.p.too_fast(n(0x10), 1));
    assert_eq!(r.p.is_suspect(n(0x10)), Some(false));
    assert!(r.requests().is_empty());
}

#[test]
fn a_board_reset_twice_in_a_few_periods_is_no_babbler_a_boot_up_babble_is() {
    // Reset at 100 ms and again five periods later (two masters, or a failover and its
    // repair): each time the heartbeat of the state it leaves, its boot-up, the
    // pre-operational and the operational heartbeat at once; its periodic heartbeats between.
    // Twelve heartbeats in 61 ms: one more than a bucket that kept the first life would take.
    let mut r = Rig::new();
    let mut dropped = 0;
    for start in [100_000, 160_000] {
        for (k, state) in [5u8, 0, 0x7F, 5].into_iter().enumerate() {
            dropped += r.beat(us(start + k as u64 * 300), 0, 0x10, state) as usize;
        }
        if start == 100_000 {
            for k in 1..5 {
                dropped += r.beat(us(start + 900 + k * 12_000), 0, 0x10, 5) as usize;
            }
        }
    }
    assert_eq!(dropped, 0);
    assert!(r.requests().is_empty());
    // A controller repeating the boot-up back to back: flagged at its sixth frame, like any
    // babble (only its first boot-up empties the bucket).
    let mut r = Rig::new();
    let flagged = (0..12).position(|k| r.beat(us(100_000 + k * 100), 0, 0x10, 0));
    assert_eq!(flagged, Some(5), "flagged at the sixth frame");
    assert_eq!(r.requests(), [(0x10, true)]);
}

#[test]
fn the_boot_up_a_masters_reset_asked_for_ends_the_verdict_though_no_heartbeat_was_calm() {
    // The node says pre-operational, a second device operational, on both buses, 5 ms apart,
    // for 20 periods: no heartbeat counts as calm. The device falls silent; a master resets
    // the node 5 ms after the node's last heartbeat (the moment the verdict made it suspect);
    // the boot-up follows 0.2 ms later. Without the reset seen, the boot-up is dropped with the
    // verdict (the master above would never see the board boot); with it, it passes on both
    // buses and the verdict ends there.
    for reset in [false, true] {
        let mut r = Rig::new();
        let mut t = 1_000_000;
        for _ in 0..20 {
            for (at, state) in [(t, 0x7F), (t + 5_000, 5)] {
                for p in 0..2 {
                    r.beat(us(at + p as u64 * 300), p, 0x10, state);
                }
            }
            t += 12_000;
        }
        for p in 0..2 {
            assert!(r.beat(us(t + p as u64 * 300), p, 0x10, 0x7F));
        }
        r.events();
        if reset {
            r.p.on_nmt(&Frame::new(Id::Standard(0), &[0x81, 0x10]).expect("two bytes"));
        }
        let boot = t + 5_200;
        let dropped: Vec<bool> = (0..2)
            .map(|p| r.beat(us(boot + p as u64 * 300), p, 0x10, 0))
            .collect();
        assert_eq!(dropped, [!reset; 2], "reset seen: {reset}");
        let trusted: Vec<_> = r
            .events()
            .into_iter()
            .filter(|e| matches!(e.kind, LinkEventKind::Trusted { .. }))
            .map(|e| e.at)
            .collect();
        let expected = if reset { vec![us(boot)] } else { vec![] };
        assert_eq!(trusted, expected, "reset seen: {reset}");
    }
}
