//! A producer node and a consumer node on a zero-latency wire: the frames the producer sends,
//! the values the consumer's dictionary takes, the safe state with its safe values, the GFC,
//! the acknowledgement.

use crate::support::*;
use duocan::cia304::srdo::config;
use duocan::cia304::srdo::consumer::SrdoCause;
use duocan::cia304::srdo::{SrdoEvent, SrdoStatus};
use duocan::node::NodeEventKind as K;
use duocan::{Duration, Frame, Id, Instant, NmtState};

fn srdo_events(w: &crate::common::Wire, i: usize) -> Vec<(Instant, SrdoEvent)> {
    w.events[i]
        .iter()
        .filter_map(|e| match e.kind {
            K::Srdo(s) => Some((e.at, s)),
            _ => None,
        })
        .collect()
}

fn safe(cause: SrdoCause, measured: Duration) -> SrdoEvent {
    SrdoEvent::SafeState {
        srdo: 1,
        cause,
        measured,
    }
}

#[test]
fn the_producer_sends_normal_then_inverse_every_refresh_time() {
    let mut w = pair();
    produce(&mut w, 0x1234, 0x56);
    start_all(&mut w);
    w.run_until(ms(45));
    let normal = w.sent(PRODUCER, NORMAL);
    let inverted = w.sent(PRODUCER, INVERTED);
    // Node 2 starts 1 ms in (node-ID × 0.5 ms), then every 20 ms.
    let times: Vec<_> = normal.iter().map(|(t, _)| *t).collect();
    assert_eq!(times, [ms(1), ms(21), ms(41)]);
    assert_eq!(normal[0].1.data(), [0x34, 0x12, 0x56]);
    assert_eq!(
        inverted[0],
        (
            ms(1),
            Frame::from_array(Id::Standard(INVERTED), [0xCB, 0xED, 0xA9])
        )
    );
    // Normal first, its inverse right after it.
    let order: Vec<_> = w
        .log
        .iter()
        .filter(|(_, s, _)| *s == PRODUCER)
        .map(|(_, _, f)| f.id())
        .collect();
    assert!(order
        .windows(2)
        .any(|p| p == [Id::Standard(NORMAL), Id::Standard(INVERTED)]));
    // The consumer took the value, plain and inverted.
    assert_eq!(consumed(&w), (0x1234, 0x56, !0x1234, !0x56));
    assert_eq!(
        w.nodes[CONSUMER].srdo_status(1),
        Some(SrdoStatus::Consumer { running: true })
    );
    assert_eq!(
        w.nodes[PRODUCER].srdo_status(1),
        Some(SrdoStatus::Producer {
            running: true,
            sent: 3
        })
    );
}

#[test]
fn a_request_sends_at_once_and_restarts_the_grid() {
    let mut w = pair();
    produce(&mut w, 1, 2);
    start_all(&mut w);
    w.run_until(ms(5));
    produce(&mut w, 7, 8);
    assert!(w.nodes[PRODUCER].srdo_request(ms(5), 1));
    w.run_until(ms(30));
    let times: Vec<_> = w.sent(PRODUCER, NORMAL).iter().map(|(t, _)| *t).collect();
    assert_eq!(times, [ms(1), ms(5), ms(25)]);
    assert_eq!(consumed(&w).0, 7);
}

#[test]
fn a_silent_producer_trips_the_consumer_exactly_sct_after_its_last_pair() {
    let mut w = pair();
    w.nodes[CONSUMER].set_srdo_safe_values(1, &[0xAD, 0xDE, 0x55]);
    produce(&mut w, 0x1234, 0x56);
    start_all(&mut w);
    w.run_until(ms(30));
    // The producer's node fails at 30 ms: its last pair went out at 21 ms.
    w.alive[PRODUCER] = false;
    w.run_until(ms(70));
    assert!(srdo_events(&w, CONSUMER).is_empty(), "not before SCT");
    w.run_until(ms(71));
    let expect = safe(SrdoCause::CycleTime, Duration::from_millis(50));
    assert_eq!(srdo_events(&w, CONSUMER), [(ms(71), expect)]);
    // Its outputs hold the safe values, the inverted entries their inverse.
    assert_eq!(consumed(&w), (0xDEAD, 0x55, !0xDEAD, !0x55));
    assert!(matches!(
        w.nodes[CONSUMER].srdo_status(1),
        Some(SrdoStatus::Safe(_))
    ));
}

