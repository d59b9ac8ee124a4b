//! The simulated redundant station behind `open_dual_named("sim-station")` (the tool's `--bus sim-station`):
//! every node answers, the pairs are as the supervisor leaves them, a mebibyte goes to a
//! DOMAIN and back, a program is downloaded, and `"sim-station:faults"` plays its script.

use duocan::cia302::program::image_id;
use duocan::net::{NetError, NetEvent, NetOptions, Network, TransferProgress, SIM_VENDOR};
use duocan::sdo::TransferMode;
use duocan::NmtState;
use duocan_redundancy::net::{
    open_dual_named, SIM_DOMAIN, SIM_DOMAIN_SIZE, SIM_FAULT_BUS_BACK, SIM_FAULT_BUS_CUT,
    SIM_FAULT_MASTER_BACK, SIM_FAULT_MASTER_STOPS, SIM_FAULT_MEMBER_STOPS, SIM_FAULT_PERIOD,
    SIM_PAIRS, SIM_PROGRAM_NODE, SIM_SLAVES,
};
use duocan_redundancy::RedundantError;
use std::time::Duration;

async fn sleep_ms(ms: u64) {
    tokio::time::sleep(Duration::from_millis(ms)).await;
}

fn sim() -> Network {
    open_dual_named("sim-station", NetOptions::default()).unwrap()
}

/// A byte pattern that differs along its length.
fn pattern(len: usize, seed: u8) -> Vec<u8> {
    (0..len)
        .map(|i| (i as u32).wrapping_mul(2_654_435_761).to_le_bytes()[3] ^ seed)
        .collect()
}

#[tokio::test(start_paused = true)]
async fn every_node_answers_and_the_pairs_are_as_the_supervisor_leaves_them() {
    let net = sim();
    // The masters configure their pairs first.
    sleep_ms(2000).await;
    for id in [0x01, 0x02] {
        let r = net.node(id).sdo().read::<u32>(0x1018, 1).await;
        assert!(r.is_ok(), "master {id:#04x}: {r:?}");
    }
    let members = SIM_PAIRS.iter().flat_map(|&(a, b)| [a, b]);
    for id in members.chain(SIM_SLAVES) {
        let vendor: u32 = net.node(id).sdo().read(0x1018, 1).await.unwrap();
        assert_eq!(vendor, SIM_VENDOR, "node {id:#04x}");
    }
    for (a, b) in SIM_PAIRS {
        assert_eq!(
            net.node(a).state().await.unwrap(),
            Some(NmtState::Operational),
            "active member {a:#04x}"
        );
        assert_eq!(
            net.node(b).state().await.unwrap(),
            Some(NmtState::PreOperational),
            "standby member {b:#04x}"
        );
    }
    let ports = net.ports().await.unwrap();
    let names: Vec<&str> = ports.iter().map(|p| p.name.as_str()).collect();
    assert_eq!(names, ["sim-bus1", "sim-bus2"]);
    assert!(ports.iter().all(|p| p.state == "ok"), "{ports:?}");
    for id in [0x01, 0x02, 0x10, 0x50, 0x05] {
        assert_eq!(
            net.heard_on(id).await.unwrap(),
            Some([true, true].into()),
            "{id:#04x}"
        );
    }
    net.close().await;
    assert!(matches!(
        net.node(5).sdo().read::<u32>(0x1018, 1).await,
        Err(NetError::Closed)
    ));
}

#[tokio::test(start_paused = true)]
async fn a_mebibyte_goes_to_a_domain_and_back() {
    let net = sim();
    let sdo = net.node(6).sdo().with_mode(TransferMode::Block);
    let blob = pattern(SIM_DOMAIN_SIZE, 7);
    let mut sent = Vec::new();
    let n = sdo
        .write_from(SIM_DOMAIN, 0, &blob[..], Some(blob.len() as u64), |p| {
            sent.push(p)
        })
        .await
        .unwrap();
    assert_eq!(n, SIM_DOMAIN_SIZE as u64);
    assert_eq!(sent.last().map(|p| p.done), Some(n));
    let mut back = Vec::new();
    let n = sdo.read_to(SIM_DOMAIN, 0, &mut back, |_| {}).await.unwrap();
    assert_eq!(n, SIM_DOMAIN_SIZE as u64);
    assert!(
        back == blob,
        "{} bytes back, not the ones written",
        back.len()
    );
    net.close().await;
}

