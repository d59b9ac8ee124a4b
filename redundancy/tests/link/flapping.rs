//! Flapping buses with cyclic traffic: bus 2 going down and up every 1, 5 or 50 ms, or both
//! buses in antiphase (one up while the other is down, swapping every 50 ms). The other bus, or
//! whichever is up, carries every frame: every application frame and every SYNC arrives exactly
//! once, a repeat is never taken for a twin.

use super::sim::*;
use duocan::{Duration, Instant};

const SLAVES: u8 = 3;
const FROM: Instant = Instant::from_millis(500);
const UNTIL: Instant = Instant::from_millis(3500);
const STOP: Instant = Instant::from_millis(4000);

/// Bus 2 (and bus 1 in antiphase, if `both`) flips every `half` from 0.5 s to 3.5 s.
fn flap(half: Duration, both: bool) -> Net {
    let mut net = network(11, SLAVES, active_active(), STOP);
    stop_sync(&mut net, STOP);
    let (b1, b2) = (net.buses[0], net.buses[1]);
    let mut t = FROM;
    let mut down = true;
    while t < UNTIL {
        net.sim.at(t, move |sim| {
            if down {
                sim.bus_down(b2);
                if both {
                    sim.bus_up(b1);
                }
            } else {
                sim.bus_up(b2);
                if both {
                    sim.bus_down(b1);
                }
            }
        });
        down = !down;
        t += half;
    }
    net.sim.at(UNTIL, move |sim| {
        sim.bus_up(b1);
        sim.bus_up(b2);
    });
    net.sim.run_until(STOP + Duration::from_millis(300));
    net
}

fn assert_exact(net: &Net) {
    net.assert_application_exact();
    net.assert_sync_exact();
}

#[test]
fn bus_2_flapping_every_millisecond_costs_nothing() {
    assert_exact(&flap(Duration::from_millis(1), false));
}

#[test]
fn bus_2_flapping_every_5_ms_costs_nothing() {
    assert_exact(&flap(Duration::from_millis(5), false));
}

#[test]
fn bus_2_flapping_every_50_ms_costs_nothing() {
    assert_exact(&flap(Duration::from_millis(50), false));
}

#[test]
fn both_buses_flapping_in_antiphase_every_50_ms_cost_nothing() {
    assert_exact(&flap(Duration::from_millis(50), true));
}