#[test]
fn a_producer_whose_inverse_is_wrong_falls_silent_and_the_consumer_trips() {
    let mut w = pair();
    produce(&mut w, 0x1234, 0x56);
    start_all(&mut w);
    w.run_until(ms(30));
    // The application corrupts one copy: the producer withholds the pair and says so once.
    w.nodes[PRODUCER].set(ms(30), 0x6011, 0, 0x56u8).unwrap();
    w.run_until(ms(100));
    assert_eq!(w.sent(PRODUCER, NORMAL).len(), 2, "nothing after 21 ms");
    let p = srdo_events(&w, PRODUCER);
    assert_eq!(p, [(ms(41), SrdoEvent::NotInverted { srdo: 1 })]);
    let c = srdo_events(&w, CONSUMER);
    assert_eq!(
        c[0],
        (
            ms(71),
            safe(SrdoCause::CycleTime, Duration::from_millis(50))
        )
    );
    // Never the corrupt value: the last intact one, then the safe values (zeros).
    assert_eq!(consumed(&w), (0, 0, 0xFFFF, 0xFF));
}

#[test]
fn a_gfc_puts_every_consumer_in_its_safe_state_at_once() {
    let mut w = pair();
    for n in &mut w.nodes {
        n.set(Instant::ZERO, config::GFC_PARAMETER, 0, 1u8).unwrap();
    }
    produce(&mut w, 0x1234, 0x56);
    start_all(&mut w);
    w.run_until(ms(10));
    assert!(w.nodes[PRODUCER].gfc_send(ms(10)));
    w.flush();
    assert_eq!(
        w.sent(PRODUCER, 0x001),
        [(ms(10), Frame::from_array(Id::Standard(1), []))]
    );
    let c = srdo_events(&w, CONSUMER);
    let tripped = safe(SrdoCause::Gfc, Duration::ZERO);
    assert_eq!(c, [(ms(10), tripped), (ms(10), SrdoEvent::Gfc)]);
    assert_eq!(consumed(&w), (0, 0, 0xFFFF, 0xFF));
    // Without 0x1300 = 1 the GFC is neither sent nor obeyed.
    let mut w = pair();
    start_all(&mut w);
    assert!(!w.nodes[PRODUCER].gfc_send(ms(1)));
    w.deliver(Frame::from_array(Id::Standard(1), []));
    assert!(srdo_events(&w, CONSUMER).is_empty());
}

#[test]
fn after_an_acknowledgement_only_a_new_intact_pair_delivers() {
    let mut w = pair();
    produce(&mut w, 0x1234, 0x56);
    start_all(&mut w);
    w.alive[PRODUCER] = false;
    w.run_until(ms(60));
    assert!(matches!(
        w.nodes[CONSUMER].srdo_status(1),
        Some(SrdoStatus::Safe(_))
    ));
    assert_eq!(consumed(&w).0, 0, "the safe value");
    assert!(w.nodes[CONSUMER].srdo_acknowledge(ms(60), 1));
    w.flush();
    assert_eq!(
        consumed(&w).0,
        0,
        "still the safe value until a pair arrives"
    );
    w.alive[PRODUCER] = true;
    w.run_until(ms(85));
    assert_eq!(consumed(&w), (0x1234, 0x56, !0x1234, !0x56));
    let events = srdo_events(&w, CONSUMER);
    assert_eq!(
        events.last(),
        Some(&(ms(60), SrdoEvent::Acknowledged { srdo: 1 }))
    );
}

#[test]
fn leaving_operational_stops_both_and_entering_again_restarts_the_sct() {
    let mut w = pair();
    produce(&mut w, 1, 2);
    start_all(&mut w);
    w.run_until(ms(30));
    for n in &mut w.nodes {
        n.set_nmt_state(ms(30), NmtState::PreOperational);
    }
    w.run_until(ms(500));
    assert_eq!(w.sent(PRODUCER, NORMAL).len(), 2);
    assert!(
        srdo_events(&w, CONSUMER).is_empty(),
        "no SCT outside operational"
    );
    // Operational again: the consumer's SCT runs from the start, the producer starts anew.
    w.alive[PRODUCER] = false;
    start_all(&mut w);
    w.run_until(ms(549));
    assert!(srdo_events(&w, CONSUMER).is_empty());
    w.run_until(ms(550));
    let e = safe(SrdoCause::CycleTime, Duration::from_millis(50));
    assert_eq!(srdo_events(&w, CONSUMER), [(ms(550), e)]);
}
