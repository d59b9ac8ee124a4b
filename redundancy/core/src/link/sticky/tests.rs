use super::*;
use StickyVerdict::{Deliver, Dropped, Switched, Unproven};

const T: Duration = Duration::from_millis(40);

fn ms(x: u64) -> Instant {
    Instant::from_millis(x)
}
fn node(n: u8) -> StreamKey {
    StreamKey::Node(NodeId::must(n))
}
fn id(raw: u16) -> StreamKey {
    StreamKey::Id {
        id: Id::Standard(raw),
        remote: false,
    }
}
fn at(m: &mut StickyMerger, t: u64, port: usize, key: StreamKey, trust: Trust) -> StickyVerdict {
    m.arrive_at(ms(t), ms(t), port, key, trust)
}

#[test]
fn streams_are_senders_or_identifiers() {
    let hb = Frame::from_array(Id::Standard(0x705), [5]);
    assert_eq!(StreamKey::of(&hb, NodeId::new(5)), node(5));
    let sync = Frame::from_array(Id::Standard(0x080), []);
    assert_eq!(StreamKey::of(&sync, None), id(0x080));
    let rtr = Frame::remote(Id::Standard(0x080), 0).unwrap();
    assert_ne!(StreamKey::of(&rtr, None), id(0x080));
    // Identifiers of both formats with the same number are different streams.
    let ext = StreamKey::Id {
        id: Id::Extended(0x080),
        remote: false,
    };
    assert_ne!(id_key(ext), id_key(id(0x080)));
    assert_ne!(id_key(StreamKey::of(&rtr, None)), id_key(id(0x080)));
}

/// Unchanged repeats (SYNC every 2 ms) with one bus's copies stamped 5 ms later, two periods
/// and a half: each occurrence once, from the early bus; nothing needs matching.
#[test]
fn repeats_faster_than_the_lag_come_once() {
    for (late, lag) in [(1usize, 5_000u64), (0, 5_000)] {
        let mut m = StickyMerger::new(T);
        let sync = id(0x080);
        let mut arrivals: Vec<(u64, usize)> = vec![];
        for k in 0..50u64 {
            arrivals.push((2_000 * k + 1, 1 - late));
            arrivals.push((2_000 * k + 1 + lag, late));
        }
        arrivals.sort();
        let mut delivered = vec![];
        for (t, p) in arrivals {
            if m.arrive(Instant::from_micros(t), p, sync) == Deliver {
                delivered.push(p);
            }
        }
        assert_eq!(delivered, vec![1 - late; 50]);
        assert_eq!(m.bound(sync), Some(1 - late));
        assert_eq!((m.stats().switches, m.stats().dropped), (0, 50));
    }
}

#[test]
fn a_switch_needs_more_than_the_timeout_of_silence() {
    let mut m = StickyMerger::new(T);
    let n = node(3);
    assert_eq!(at(&mut m, 100, 1, n, Trust::Trusted), Deliver);
    assert_eq!(m.bound(n), Some(1));
    // Exactly the timeout after the last frame on the bound bus: still dropped.
    assert_eq!(at(&mut m, 140, 0, n, Trust::Trusted), Dropped);
    assert_eq!(
        m.arrive_at(ms(141), Instant::from_micros(140_001), 0, n, Trust::Trusted),
        Switched
    );
    assert_eq!(m.bound(n), Some(0));
    // The old bus's copies, however late its reader hands them over, are dropped.
    assert_eq!(m.arrive_at(ms(500), ms(130), 1, n, Trust::Trusted), Dropped);
    // Other streams are not concerned.
    assert_eq!(m.bound(node(4)), None);
    assert_eq!(m.stats().switches, 1);
}

/// A stamp later than `now` is taken as `now`; a port beyond 1 is delivered, counted.
#[test]
fn stamps_after_now_and_bad_ports() {
    let mut m = StickyMerger::new(T);
    let n = node(9);
    assert_eq!(m.arrive_at(ms(10), ms(900), 0, n, Trust::Trusted), Deliver);
    // Stamped 10 ms, not 900 ms: 60 ms is a switch.
    assert_eq!(at(&mut m, 60, 1, n, Trust::Trusted), Switched);
    assert_eq!(at(&mut m, 61, 7, n, Trust::Trusted), Deliver);
    assert_eq!(m.stats().bad_port, 1);
    assert_eq!(m.stats().delivered, 3);
}

