//! A network with a tap: every frame its port receives and sends is recorded, and the
//! decoder reads the record back as CANopen lines.

use duocan::capture::candump::read_log;
use duocan::capture::decode::Decoder;
use duocan::capture::recorder::{Filter, Recorder};
use duocan::net::{NetOptions, Network, SIM_VENDOR};
use std::sync::Arc;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_tapped_network_records_what_its_port_carries() {
    let path = std::env::temp_dir().join(format!("duocan-net-tap-{}.log", std::process::id()));
    let rec = Arc::new(
        Recorder::with_epoch(1_700_000_000_000_000)
            .port_names(["sim"])
            .candump(Filter::All, std::fs::File::create(&path).unwrap()),
    );
    let opts = NetOptions::default().with_tap(rec.clone());
    assert!(format!("{opts:?}").contains("tap: true"));
    let net = Network::simulated([5], opts).unwrap();
    let vendor: u32 = net.node(5).sdo().read(0x1018, 1).await.unwrap();
    assert_eq!(vendor, SIM_VENDOR);
    net.close().await;
    rec.flush().unwrap();
    let text = std::fs::read(&path).unwrap();
    let mut dec = Decoder::new();
    let lines: Vec<String> = read_log("tap", &text[..])
        .map(|e| {
            let e = e.unwrap();
            assert_eq!(e.interface, "sim");
            dec.decode(e.record.frame().unwrap()).to_string()
        })
        .collect();
    // The request the network sent and the answer it received, both through the tap.
    let answer = format!("node 5 SDO upload 0x1018:01 = {SIM_VENDOR:#010x}");
    let at = |l: &str| lines.iter().position(|x| x == l);
    let (req, ans) = (at("node 5 SDO upload 0x1018:01 request"), at(&answer));
    assert!(req.is_some() && ans > req, "{lines:#?}");
    assert_eq!(rec.errors(), 0);
}
