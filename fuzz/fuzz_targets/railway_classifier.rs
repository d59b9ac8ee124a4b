//! The railway 29-bit profile's classifier: a node table from the input, then frames on
//! identifiers the input makes (railway functions at the table's addresses and ports, raw
//! 29-bit and 11-bit identifiers, remote frames, valid and corrupt CRC payloads). Every answer
//! of the profile (`IdProfile::classify`, `decode`) and of the dual-bus classifier
//! (`heartbeat_of`, `sender`, `function`, `same_value`) must agree with the table and with the
//! identifiers the profile itself builds; payloads that check re-encode to the same frame; and
//! a dual-bus layer over the profile with two A/B pairs takes the frames on both ports without a
//! panic or unbounded output.
#![no_main]

mod common;

use common::{advance, port_status, MAX_PER_STEP};
use duocan::profile::railway::{
    compose, split, DeviceAddress, Payload, RailFunction, RailwayProfile,
};
use duocan::profile::{IdProfile, ProfileFrame};
use duocan::{BusLink, Duration, Frame, Id, Instant, NodeId};
use duocan_redundancy::{DualBus, DualBusConfig, FrameClassifier, LinkMode, Member};
use libfuzzer_sys::fuzz_target;

fn check_table(p: &RailwayProfile) {
    for (n, a) in p.iter() {
        assert_eq!(p.node_at(a), Some(n), "{a:?} names {n:?}");
        assert_eq!(p.address(n), Some(a));
        assert_eq!(a.port(), 0, "the table holds board addresses");
    }
}

fn check_frame(p: &RailwayProfile, f: &Frame) {
    let id = f.id();
    let remote = f.is_remote();
    match p.classify(id, remote) {
        Some(ProfileFrame::Nmt) => assert_eq!(id, p.nmt()),
        Some(ProfileFrame::Heartbeat(n)) => assert_eq!(id, p.heartbeat(n)),
        Some(ProfileFrame::Guarding(n)) => assert_eq!(id, p.guarding(n)),
        Some(ProfileFrame::Emcy(n)) => assert_eq!(id, p.emcy(n)),
        // ProfileFrame may grow: nothing to check for what this target does not know.
        _ => {}
    }
    if let Some(d) = p.decode(id) {
        assert_eq!(compose(d.function.code(), d.address), id);
        assert_eq!(d.node, p.node_at(d.address));
    }
    if let Some(n) = p.heartbeat_of(f) {
        assert!(!remote && f.dlc() == 1);
        assert_eq!(p.heartbeat(n), id);
    }
    let board = split(id).map(|(_, a)| a.board_address());
    if let Some(n) = p.sender(f) {
        assert!(!remote);
        assert_eq!(p.address(n), board, "the sender sits at the frame's board");
    }
    if let Some((n, key)) = p.function(f) {
        assert!(!remote);
        assert_eq!(p.address(n), board);
        let port = split(id).map_or(0, |(_, a)| a.port());
        assert_eq!(key >> 24, u32::from(port & 0xF), "the key names the port");
    }
    assert!(p.same_value(f, f), "a frame agrees with itself");
    if let Ok(payload) = Payload::decode(f) {
        assert_eq!(
            payload.encode(id),
            *f,
            "a payload that checks re-encodes to its frame"
        );
    }
}

/// An identifier from 4 input bytes: mostly a railway function at a table address.
fn identifier(p: &RailwayProfile, b: [u8; 4]) -> Id {
    let entries: Vec<DeviceAddress> = p.iter().map(|(_, a)| a).collect();
    match b[0] % 4 {
        0 | 1 if !entries.is_empty() => {
            let f = RailFunction::ALL[usize::from(b[1]) % RailFunction::ALL.len()];
            let a = entries[usize::from(b[2]) % entries.len()];
            let a = if b[3] & 0x80 == 0 {
                a
            } else {
                a.with_port(b[3] & 0xF)
            };
            compose(f.code(), a)
        }
        2 => Id::Standard(u16::from_le_bytes([b[1], b[2]]) & 0x7FF),
        _ => Id::Extended(u32::from_le_bytes(b) & 0x1FFF_FFFF),
    }
}

fuzz_target!(|data: &[u8]| {
    let Some((&entries, rest)) = data.split_first() else {
        return;
    };
    let n = usize::from(entries % 9);
    if rest.len() < 4 * n {
        return;
    }
    let (table, frames) = rest.split_at(4 * n);
    let mut p = RailwayProfile::new();
    for e in table.chunks_exact(4) {
        let node = NodeId::new(e[0] & 0x7F);
        let raw = u32::from_le_bytes([e[1], e[2], e[3] & 0x0F, 0]);
        match (node, DeviceAddress::from_raw(raw)) {
            (Some(node), Ok(a)) if e[3] & 0x80 == 0 => drop(p.add(node, a)),
            (Some(node), _) => drop(p.remove(node)),
            _ => {}
        }
        check_table(&p);
    }
    // The first four nodes of the table as two A/B pairs on a dual bus over the profile.
    let nodes: Vec<NodeId> = p.iter().map(|(n, _)| n).collect();
    let mut link: DualBus<RailwayProfile> = DualBus::with_classifier(
        DualBusConfig::with_guard_period(LinkMode::ActiveActive, Duration::from_millis(20)),
        p.clone(),
    );
    for pair in nodes.chunks_exact(2).take(2) {
        let _ = link.add_pair(pair[0], pair[1], Some(Member::A));
    }
    let mut now = Instant::ZERO;
    let mut previous: Option<Frame> = None;
    for c in frames.chunks_exact(14) {
        let [kind, i0, i1, i2, i3, dlc, step, d @ ..] = c else {
            continue;
        };
        now = advance(now, *step);
        let id = identifier(&p, [*i0, *i1, *i2, *i3]);
        let frame = match kind % 4 {
            0 => Frame::remote(id, dlc % 9).ok(),
            // A payload that checks.
            1 => Payload::new(
                u16::from_le_bytes([d[0], d[1]]),
                d[2],
                &d[3..3 + usize::from(dlc % 4)],
            )
            .ok()
            .map(|pl| pl.encode(id)),
            _ => Frame::new(id, &d[..usize::from(dlc % 8)]).ok(),
        };
        let Some(f) = frame else { continue };
        check_frame(&p, &f);
        if let Some(prev) = previous {
            assert_eq!(
                p.same_value(&f, &prev),
                p.same_value(&prev, &f),
                "symmetric"
            );
        }
        previous = Some(f);
        for _ in 0..64 {
            match link.poll_timeout() {
                Some(t) if t <= now => link.handle_timeout(now),
                _ => break,
            }
        }
        if kind & 0x40 != 0 {
            link.handle_port_status(now, usize::from(kind >> 7), port_status(*dlc, d[0]));
        }
        match kind >> 4 & 3 {
            0 => drop(link.handle_rx(now, 0, &f)),
            1 => drop(link.handle_rx(now, 1, &f)),
            _ => {
                let _ = link.handle_rx(now, 0, &f);
                let _ = link.handle_rx(now + Duration::from_micros(u64::from(*step)), 1, &f);
            }
        }
        let mut k = 0;
        while link.poll_transmit().is_some()
            || link.poll_port_request().is_some()
            || link.poll_event().is_some()
        {
            k += 1;
            assert!(k <= MAX_PER_STEP, "unbounded layer output");
        }
    }
});
