//! The merger's memory with one bus dead for an hour of simulated traffic: constant.
//!
//! A master sends SYNC every 10 ms; 20 nodes answer with a TPDO carrying a counter, and send a
//! heartbeat every 100 ms (a frame that repeats unchanged). Bus 2 is dead: every arrival is
//! unmatched and kept until the horizon (eight windows), never evicted.

use duocan::{Duration, Frame, Id, Instant};
use duocan_redundancy::link::merge::{Merger, Trust, Verdict};

#[test]
fn one_bus_dead_for_an_hour_keeps_memory_constant() {
    let trust = Trust::Trusted;
    const WINDOW: Duration = Duration::from_millis(10);
    let mut m: Merger<1024> = Merger::new(WINDOW);
    let sync = Frame::from_array(Id::Standard(0x80), []);
    let mut sent = 0u64;
    let mut delivered = 0u64;
    let mut peak_per_minute = vec![];
    let mut peak = 0usize;
    let cycles = 3_600 * 100; // one hour of 10 ms cycles
    for cycle in 0..cycles as u64 {
        let t0 = cycle * 10_000;
        let mut arrive = |t: u64, f: &Frame| {
            sent += 1;
            let t = Instant::from_micros(t);
            if m.arrive_at(t, t, 0, f, trust).0 == Verdict::Deliver {
                delivered += 1;
            }
            peak = peak.max(m.len());
        };
        arrive(t0, &sync);
        for n in 1..=20u16 {
            let t = t0 + 150 * n as u64;
            let counter = (cycle as u32).to_le_bytes();
            arrive(t, &Frame::from_array(Id::Standard(0x180 + n), counter));
            if cycle % 10 == n as u64 % 10 {
                arrive(t + 70, &Frame::from_array(Id::Standard(0x700 + n), [5]));
            }
        }
        if cycle % 6_000 == 5_999 {
            peak_per_minute.push(peak);
            peak = 0;
        }
    }
    assert_eq!(
        delivered, sent,
        "with one bus dead every arrival is a first copy"
    );
    let s = m.stats();
    assert_eq!(
        s.evicted, 0,
        "records leave at the horizon, never by overflow"
    );
    assert_eq!(s.duplicates, 0);
    // 80 ms of traffic: 8 SYNCs + 160 TPDOs + 16 heartbeats, plus the ones on the edge.
    assert!(s.high_water <= 8 * 23 + 1, "high water {}", s.high_water);
    assert_eq!(peak_per_minute.len(), 60);
    let first = peak_per_minute[0];
    assert!(
        peak_per_minute.iter().all(|p| *p == first),
        "occupancy is the same every minute: {peak_per_minute:?}"
    );
    // Everything still held is forgotten at the horizon after the last arrival.
    m.expire(Instant::from_micros(cycles as u64 * 10_000 + 80_000));
    assert_eq!((m.len(), m.keys()), (0, 0));
    assert_eq!(m.stats().forgotten, sent);
}