/// A port back from a fault leads nothing while the other port works, whatever the stream;
/// it does once the other port has carried nothing for a timeout.
#[test]
fn a_port_not_trusted_yet_leads_only_when_the_other_is_silent() {
    let mut m = StickyMerger::new(T);
    let (n, quiet) = (node(2), node(3));
    assert_eq!(at(&mut m, 0, 0, quiet, Trust::Trusted), Deliver);
    assert_eq!(at(&mut m, 10, 0, n, Trust::Trusted), Deliver);
    // Port 1 carries an old frame of a stream port 0 has been silent about for long, and a
    // stream port 0 never carried: both dropped, port 0 works.
    for t in [100, 200] {
        assert_eq!(at(&mut m, t, 0, n, Trust::Trusted), Deliver);
        assert_eq!(at(&mut m, t + 1, 1, quiet, Trust::Unproven), Unproven);
        assert_eq!(at(&mut m, t + 2, 1, node(4), Trust::Unproven), Unproven);
    }
    assert_eq!(m.bound(node(4)), None);
    // Port 0 dies after 200 ms: 40 ms later port 1 leads.
    assert_eq!(at(&mut m, 240, 1, quiet, Trust::Unproven), Unproven);
    assert_eq!(at(&mut m, 241, 1, quiet, Trust::Unproven), Switched);
    assert_eq!(at(&mut m, 242, 1, node(4), Trust::Unproven), Deliver);
    assert_eq!(m.stats().unproven, 5);
}

/// A failed bound port does not switch its streams at once: the other bus's copies within the
/// timeout may be those of what it delivered last.
#[test]
fn a_failed_bound_port_is_left_after_the_timeout_as_a_silent_one() {
    let mut m = StickyMerger::new(T);
    let n = node(6);
    assert_eq!(at(&mut m, 0, 0, n, Trust::Trusted), Deliver);
    m.set_failed(0, true);
    assert_eq!(at(&mut m, 30, 1, n, Trust::Trusted), Dropped);
    assert_eq!(at(&mut m, 41, 1, n, Trust::Trusted), Switched);
}

#[test]
fn identifiers_beyond_the_table_share_a_stream_until_entries_are_done() {
    let mut m = StickyMerger::new(T);
    for i in 0..ID_STREAMS as u16 {
        assert_eq!(at(&mut m, 1, 0, id(0x200 + i), Trust::Trusted), Deliver);
    }
    assert_eq!(m.id_streams(), ID_STREAMS);
    // Port 1 has received nothing after them: none is done, a new identifier shares.
    let (a, b) = (id(0x600), id(0x601));
    assert_eq!(at(&mut m, 2, 1, a, Trust::Trusted), Deliver);
    assert_eq!(m.bound(a), Some(1));
    assert_eq!(m.bound(b), Some(1), "the shared stream");
    assert_eq!(at(&mut m, 3, 0, b, Trust::Trusted), Dropped);
    assert_eq!(at(&mut m, 4, 1, b, Trust::Trusted), Deliver);
    assert_eq!(m.stats().overflow, 3);
    assert_eq!(m.stats().evicted, 0);
    // Port 0 passes the shared stream's last frame (4 ms) by more than the timeout: the shared
    // stream is done and starts over. No entry is (port 1 has not passed their 1 ms by a
    // timeout): the new identifier shares again.
    assert_eq!(at(&mut m, 50, 0, id(0x200), Trust::Trusted), Deliver);
    assert_eq!(at(&mut m, 51, 1, id(0x602), Trust::Trusted), Deliver);
    assert_eq!(m.stats().overflow, 4);
    assert_eq!(m.bound(id(0x602)), Some(1));
    // Port 1 passes the entries' frames (1 ms) and port 0 the shared stream's (51 ms) by
    // more than the timeout: the oldest entry makes room, the shared stream starts over.
    assert_eq!(at(&mut m, 60, 1, id(0x603), Trust::Trusted), Deliver);
    assert_eq!(m.stats().overflow, 5, "the shared stream is not done yet");
    assert_eq!(at(&mut m, 101, 0, id(0x200), Trust::Trusted), Deliver);
    assert_eq!(at(&mut m, 102, 0, id(0x604), Trust::Trusted), Deliver);
    assert_eq!(m.stats().overflow, 5);
    assert_eq!(m.stats().evicted, 1);
    assert_eq!(m.bound(id(0x604)), Some(0));
    assert_eq!(m.id_streams(), ID_STREAMS);
    // Its copy on port 1 is its own stream's: dropped.
    assert_eq!(at(&mut m, 103, 1, id(0x604), Trust::Trusted), Dropped);
}

/// A failed port passes nothing, but nothing can come from it either: a stream bound to the
/// other port is done at once.
#[test]
fn entries_bound_against_a_failed_port_are_done() {
    let mut m = StickyMerger::new(T);
    m.set_failed(1, true);
    for i in 0..ID_STREAMS as u16 {
        assert_eq!(at(&mut m, 1, 0, id(0x200 + i), Trust::Trusted), Deliver);
    }
    assert_eq!(at(&mut m, 2, 0, id(0x700), Trust::Trusted), Deliver);
    assert_eq!((m.stats().evicted, m.stats().overflow), (1, 0));
}

#[test]
fn a_step_back_keeps_the_silence_left() {
    let mut m = StickyMerger::new(T);
    let n = node(7);
    assert_eq!(at(&mut m, 1_000, 0, n, Trust::Trusted), Deliver);
    m.step_back(Duration::from_millis(900));
    // 30 ms after its last frame in the new time line: not silent long enough.
    assert_eq!(at(&mut m, 130, 1, n, Trust::Trusted), Dropped);
    assert_eq!(at(&mut m, 141, 1, n, Trust::Trusted), Switched);
}
