//! A fixed latency on one port: receiving, every frame late by exactly that much, in order;
//! transmitting, its copies leave exactly that much after their twins, in order, and the device
//! hears of each when it ends on the wire.

use super::network;
use super::probe::{std_frame, Probe};
use crate::frame::instant::{Duration, Instant};
use crate::machine::PortStatus;
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

#[test]
fn a_slow_transmitter_sends_on_that_bus_exactly_the_latency_after_its_twin_and_in_order() {
    let (mut sim, b) = network(1, 2, RATE);
    let f = |i: u8| std_frame(0x181, &[i]);
    let x = sim.add_device("x", Probe::new(2), &b).unwrap();
    let rx = sim.add_device("rx", Probe::new(2), &b).unwrap();
    let lag = Duration::from_millis(7);
    sim.set_port_tx_latency(x.port(1), lag);
    assert_eq!(sim.port_tx_latency(x.port(1)), lag);
    assert_eq!(sim.port_tx_latency(x.port(0)), Duration::ZERO);
    // A frame on both ports every 2 ms: three or four wait in the slow controller at a time.
    for i in 0..20u8 {
        sim.at(ms(2 * i as u64), move |s| {
            let p = s.device_mut(x);
            p.send(0, f(i));
            p.send(1, f(i));
        });
    }
    sim.run_until(ms(100));
    let fast = sim.device(rx).rx_on(0);
    let slow = sim.device(rx).rx_on(1);
    assert_eq!(fast.len(), 20);
    let shifted: Vec<_> = fast.iter().map(|(t, fr)| (*t + lag, *fr)).collect();
    assert_eq!(slow, shifted);
    // Each outcome when its frame ended on the wire: the slow port's the latency later.
    let ok = |p| -> Vec<Instant> {
        let st = sim.device(x).status_on(p);
        st.iter()
            .filter(|(_, s)| *s == PortStatus::TxOk)
            .map(|(t, _)| *t)
            .collect()
    };
    let shifted: Vec<_> = ok(0).iter().map(|t| *t + lag).collect();
    assert_eq!(ok(1), shifted);
    assert_eq!(sim.port_stats(x.port(1)).tx_waited, 20);
    assert_eq!(sim.port_stats(x.port(0)).tx_waited, 0);
    // The receive side of the slow port is not affected.
    let back = sim.add_device("back", Probe::new(2), &b).unwrap();
    sim.at(ms(100), move |s| s.device_mut(back).send(1, f(99)));
    sim.run_until(ms(110));
    let got = sim.device(x).rx_on(1);
    assert_eq!(got.len(), 1);
    assert!(got[0].0 < ms(101), "received at {}", got[0].0);
}

#[test]
fn lowering_the_transmit_latency_never_lets_a_newer_frame_overtake() {
    let (mut sim, b) = network(1, 1, RATE);
    let f = |i: u8| std_frame(0x181, &[i]);
    let x = sim.add_device("x", Probe::new(1), &[b[0]]).unwrap();
    let rx = sim.add_device("rx", Probe::new(1), &[b[0]]).unwrap();
    let port = x.port(0);
    sim.set_port_tx_latency(port, Duration::from_millis(20));
    for i in 0..10u8 {
        sim.at(ms(5 * i as u64), move |s| s.device_mut(x).send(0, f(i)));
    }
    // At 22 ms the frames sent at 5..20 ms wait (due 25..40 ms); from now on no latency.
    sim.at(ms(22), move |s| s.set_port_tx_latency(port, Duration::ZERO));
    sim.run_until(ms(100));
    let got = sim.device(rx).rx_on(0);
    let order: Vec<u8> = got.iter().map(|(_, fr)| fr.data()[0]).collect();
    assert_eq!(order, (0..10).collect::<Vec<u8>>());
    // Frames 5.. (handed over at 25.. ms) waited behind frame 4 (due 40 ms), then went out
    // one after the other; none before its older neighbour.
    let t4 = got[4].0;
    assert!(t4 >= ms(40) && t4 < ms(41), "frame 4 at {t4}");
    assert!(got[5].0 > t4, "frame 5 at {} before frame 4", got[5].0);
    assert_eq!(sim.port_stats(port).tx_waited, 5);
}

#[test]
fn a_drifting_stamp_clock_moves_the_stamps_not_the_frames() {
    let (mut sim, b) = network(1, 1, RATE);
    let f = std_frame(0x181, &[1]);
    let x = sim.add_device("x", Probe::new(1), &[b[0]]).unwrap();
    let d = sim.add_device("d", Probe::new(1), &[b[0]]).unwrap();
    let port = d.port(0);
    // 2,000 ppm fast from 10 ms, 1,000 ppm slow from 110 ms, resynchronised at 160 ms.
    sim.at(ms(10), move |s| s.set_port_stamp_drift(port, 2_000));
    sim.at(ms(110), move |s| s.set_port_stamp_drift(port, -1_000));
    sim.at(ms(160), move |s| s.set_port_stamp_drift(port, 0));
    for i in 0..5 {
        sim.at(ms(50 * i), move |s| s.device_mut(x).send(0, f));
    }
    sim.run_until(ms(300));
    let e = crate::sim::timing::frame_duration(&f, RATE).as_micros();
    assert!(e < 500, "{e}");
    // Frames reach the device when they end on the wire, whatever its clock.
    let wire: Vec<u64> = (0..5).map(|i| 50_000 * i + e).collect();
    let got: Vec<u64> = sim
        .device(d)
        .rx_on(0)
        .iter()
        .map(|r| r.0.as_micros())
        .collect();
    assert_eq!(got, wire);
    // Stamps: exact before the drift; then 2 µs per ms since 10 ms (the frame's own
    // microseconds add less than one); at 110 ms 200 µs ahead, then 1 µs per ms less;
    // exact again after the resynchronisation.
    let stamps: Vec<u64> = sim.device(d).stamps.iter().map(|t| t.as_micros()).collect();
    assert_eq!(
        stamps,
        [wire[0], wire[1] + 80, wire[2] + 180, wire[3] + 160, wire[4]]
    );
    assert_eq!(
        sim.port_stamp_clock(port),
        crate::sim::StampClock::default()
    );
}
