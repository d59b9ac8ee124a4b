//! The safety gateway on the host: the same no_std code as on the board, on mock controllers,
//! against a duocan interlocking master on two buses and a scripted track-circuit board.
//!
//! ```text
//! cargo run -p safety-gateway --example gateway_host
//! ```
//!
//! Prints what the interlocking sees of the four track circuits while the field board sends
//! them as an SRDO, sends a stuck-at code and a pair with a corrupted inverse, bus 1 breaks and
//! is repaired, and the field board falls silent. Exits non-zero if the interlocking ever reads a track circuit clear that
//! the field board did not report clear.

#[path = "../tests/harness/mod.rs"]
mod harness;

use duocan::profile::railway::safety::TrackCircuit;
use duocan::Frame;
use harness::{wires, Bench};
use safety_gateway::mirror::field_pair;
use safety_gateway::mock::{MockCan, Wire};
use safety_gateway::{Event, Storage, TRACKS};
use static_cell::StaticCell;

static STORAGE: Storage<MockCan<'static>> = Storage::new();
static WIRES: StaticCell<[Wire; 3]> = StaticCell::new();

fn show(b: &Bench, what: &str) {
    let view: String = (1..=TRACKS)
        .map(|k| match b.interlocking().state(k) {
            Some(TrackCircuit::Clear) => format!(" {k}:clear   "),
            Some(TrackCircuit::Occupied) => format!(" {k}:OCCUPIED"),
            None => format!(" {k}:-       "),
        })
        .collect();
    println!("{:>8}  {view}   {what}", b.now.to_string());
}

fn main() {
    let mut b = Bench::new(&STORAGE, wires(&WIRES));
    println!(
        "gateway: {} bytes (node with dictionary {} bytes) in static storage",
        std::mem::size_of::<safety_gateway::Gateway<MockCan<'static>>>(),
        std::mem::size_of::<safety_gateway::Board>()
    );
    show(&b, "power-on: boot-up on both buses, pre-operational");
    b.run_ms(200);
    b.start_gateway();
    b.run_ms(100);
    show(
        &b,
        "NMT start: nothing reported yet, so every track circuit is occupied",
    );
    for (k, code) in [(1, 0x55), (2, 0x55), (3, 0xAA), (4, 0x55)] {
        b.field_set(k, code);
    }
    show(&b, "field board reports 1, 2, 4 clear, 3 occupied");
    let v = b.sdo_read(0x6000, 1).expect("SDO read 0x6000:1");
    show(
        &b,
        &format!("SDO read of 0x6000 sub 1 over the 29-bit channel: {v:02X?}"),
    );
    b.run_ms(200);
    b.field_set(2, 0xFF);
    show(
        &b,
        "track 2 sent as 0xFF (stuck-at, in an intact pair): occupied",
    );
    b.run_ms(200);
    b.field_set(2, 0x55);
    let [normal, inverted] = field_pair(b.field_codes);
    let mut bytes = inverted.data().to_vec();
    bytes[0] ^= 1;
    b.field_send(&normal);
    b.field_send(&Frame::new(inverted.id(), &bytes).expect("frame"));
    b.settle();
    show(
        &b,
        "a pair whose inverse has a flipped bit: the SRDO trips, all occupied",
    );
    b.run_ms(100);
    show(&b, "the next field cycle restores them");
    b.wires[0].cut(true);
    b.run_ms(1_000);
    show(
        &b,
        "bus 1 broken for a second: states keep arriving over bus 2",
    );
    b.wires[0].cut(false);
    b.run_ms(500);
    show(&b, "bus 1 repaired");
    b.field_stop();
    b.run_ms(400);
    show(
        &b,
        "field board silent for 400 ms (SCT 300 ms): all occupied",
    );

    for e in &b.gateway_events {
        if let Event::Track(c) = e {
            println!(
                "{:>8}  track {} {:?} -> {:?} ({:?})",
                c.at.to_string(),
                c.track,
                c.from,
                c.to,
                c.cause
            );
        }
    }
    let lost = b
        .master_node_events()
        .iter()
        .filter(|(_, k)| matches!(k, duocan::NodeEventKind::HeartbeatTimeout { .. }))
        .count();
    println!("heartbeat timeouts at the interlocking: {lost}");
    // Every frame the interlocking accepted as clear had a field report of clear behind it.
    let bad = b
        .interlocking()
        .seen
        .iter()
        .filter(|(_, _, s)| s.is_err())
        .count();
    if lost != 0
        || bad != 0
        || (1..=TRACKS).any(|k| b.interlocking().state(k) != Some(TrackCircuit::Occupied))
    {
        eprintln!("gateway_host: FAILED: {lost} heartbeat timeouts, {bad} refused frames");
        std::process::exit(1);
    }
    println!("gateway_host: OK");
}
