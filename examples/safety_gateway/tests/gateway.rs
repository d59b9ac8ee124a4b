//! The gateway against a duocan interlocking master on two mock buses and a scripted field
//! board on a third (its track circuits as an SRDO every 100 ms), in simulated time.

mod harness;

use duocan::cia304::srdo::consumer::SrdoCause;
use duocan::node::NodeEventKind as K;
use duocan::profile::railway::safety::TrackCircuit::{Clear, Occupied};
use duocan::{AbortCode, Duration, Frame, Instant, NmtState};
use duocan_redundancy::{LinkEventKind, PortState};
use harness::{view, wires, Bench};
use safety_gateway::dictionary::{FIELD_TIMEOUT, HEARTBEAT_MS, PRODUCT, REFRESH_MS, VENDOR};
use safety_gateway::mirror::field_pair;
use safety_gateway::mock::{MockCan, Wire};
use safety_gateway::{Cause, Event, Storage, TrackChange, NODE_ID, TRACKS};
use static_cell::StaticCell;

fn ms(v: u64) -> Instant {
    Instant::from_millis(v)
}

static STORAGE: Storage<MockCan<'static>> = Storage::new();
static WIRES: StaticCell<[Wire; 3]> = StaticCell::new();

fn gateway_changes(b: &Bench) -> Vec<TrackChange> {
    b.gateway_events
        .iter()
        .filter_map(|e| match e {
            Event::Track(c) => Some(*c),
            _ => None,
        })
        .collect()
}