#[tokio::test(start_paused = true)]
async fn a_program_is_downloaded_and_runs() {
    let net = sim();
    // Larger than one whole transfer of the network (64 KiB): the image streams.
    let image = pattern(200 * 1024, 3);
    let mut seen: Vec<TransferProgress> = Vec::new();
    let node = net.node(SIM_PROGRAM_NODE);
    let report = node
        .download_program(&image, |p| seen.push(p))
        .await
        .unwrap();
    assert_eq!(report.node.raw(), SIM_PROGRAM_NODE);
    assert_eq!(report.bytes, image.len());
    assert_eq!(report.identification, image_id(&image));
    let id: u32 = node.sdo().read(0x1F56, 1).await.unwrap();
    assert_eq!(id, image_id(&image), "the new program runs");
    assert!(seen.len() > 3, "progress along the way");
    assert_eq!(seen.last().map(|p| p.done), Some(image.len() as u64));
    // A node without program download: the first step is refused, and nothing is started.
    let e = net
        .node(6)
        .download_program(&image, |_| {})
        .await
        .unwrap_err();
    let NetError::Program(e) = e else {
        panic!("{e}")
    };
    assert_eq!(e.step, duocan::master::ProgramStep::Stop);
    assert_eq!(e.node.raw(), 6);
    net.close().await;
}

#[tokio::test(start_paused = true)]
async fn sim_faults_plays_a_bus_a_member_and_a_master_failover() {
    let net = open_dual_named("sim-station:faults", NetOptions::default()).unwrap();
    let mut events = net.events();
    // One period and the start of the next.
    let end = tokio::time::Instant::now() + Duration::from_millis(12_500);
    let mut seen = Vec::new();
    while let Ok(Some(e)) = tokio::time::timeout_at(end, events.next()).await {
        seen.push(e);
    }
    let at_ms = |e: &NetEvent| e.at().map(|t| t.as_micros() / 1000).unwrap_or(0);
    // Bus 1 fails at the cut (the port goes down) and is ok again after it is plugged back.
    let bus1: Vec<(u64, &str)> = seen
        .iter()
        .filter_map(|e| match e {
            NetEvent::PortState { port: 0, to, .. } => Some((at_ms(e), to.as_str())),
            _ => None,
        })
        .collect();
    let cut = SIM_FAULT_BUS_CUT.as_millis();
    let back = SIM_FAULT_BUS_BACK.as_millis();
    let failed: Vec<u64> = bus1
        .iter()
        .filter(|(_, s)| *s == "failed")
        .map(|(t, _)| *t)
        .collect();
    // (While cut, each re-initialisation attempt is recovering, then failed again.)
    let next = SIM_FAULT_PERIOD.as_millis() + cut;
    let first_from = |t0: u64| failed.iter().copied().find(|t| *t >= t0);
    assert!(
        first_from(0).is_some_and(|t| (cut..cut + 50).contains(&t)),
        "{bus1:?}"
    );
    assert!(
        first_from(back).is_some_and(|t| (next..next + 50).contains(&t)),
        "the script repeats: {bus1:?}"
    );
    assert!(
        bus1.iter().any(|(t, s)| *s == "ok" && *t > back),
        "bus 1 ok again: {bus1:?}"
    );
    // The active member 0x10 stops: the standby 0x50 is started.
    let member = SIM_FAULT_MEMBER_STOPS.as_millis();
    let started = seen.iter().find(|e| {
        matches!(e, NetEvent::State { node, to: NmtState::Operational, .. } if node.raw() == 0x50)
    });
    let started = started.expect("0x50 operational");
    assert!(at_ms(started) > member, "{started}");
    // The active master 0x01 stops: heard on no bus after the reach timeout.
    let master = SIM_FAULT_MASTER_STOPS.as_millis();
    let gone = seen.iter().find(
        |e| matches!(e, NetEvent::Reach { node, heard, .. } if *heard == [false, false] && node.raw() == 0x01),
    );
    let gone = gone.expect("master 0x01 gone");
    assert!((master..master + 500).contains(&at_ms(gone)), "{gone}");
    // …and is heard again once powered.
    let again = seen.iter().find(|e| {
        matches!(e, NetEvent::Reach { node, heard, .. } if *heard == [true, true] && node.raw() == 0x01)
            && at_ms(e) > master
    });
    assert!(
        again.is_some_and(|e| at_ms(e) > SIM_FAULT_MASTER_BACK.as_millis()),
        "{again:?}"
    );
    net.close().await;
}

#[test]
fn a_name_without_two_ports_is_an_error_naming_it() {
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    rt.block_on(async {
        let Err(e) = open_dual_named("can0", NetOptions::default()) else {
            panic!("opened")
        };
        assert!(
            matches!(&e, RedundantError::Port { name, .. } if name == "can0"),
            "{e}"
        );
        assert!(e.to_string().contains("can0,can1"), "{e}");
    });
    // Outside a runtime: an error, not a panic.
    assert!(open_dual_named("sim-station", NetOptions::default()).is_err());
}

/// The station is `sim-station`; a bare `sim`, or another door's simulated network, is an error
/// that names the simulated networks there are and where each opens.
#[test]
fn sim_names_no_station() {
    for name in ["sim", "sim:faults", "sim-nodes", "sim-pairs"] {
        let Err(e) = open_dual_named(name, NetOptions::default()) else {
            panic!("{name} opened");
        };
        let text = e.to_string();
        assert!(
            text.contains("station on two buses is sim-station")
                && text.contains(duocan::net::SIM_NAMES),
            "{name}: {text}"
        );
    }
}
