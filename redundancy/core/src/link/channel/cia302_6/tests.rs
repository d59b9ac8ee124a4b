//! The CiA 302-6 channel policy's unit tests.

use super::*;
use duocan_core::machine::ErrorCause;

fn ms(x: u64) -> Instant {
    Instant::from_millis(x)
}
fn hb(n: u8) -> Frame {
    Frame::from_array(Id::Standard(0x700 + n as u16), [5])
}
fn info(n: u8) -> FrameInfo {
    FrameInfo {
        heartbeat: NodeId::new(n),
    }
}
fn channel_events(out: &mut Outbox) -> Vec<(Instant, u8, u8, SwitchReason)> {
    let mut v = vec![];
    while let Some(e) = out.events.pop() {
        if let LinkEventKind::Channel { from, to, reason } = e.kind {
            v.push((e.at, from, to, reason));
        }
    }
    v
}
fn boot(p: &mut Cia3026, now: Instant, out: &mut Outbox) -> PortMask {
    let h = Health::new(Default::default(), Duration::from_millis(10));
    let f = Frame::from_array(Id::Standard(0x701), [0]);
    p.route_tx(now, &f, &info(1), &h, out)
}

#[test]
fn heartbeats_go_on_both_channels_everything_else_on_the_active_one() {
    let mut p = Cia3026::new(Cia3026Config::default());
    let mut out = Outbox::new();
    let h = Health::new(Default::default(), Duration::from_millis(10));
    assert_eq!(boot(&mut p, ms(0), &mut out), BOTH);
    let pdo = Frame::from_array(Id::Standard(0x181), [1]);
    let none = FrameInfo { heartbeat: None };
    assert_eq!(p.route_tx(ms(1), &pdo, &none, &h, &mut out), 0b01);
    assert!(p.select(ms(2), 1, &mut out));
    assert_eq!(p.route_tx(ms(3), &pdo, &none, &h, &mut out), 0b10);
    assert_eq!(out.pop_frame(), Some((1, indicate_active())));
}

#[test]
fn power_on_evaluation_switches_when_a_producer_gave_fewer_than_three() {
    let producers: NodeSet = [NodeId::must(2), NodeId::must(3)].into_iter().collect();
    let cfg = Cia3026Config {
        producers,
        ..Default::default()
    };
    let mut p = Cia3026::new(cfg);
    let mut out = Outbox::new();
    boot(&mut p, ms(0), &mut out);
    for t in [100, 200, 300] {
        p.on_rx(ms(t), 0, &hb(2), &info(2), &mut out);
        p.on_rx(ms(t), 1, &hb(3), &info(3), &mut out);
    }
    p.on_rx(ms(400), 0, &hb(3), &info(3), &mut out);
    assert_eq!(p.poll_timeout(), Some(ms(1000)));
    p.handle_timeout(ms(1000), &mut out);
    assert_eq!(
        channel_events(&mut out),
        [(
            ms(1000),
            0,
            1,
            SwitchReason::PowerOnEvaluation {
                node: NodeId::must(3),
                count: 1
            }
        )]
    );
    assert_eq!(out.pop_frame(), Some((1, indicate_active())));
    // Back to default as soon as both give three heartbeats there.
    for t in [1100, 1200, 1300] {
        p.on_rx(ms(t), 0, &hb(2), &info(2), &mut out);
        p.on_rx(ms(t + 1), 0, &hb(3), &info(3), &mut out);
    }
    assert_eq!(
        channel_events(&mut out),
        [(ms(1301), 1, 0, SwitchReason::HeartbeatsBack)]
    );
    assert_eq!(out.pop_frame(), Some((0, indicate_active())));
}

#[test]
fn power_on_evaluation_stays_when_every_producer_gave_three() {
    let mut p = Cia3026::new(Cia3026Config::default());
    let mut out = Outbox::new();
    boot(&mut p, ms(0), &mut out);
    for t in [100, 200, 300] {
        p.on_rx(ms(t), 0, &hb(2), &info(2), &mut out);
        p.on_rx(ms(t), 1, &hb(2), &info(2), &mut out);
    }
    p.handle_timeout(ms(1000), &mut out);
    assert!(channel_events(&mut out).is_empty());
    assert_eq!(p.poll_timeout(), None);
}

