//! The gateway carries its mirrored track states to the interlocking as SRDO 1 (CiA 304): the
//! four codes on 0x127 and their inverses on 0x128, on both buses, every 50 ms. A bus cut does
//! not trip the interlocking's consumer; the gateway losing power trips it exactly SCT after
//! the last pair, its outputs at the safe values.

mod harness;

use duocan::cia304::srdo::consumer::SrdoCause;
use duocan::cia304::srdo::SrdoEvent;
use duocan::node::NodeEventKind as K;
use duocan::od::ObjectDictionary;
use duocan::{Duration, Instant};
use harness::*;
use safety_gateway::mock::Wire;
use safety_gateway::Storage;
use static_cell::StaticCell;

static STORAGE: Storage<safety_gateway::mock::MockCan<'static>> = Storage::new();
static WIRES: StaticCell<[Wire; 3]> = StaticCell::new();

const SCT_MS: u16 = 120;

fn ms(v: u64) -> Instant {
    Instant::from_millis(v)
}

fn srdo_events(b: &Bench) -> Vec<(Instant, SrdoEvent)> {
    b.master_node_events()
        .into_iter()
        .filter_map(|(t, k)| match k {
            K::Srdo(e) => Some((t, e)),
            _ => None,
        })
        .collect()
}

/// The master's copy: codes (0x6000) and inverses (0x6001) of the four track circuits.
fn received(b: &mut Bench) -> Vec<(u8, u8)> {
    let od = b.master_node().od();
    (1..=4u8)
        .map(|k| {
            let plain: u8 = od.get_value(0x6000, k).unwrap();
            let inverse: u8 = od.get_value(0x6001, k).unwrap();
            (plain, inverse)
        })
        .collect()
}

#[test]
fn track_states_travel_as_an_srdo_a_bus_cut_keeps_them_a_power_loss_trips_within_sct() {
    let mut b = Bench::new(&STORAGE, wires(&WIRES));
    b.start_gateway();
    b.watch_srdo(SCT_MS);
    b.field_on = true;
    for k in 1..=4 {
        b.field_set(k, if k % 2 == 1 { 0x55 } else { 0xAA });
    }
    b.run_until(ms(400));
    assert!(srdo_events(&b).is_empty(), "{:?}", srdo_events(&b));
    let states = [(0x55, 0xAA), (0xAA, 0x55), (0x55, 0xAA), (0xAA, 0x55)];
    assert_eq!(received(&mut b), states);

    // Bus 1 cut for 400 ms: the pairs keep coming over bus 2, nothing trips, a change arrives.
    b.wires[0].cut(true);
    b.run_until(ms(600));
    b.field_set(1, 0xAA);
    b.run_until(ms(800));
    b.wires[0].cut(false);
    b.run_until(ms(1_000));
    assert!(srdo_events(&b).is_empty(), "{:?}", srdo_events(&b));
    assert_eq!(received(&mut b)[0], (0xAA, 0x55));

    // The gateway loses power at 1 000 ms. Its SRDO went out 10 ms after its start at 0
    // (node-ID 20 × 0.5 ms) and every 50 ms since: the last pair at 960 ms, so the
    // interlocking is safe at 960 + SCT = 1 080 ms, 80 ms after the power loss.
    b.gateway_on = false;
    b.run_until(ms(1_400));
    let events = srdo_events(&b);
    assert_eq!(events.len(), 1, "{events:?}");
    let (at, e) = events[0];
    assert_eq!(
        e,
        SrdoEvent::SafeState {
            srdo: 1,
            cause: SrdoCause::CycleTime,
            measured: Duration::from_millis(SCT_MS as u64),
        }
    );
    // Within SCT of the power loss, and not before the last pair's SCT ran out.
    assert!(
        at > ms(1_000) && at <= ms(1_000) + Duration::from_millis(SCT_MS as u64),
        "{at}"
    );
    // The safe values: every track code 0 (neither clear nor occupied: no clear signal).
    assert_eq!(received(&mut b), [(0, 0xFF); 4]);
}
