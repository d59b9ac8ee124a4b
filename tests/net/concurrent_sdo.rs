//! Twenty nodes read at once through one handle, on a simulated 1 Mbit/s bus (tokio's paused
//! clock: the time is the bus's, exactly): the transfers share the bus rather than wait for
//! each other, so together they take the bus time of their frames, twenty times one read's, and
//! nothing more. (On a real transport the round trips overlap too: the UDP figure is the python
//! tier's.)

use duocan::net::{NetOptions, Network, SIM_DEVICE_NAME};
use duocan::port::mem::{MemBus, MEM_BUS_BURST};
use std::time::Duration;

/// Bus time of one 8-byte frame with an 11-bit identifier at 1 Mbit/s (nominal, as the paced
/// in-memory bus counts it: 47 bits around 64 bits of data).
const FRAME: Duration = Duration::from_micros(111);

/// A segmented upload of the 21-byte device name: initiate and three segments, each a request
/// and an answer.
const FRAMES_PER_READ: u32 = 8;

#[tokio::test(start_paused = true)]
async fn twenty_nodes_read_at_once_take_the_bus_time_of_their_frames() {
    let bus = MemBus::with_bit_rate("sim", 1_000_000);
    let net = Network::simulated_on(&bus, 1..=20, NetOptions::default()).unwrap();
    // Boot-ups and first heartbeats out of the way.
    tokio::time::sleep(Duration::from_millis(50)).await;

    // One read alone: its frames fit in what the paced bus lets a sender run ahead, so it
    // takes no simulated time; its bus time is what it costs.
    assert_eq!(
        net.node(1).sdo().read_string(0x1008, 0).await.unwrap(),
        SIM_DEVICE_NAME
    );
    let one = FRAME * FRAMES_PER_READ;
    tokio::time::sleep(Duration::from_millis(10)).await;

    let start = tokio::time::Instant::now();
    let mut reads = tokio::task::JoinSet::new();
    for id in 1..=20u8 {
        let sdo = net.node(id).sdo();
        reads.spawn(async move { sdo.read_string(0x1008, 0).await });
    }
    while let Some(r) = reads.join_next().await {
        assert_eq!(r.unwrap().unwrap(), SIM_DEVICE_NAME);
    }
    let twenty = start.elapsed();
    let bus_time = FRAME * FRAMES_PER_READ * 20;
    println!(
        "one read: {one:?} of bus time; twenty at once: {twenty:?} ({:.1}× one), the bus time \
         of their {} frames being {bus_time:?} ({:.3}× it)",
        twenty.as_secs_f64() / one.as_secs_f64(),
        FRAMES_PER_READ * 20,
        twenty.as_secs_f64() / bus_time.as_secs_f64(),
    );
    // Twenty take the bus time of their frames (senders may run MEM_BUS_BURST ahead of the
    // bus), not twenty times a round trip plus the time between them.
    assert!(
        twenty <= bus_time && twenty + MEM_BUS_BURST + FRAME * 2 >= bus_time,
        "{twenty:?} for a bus time of {bus_time:?}"
    );
    net.close().await;
}

/// More reads at once than the client has sessions, most to absent node-IDs (a scan): each
/// start waits for a session without counting the wait against its own timeout, so the present
/// nodes answer though their reads started after others had timed out (found by the tool's
/// scan over UDP, which missed a node whose probe waited past its 100 ms for a session).
#[tokio::test(start_paused = true)]
async fn reads_beyond_the_sessions_wait_for_one_without_timing_out() {
    use duocan::sdo::SdoOptions;
    let bus = MemBus::with_bit_rate("sim", 1_000_000);
    let net = Network::simulated_on(&bus, 120..=127, NetOptions::default()).unwrap();
    tokio::time::sleep(Duration::from_millis(50)).await;
    let probe = SdoOptions::default().with_timeout(duocan::Duration::from_millis(100));
    let mut reads = tokio::task::JoinSet::new();
    for id in 1..=127u8 {
        let sdo = net.node(id).sdo().with_options(probe);
        reads.spawn(async move { (id, sdo.read::<u32>(0x1000, 0).await.is_ok()) });
    }
    let mut found = vec![];
    while let Some(r) = reads.join_next().await {
        let (id, ok) = r.unwrap();
        if ok {
            found.push(id);
        }
    }
    found.sort_unstable();
    assert_eq!(found, (120..=127).collect::<Vec<u8>>());
    net.close().await;
}

/// The same on a bus where nothing answers and nothing else is sent: a start waiting for a
/// session goes when another's result is taken, with no input to wake the door, so 40 reads
/// through 8 sessions end in 5 rounds of their timeout (they once waited for ever).
#[tokio::test(start_paused = true)]
async fn reads_beyond_the_sessions_end_on_a_silent_bus() {
    use duocan::sdo::SdoOptions;
    let bus = MemBus::with_bit_rate("silent", 1_000_000);
    let net = Network::open(bus.port()).unwrap();
    let probe = SdoOptions::default().with_timeout(duocan::Duration::from_millis(100));
    let start = tokio::time::Instant::now();
    let mut reads = tokio::task::JoinSet::new();
    for id in 1..=40u8 {
        let sdo = net.node(id).sdo().with_options(probe);
        reads.spawn(async move { sdo.read::<u32>(0x1000, 0).await.is_err() });
    }
    let all = async {
        while let Some(r) = reads.join_next().await {
            assert!(r.unwrap(), "nothing answers");
        }
    };
    tokio::time::timeout(Duration::from_secs(5), all)
        .await
        .expect("every read ends");
    assert!(
        start.elapsed() <= Duration::from_millis(520),
        "{:?}",
        start.elapsed()
    );
    net.close().await;
}