#[test]
fn reset_communication_returns_to_default_and_switches_if_a_producer_is_silent() {
    let producers: NodeSet = [NodeId::must(2), NodeId::must(3)].into_iter().collect();
    let cfg = Cia3026Config {
        producers,
        eval_reset: Duration::from_millis(500),
        ..Default::default()
    };
    let mut p = Cia3026::new(cfg);
    let mut out = Outbox::new();
    boot(&mut p, ms(0), &mut out);
    p.select(ms(10), 1, &mut out);
    boot(&mut p, ms(2000), &mut out);
    p.on_rx(ms(2100), 0, &hb(2), &info(2), &mut out);
    p.handle_timeout(ms(2500), &mut out);
    assert_eq!(
        channel_events(&mut out),
        [
            (ms(10), 0, 1, SwitchReason::Command),
            (ms(2000), 1, 0, SwitchReason::ResetCommunication),
            (
                ms(2500),
                0,
                1,
                SwitchReason::ResetEvaluation {
                    node: NodeId::must(3)
                }
            ),
        ]
    );
}

#[test]
fn error_counter_plus_four_minus_one_reaching_the_threshold_switches() {
    let cfg = Cia3026Config {
        error_threshold: 10,
        eval_power_on: Duration::ZERO,
        ..Default::default()
    };
    let mut p = Cia3026::new(cfg);
    let mut out = Outbox::new();
    boot(&mut p, ms(0), &mut out);
    let fail = PortStatus::TxFailed(ErrorCause::NoAck);
    p.on_status(ms(1), 0, fail, &mut out);
    p.on_status(ms(2), 0, PortStatus::TxOk, &mut out);
    p.on_status(ms(3), 1, fail, &mut out); // redundant channel: not counted
    assert_eq!(p.error_counter(), 3);
    p.on_status(ms(4), 0, fail, &mut out);
    assert_eq!(p.error_counter(), 7);
    assert_eq!(p.active_channel(), 0);
    p.on_status(ms(5), 0, fail, &mut out);
    assert_eq!(p.error_counter(), 10);
    assert!(p.default_disabled());
    assert_eq!(
        channel_events(&mut out),
        [(ms(5), 0, 1, SwitchReason::TxErrors { counter: 10 })]
    );
    // Disabled: heartbeats on default do not switch back until a success re-enables it.
    for t in 6..9 {
        p.on_rx(ms(t), 0, &hb(2), &info(2), &mut out);
    }
    assert_eq!(p.active_channel(), 1);
    p.on_status(ms(10), 0, PortStatus::TxOk, &mut out);
    assert!(!p.default_disabled());
    p.on_rx(ms(11), 0, &hb(2), &info(2), &mut out);
    assert_eq!(p.active_channel(), 0);
}

#[test]
fn max_transmit_delay_counts_missing_outcomes_as_errors() {
    let cfg = Cia3026Config {
        error_threshold: 8,
        eval_power_on: Duration::ZERO,
        max_tx_delay: Duration::from_millis(5),
        ..Default::default()
    };
    let mut p = Cia3026::new(cfg);
    let mut out = Outbox::new();
    boot(&mut p, ms(0), &mut out);
    p.on_status(ms(1), 0, PortStatus::TxOk, &mut out); // the boot-up
    let h = Health::new(Default::default(), Duration::from_millis(10));
    let pdo = Frame::from_array(Id::Standard(0x181), [1]);
    let none = FrameInfo { heartbeat: None };
    p.route_tx(ms(10), &pdo, &none, &h, &mut out);
    p.route_tx(ms(11), &pdo, &none, &h, &mut out);
    assert_eq!(p.poll_timeout(), Some(ms(15)));
    p.handle_timeout(ms(16), &mut out);
    assert_eq!(p.error_counter(), 8);
    assert_eq!(
        channel_events(&mut out),
        [(ms(16), 0, 1, SwitchReason::TxErrors { counter: 8 })]
    );
    // The late outcomes do not pop anything else.
    p.on_status(ms(20), 0, PortStatus::TxOk, &mut out);
    p.on_status(ms(20), 0, PortStatus::TxOk, &mut out);
    assert_eq!(p.error_counter(), 6);
}

#[test]
fn indication_makes_the_channel_active_without_answering() {
    let mut p = Cia3026::new(Cia3026Config::default());
    let mut out = Outbox::new();
    boot(&mut p, ms(0), &mut out);
    let none = FrameInfo { heartbeat: None };
    assert_eq!(
        p.on_rx(ms(5), 1, &indicate_active(), &none, &mut out),
        RxRoute::Ignore
    );
    assert_eq!(p.active_channel(), 1);
    assert!(out.pop_frame().is_none());
    assert_eq!(
        channel_events(&mut out),
        [(ms(5), 0, 1, SwitchReason::Indicated)]
    );
}
