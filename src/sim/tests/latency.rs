//! A fixed receive latency on one port: every frame late by exactly that much, in order.

use super::network;
use super::probe::{std_frame, Probe};
use crate::frame::instant::{Duration, Instant};
use crate::sim::{FaultRates, TraceRecord};

const RATE: u32 = 500_000;

fn ms(n: u64) -> Instant {
    Instant::from_millis(n)
}

#[test]
fn a_lagging_port_gets_every_frame_exactly_the_latency_later_and_in_order() {
    let (mut sim, b) = network(1, 1, RATE);
    let f = |i: u8| std_frame(0x181, &[i]);
    let x = sim.add_device("x", Probe::new(1), &[b[0]]).unwrap();
    let slow = sim.add_device("slow", Probe::new(1), &[b[0]]).unwrap();
    let fast = sim.add_device("fast", Probe::new(1), &[b[0]]).unwrap();
    let lag = Duration::from_millis(12);
    sim.set_port_latency(slow.port(0), lag);
    assert_eq!(sim.port_latency(slow.port(0)), lag);
    assert_eq!(sim.port_latency(fast.port(0)), Duration::ZERO);
    // One frame every 5 ms: a backlog of two or three frames is always on its way.
    for i in 0..20u8 {
        sim.at(ms(5 * i as u64), move |s| s.device_mut(x).send(0, f(i)));
    }
    sim.run_until(ms(200));
    let on_time = sim.device(fast).rx_on(0);
    let late = sim.device(slow).rx_on(0);
    assert_eq!(on_time.len(), 20);
    let shifted: Vec<_> = on_time.iter().map(|(t, fr)| (*t + lag, *fr)).collect();
    assert_eq!(late, shifted);
    // Not a random fault: nothing drawn, nothing traced, nothing counted as delayed.
    assert!(!sim.trace().iter().any(|r| matches!(r, TraceRecord::Rx(_))));
    assert_eq!(sim.port_stats(slow.port(0)).rx_delayed, 0);
    assert_eq!(sim.port_stats(slow.port(0)).rx, 20);
}

#[test]
fn lowering_the_latency_lets_newer_frames_wait_for_the_backlog_and_never_overtake() {
    let (mut sim, b) = network(1, 1, RATE);
    let f = |i: u8| std_frame(0x181, &[i]);
    let x = sim.add_device("x", Probe::new(1), &[b[0]]).unwrap();
    let slow = sim.add_device("slow", Probe::new(1), &[b[0]]).unwrap();
    let fast = sim.add_device("fast", Probe::new(1), &[b[0]]).unwrap();
    let port = slow.port(0);
    sim.set_port_latency(port, Duration::from_millis(20));
    for i in 0..10u8 {
        sim.at(ms(5 * i as u64), move |s| s.device_mut(x).send(0, f(i)));
    }
    // At 22 ms the frames sent at 5..20 ms are on their way (due 25..40 ms); from now on 1 ms.
    sim.at(ms(22), move |s| {
        s.set_port_latency(port, Duration::from_millis(1))
    });
    sim.run_until(ms(100));
    let on_time = sim.device(fast).rx_on(0);
    let late = sim.device(slow).rx_on(0);
    assert_eq!(on_time.len(), 10);
    let wire: Vec<Instant> = on_time.iter().map(|(t, _)| *t).collect();
    let want: Vec<(Instant, _)> = on_time
        .iter()
        .enumerate()
        .map(|(i, (t, fr))| {
            let at = match i {
                0..=4 => *t + Duration::from_millis(20),
                // Sent at 25, 30, 35 ms: due 1 ms later, but behind the backlog, whose last
                // frame (sent at 20 ms) is handed over at wire[4] + 20 ms: all at that instant.
                5..=7 => wire[4] + Duration::from_millis(20),
                _ => *t + Duration::from_millis(1),
            };
            (at, *fr)
        })
        .collect();
    assert_eq!(late, want);
    assert!(late.windows(2).all(|w| w[0].0 <= w[1].0));
}

#[test]
fn latency_and_random_delay_add_up() {
    let (mut sim, b) = network(5, 1, RATE);
    let x = sim.add_device("x", Probe::new(1), &[b[0]]).unwrap();
    let slow = sim.add_device("slow", Probe::new(1), &[b[0]]).unwrap();
    let fast = sim.add_device("fast", Probe::new(1), &[b[0]]).unwrap();
    let (lag, max) = (Duration::from_millis(3), Duration::from_micros(500));
    sim.set_port_latency(slow.port(0), lag);
    sim.set_port_faults(slow.port(0), FaultRates::NONE.with_delay(1.0, max));
    for i in 0..30u8 {
        sim.at(ms(2 * i as u64), move |s| {
            s.device_mut(x).send(0, std_frame(0x200, &[i]))
        });
    }
    sim.run_until(ms(100));
    let on_time = sim.device(fast).rx_on(0);
    let late = sim.device(slow).rx_on(0);
    assert_eq!(late.len(), 30);
    for ((t_wire, a), (t_rx, b)) in on_time.iter().zip(&late) {
        assert_eq!(a, b);
        assert!(
            *t_rx > *t_wire + lag && *t_rx <= *t_wire + lag + max,
            "{t_wire} {t_rx}"
        );
    }
    assert_eq!(sim.port_stats(slow.port(0)).rx_delayed, 30);
}
