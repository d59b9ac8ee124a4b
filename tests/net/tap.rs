//! A network with a tap: every frame its port receives and sends is recorded, and the
//! decoder reads the record back as CANopen lines.

use duocan::capture::candump::read_log;
use duocan::capture::decode::Decoder;
use duocan::capture::recorder::{Filter, Recorder};
use duocan::net::{NetOptions, Network, SIM_VENDOR};
use std::io::{self, Write};
use std::sync::{Arc, Mutex};

#[derive(Clone, Default)]
struct Shared(Arc<Mutex<Vec<u8>>>);

impl Write for Shared {
    fn write(&mut self, b: &[u8]) -> io::Result<usize> {
        self.0.lock().unwrap().extend_from_slice(b);
        Ok(b.len())
    }
    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_tapped_network_records_what_its_port_carries() {
    let log = Shared::default();
    let rec = Arc::new(
        Recorder::with_epoch(1_700_000_000_000_000)
            .port_names(["sim"])
            .candump(Filter::All, log.clone()),
    );
    let opts = NetOptions::default().with_tap(rec.clone());
    assert!(format!("{opts:?}").contains("tap: true"));
    let net = Network::simulated([5], opts).unwrap();
    let vendor: u32 = net.node(5).sdo().read(0x1018, 1).await.unwrap();
    assert_eq!(vendor, SIM_VENDOR);
    net.close().await;
    let text = log.0.lock().unwrap().clone();
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
