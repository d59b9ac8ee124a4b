//! A member's heartbeat producer time (0x1017) changed at run time by an SDO download, as a
//! service tool on the bus or the application through the master's own client does (CiA 301
//! lets it: the object is writable, the node beats at the new period at once; the consumers'
//! times stay). On the supervised network of `net.rs` (slaves beat every 20 ms, consumer time
//! 50 ms).

use crate::impostor::{inject, suspects};
use crate::net::*;
use duocan::{Duration, Frame, Id, Instant};

fn ms(x: u64) -> Instant {
    Instant::from_millis(x)
}

/// An expedited SDO download of `value` (u16) to 0x1017:00 of `node`, from a tool.
fn write_producer_time(node: u8, value: u16) -> Frame {
    let [lo, hi] = value.to_le_bytes();
    Frame::from_array(
        Id::Standard(0x600 + u16::from(node)),
        [0x2B, 0x17, 0x10, 0x00, lo, hi, 0, 0],
    )
}

/// A tool writes `ms` to the active board's producer time at 1 s: it beats at that period
/// from then on, and nothing else happens for 2 s (no suspicion, no reset, no switch-over).
fn new_producer_time(ms_: u16) {
    let mut n = SupNet::new(Params::default());
    let buses = n.buses;
    inject(
        &mut n,
        &buses,
        write_producer_time(a(0), ms_),
        Some(ms(1_000)),
        Duration::ZERO,
    );
    n.sim.run_until(ms(3_000));
    let beats = crate::impostor::arrivals(&n, 0, 0x700 + u16::from(a(0)));
    let late = beats.iter().filter(|t| **t > ms(1_100)).count() as u64;
    let expected = 1_900 / u64::from(ms_);
    assert!(
        late.abs_diff(expected) <= 1,
        "{late} heartbeats, {expected} expected"
    );
    assert_eq!(suspects(&n, STRONG), vec![]);
    assert_eq!(n.resets_in(ms(1_000), ms(3_000)), Vec::<u8>::new());
    assert_eq!(
        n.pair_roles(STRONG, 0).len(),
        1,
        "{:?}",
        n.pair_roles(STRONG, 0)
    );
}

/// Twice as fast as it was watched with: as two devices sharing its node-ID would beat.
/// (Before the layer followed the download, it was suspect at 1.110 s and reset.)
#[test]
fn a_member_beating_faster_after_a_new_producer_time_stays_in_service() {
    new_producer_time(10);
}

/// Slower, still within the consumer time (50 ms).
#[test]
fn a_member_beating_slower_after_a_new_producer_time_stays_in_service() {
    new_producer_time(40);
}