#[test]
fn the_gateway_mirrors_checked_track_states_to_the_interlocking_over_both_buses() {
    let mut b = Bench::new(&STORAGE, wires(&WIRES));
    assert_eq!(
        STORAGE
            .install(
                &harness::NETWORK,
                {
                    let w: &'static [Wire; 3] =
                        Box::leak(Box::new([Wire::new(), Wire::new(), Wire::new()]));
                    let [a, _] = w[0].ends();
                    let [c, _] = w[1].ends();
                    let [d, _] = w[2].ends();
                    [a, c, d]
                },
                Instant::ZERO
            )
            .err(),
        Some(safety_gateway::SetupError::AlreadyInstalled),
        "one gateway per storage"
    );

    // Boot-up: the gateway's boot-up message went out on both buses, and the master (whose
    // dual-bus layer merges the two copies) saw it once.
    let boots: Vec<_> = b
        .master_node_events()
        .into_iter()
        .filter(|(_, k)| matches!(k, K::BootUp { node } if *node == NODE_ID))
        .collect();
    assert_eq!(boots, [(Instant::ZERO, K::BootUp { node: NODE_ID })]);
    assert!(b.gateway.bus_stats(0).unwrap().tx_frames >= 1);
    assert!(b.gateway.bus_stats(1).unwrap().tx_frames >= 1);
    assert_eq!(b.gateway.node().nmt_state(), NmtState::PreOperational);

    // Pre-operational: heartbeats, no state changes (PDOs need operational).
    b.run_until(ms(100));
    assert!(b.interlocking().seen.is_empty());
    let tx0 = b.gateway.bus_stats(0).unwrap().tx_frames;
    b.run_until(ms(300));
    let beats = b.gateway.bus_stats(0).unwrap().tx_frames - tx0;
    assert_eq!(
        beats,
        (200 / HEARTBEAT_MS) as u32,
        "one heartbeat per {HEARTBEAT_MS} ms on bus 1"
    );
    assert_eq!(
        b.gateway.bus_stats(1).unwrap().tx_frames,
        b.gateway.bus_stats(0).unwrap().tx_frames
    );

    // NMT start: every track circuit is reported occupied (nothing heard from the field yet).
    b.start_gateway();
    assert_eq!(b.gateway.node().nmt_state(), NmtState::Operational);
    b.run_until(ms(300 + REFRESH_MS as u64));
    assert!(
        (1..=TRACKS).all(|k| b.interlocking().state(k) == Some(Occupied)),
        "{:?}",
        view(&b)
    );
    assert!(
        b.interlocking().seen.iter().all(|(_, _, s)| s.is_ok()),
        "every frame passes its CRC"
    );

    // The field board reports: clear tracks reach the interlocking at the same instant.
    b.run_until(ms(500));
    for (k, code) in [(1, 0x55), (2, 0x55), (3, 0xAA), (4, 0x55)] {
        b.field_set(k, code);
    }
    for k in [1, 2, 4] {
        assert_eq!(b.interlocking().since(k, Clear), Some(ms(500)), "track {k}");
    }
    assert_eq!(b.interlocking().state(3), Some(Occupied));
    assert_eq!(b.gateway.track(1), Some((Clear, Cause::Report)));

    // SDO over the railway 29-bit channel: the mirrored state, the identity, and the aborts.
    assert_eq!(b.sdo_read(0x6000, 1).unwrap(), [0x55]);
    assert_eq!(b.sdo_read(0x6000, 3).unwrap(), [0xAA]);
    assert_eq!(b.sdo_read(0x1018, 1).unwrap(), VENDOR.to_le_bytes());
    assert_eq!(b.sdo_read(0x1018, 2).unwrap(), PRODUCT.to_le_bytes());
    let e = b.sdo_read(0x6000, 9).unwrap_err();
    assert_eq!(e.code(), Some(AbortCode::NO_SUB_INDEX), "{e}");
    let e = b.sdo_write(0x6000, 1, &[0x55]).unwrap_err();
    assert_eq!(e.code(), Some(AbortCode::READ_ONLY), "{e}");
    assert!(e.to_string().contains("node 20"), "{e}");

    // A stuck-at code in an intact pair: that track circuit, and only it, goes occupied.
    b.run_until(ms(1_000));
    b.field_set(2, 0xFF);
    assert_eq!(b.interlocking().since(2, Occupied), Some(ms(1_000)));
    assert_eq!(b.interlocking().state(1), Some(Clear));
    assert!(matches!(
        b.gateway.track(2),
        Some((Occupied, Cause::InvalidCode(_)))
    ));
    b.run_until(ms(1_050));
    b.field_set(2, 0x55);
    assert_eq!(b.interlocking().since(2, Clear), Some(ms(1_050)));

    // A pair whose inverse has one bit flipped on the wire: not each other's inverse, every
    // track circuit occupied at once, until the next cycle's intact pair.
    b.run_until(ms(1_130));
    let [normal, inverted] = field_pair(b.field_codes);
    let mut bytes = inverted.data().to_vec();
    bytes[2] ^= 0x01;
    b.field_send(&normal);
    b.field_send(&Frame::new(inverted.id(), &bytes).unwrap());
    b.settle();
    for k in [1, 2, 4] {
        assert_eq!(
            b.interlocking().since(k, Occupied),
            Some(ms(1_130)),
            "track {k}"
        );
    }
    assert_eq!(
        b.interlocking().since(3, Occupied),
        Some(ms(300)),
        "occupied all along"
    );
    let not_inverted = Cause::Srdo {
        cause: SrdoCause::NotInverted,
        measured: Duration::ZERO,
    };
    assert_eq!(b.gateway.track(1), Some((Occupied, not_inverted)));
    // The field board's cycle (every 100 ms from 500) restores them at 1 200.
    b.run_until(ms(1_200));
    assert_eq!(b.interlocking().since(1, Clear), Some(ms(1_200)));
    assert_eq!(b.interlocking().state(3), Some(Occupied));

    // Bus 1 breaks for a second: everything keeps arriving over bus 2, the heartbeat is never
    // lost, and both dual-bus layers fail bus 1 and take it back after the repair.
    b.run_until(ms(1_500));
    b.wires[0].cut(true);
    b.run_until(ms(2_000));
    b.field_set(4, 0xAA);
    assert_eq!(b.interlocking().since(4, Occupied), Some(ms(2_000)));
    b.run_until(ms(2_500));
    b.wires[0].cut(false);
    b.field_set(4, 0x55);
    assert_eq!(b.interlocking().since(4, Clear), Some(ms(2_500)));
    b.run_until(ms(3_500));
    let lost: Vec<_> = b
        .master_node_events()
        .into_iter()
        .filter(|(_, k)| matches!(k, K::HeartbeatTimeout { .. }))
        .collect();
    assert!(lost.is_empty(), "no heartbeat lost: {lost:?}");
    let bus1: Vec<_> = b
        .master_link_events()
        .into_iter()
        .filter_map(|e| match e.kind {
            LinkEventKind::Port { port: 0, to, .. } => Some((e.at, to)),
            _ => None,
        })
        .collect();
    // Bus 1 went silent at 1 500 (its last frame): failed at the silence limit, 150 ms later;
    // back to ok once frames flow again after the repair.
    let failed = bus1
        .iter()
        .find(|(_, s)| *s == PortState::Failed)
        .map(|x| x.0);
    assert_eq!(failed, Some(ms(1_650)), "{bus1:?}");
    let ok = bus1
        .iter()
        .rev()
        .find(|(_, s)| *s == PortState::Ok)
        .map(|x| x.0);
    assert!(
        ok.is_some_and(|t| t > ms(2_500) && t <= ms(2_750)),
        "{bus1:?}"
    );
    assert_eq!(bus1.last().map(|x| x.1), Some(PortState::Ok), "{bus1:?}");
    assert!(b.gateway.device().link.health().port(0).state() == PortState::Ok);
    assert!(b.wires[0].lost() > 0);

    // The field board dies: every track circuit goes occupied exactly one SCT (the field
    // timeout, 300 ms) after its last pair. Then the timeout is raised over SDO.
    let last = ms(3_500);
    // Two trips so far: at 300 ms (no field board yet) and the corrupted pair.
    assert_eq!(b.gateway.field_stats().trips, 2);
    b.field_stop();
    b.run_until(ms(4_000));
    let sct = Duration::from_millis(300);
    for k in [1, 2, 4] {
        assert_eq!(
            b.interlocking().since(k, Occupied),
            Some(last + sct),
            "track {k}"
        );
        let silent = Cause::Srdo {
            cause: SrdoCause::CycleTime,
            measured: sct,
        };
        assert_eq!(b.gateway.track(k).unwrap().1, silent);
    }
    let fs = b.gateway.field_stats();
    assert_eq!(fs.trips, 3);
    assert_eq!(fs.last_trip.map(|f| f.at), Some(last + sct));
    b.sdo_write(FIELD_TIMEOUT, 0, &500u16.to_le_bytes())
        .unwrap();
    // Still silent: the next trip at 4 100 checks again with the new SCT.
    b.run_until(ms(4_100));
    b.field_set(1, 0x55);
    assert_eq!(b.interlocking().since(1, Clear), Some(ms(4_100)));
    b.field_stop();
    b.run_until(ms(5_000));
    assert_eq!(b.interlocking().since(1, Occupied), Some(ms(4_600)));

    // Cyclic refresh: the interlocking hears every track every REFRESH_MS while nothing changes.
    let n = b
        .interlocking()
        .seen
        .iter()
        .filter(|(t, k, _)| *k == 3 && *t > ms(4_000) && *t <= ms(5_000))
        .count();
    assert_eq!(n, (1_000 / REFRESH_MS) as usize);

    // The gateway's own record agrees, and nothing was dropped.
    let changes = gateway_changes(&b);
    assert!(changes
        .iter()
        .any(|c| c.track == 2 && matches!(c.cause, Cause::InvalidCode(_))));
    assert_eq!(b.gateway.events_dropped(), 0);
    let fs = b.gateway.field_stats();
    assert_eq!((fs.trips, fs.invalid_codes, fs.errors), (5, 1, 0));
    // Intact pairs: nine sent on a change (four at 500, then 1 000, 1 050, 2 000, 2 500 and
    // 4 100) and thirty by the cycle (every 100 ms from 600 to 3 500); the corrupted one is not.
    assert_eq!(fs.pairs, 9 + 30);
}
