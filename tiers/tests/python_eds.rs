//! python `canopen` reads and writes a duocan node by the names of the EDS duocan exported for
//! it: `network.add_node(node_id, "duocan.eds")`, then `node.sdo["Producer heartbeat time"].raw`.
//!
//! Needs a private network namespace with loopback multicast and `DUOCAN_PYTHON` pointing at a
//! python with `python-can`, `canopen` and `msgpack`: `.ci/tier-python.sh` sets up both.

#[path = "common/peer.rs"]
mod peer;
#[path = "../../tests/common/runtime.rs"]
mod rt;

use duocan::eds::{export_eds, find, ExportOptions};
use duocan::od::{Access, DataType, DefaultValue, Limit, ObjectDef, ObjectDictionary};
use duocan::port::udp::{UdpBusConfig, UdpPort};
use duocan::runtime::Runtime;
use peer::{group, Peer};
use std::collections::BTreeSet;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn python_canopen_reads_a_duocan_node_by_the_names_of_its_exported_eds() {
    let mut n = rt::sdo_node(0x36, false, 700, &[]);
    let od = n.od_mut();
    od.insert_all(&[
        ObjectDef::u16(0x2100, 0, Access::Rw, 100)
            .limits(Limit::Unsigned(10), Limit::Unsigned(1000))
            .named("Speed"),
        ObjectDef::new(0x2101, 0, DataType::Integer16)
            .default(DefaultValue::Signed(-5))
            .named("Offset"),
        ObjectDef::new(0x2102, 0, DataType::Real32)
            .default(DefaultValue::Real(0.5))
            .named("Gain"),
        ObjectDef::u32(0x2103, 0, Access::Ro, 0)
            .default(DefaultValue::NodeIdPlus(0x4000))
            .named("Node-relative"),
    ])
    .unwrap();
    // The names python will use are the ones duocan finds too.
    assert_eq!(find(n.od(), "speed"), Ok((0x2100, 0)));
    let text = export_eds(n.od(), &ExportOptions::default().with_vendor_name("duocan")).unwrap();
    let objects: BTreeSet<u16> = {
        let mut s = BTreeSet::new();
        n.od().for_each(&mut |e| {
            s.insert(e.def.index);
        });
        s
    };
    let path = std::env::temp_dir().join(format!("duocan-python-{}.eds", std::process::id()));
    std::fs::write(&path, &text).unwrap();

    let cfg = UdpBusConfig::numbered(6);
    let d = Runtime::new(rt::single(n))
        .name("duocan-eds")
        .port(UdpPort::open(cfg.clone()).expect("open the UDP bus (inside unshare -n?)"))
        .spawn()
        .unwrap();
    d.boot().await.unwrap();
    let (g, p) = group(&cfg);
    let file = path.display().to_string();
    let mut peer = Peer::spawn(&["eds", "0x36", &file, &g, &p]).await;
    assert_eq!(
        peer.expect("NAMES", 5).await,
        format!("NAMES {}", objects.len()),
        "python's dictionary has every object of the file"
    );
    for (name, value) in [
        ("Producer heartbeat time", "700".to_string()),
        ("Identity object/Vendor-ID", 0x1234.to_string()),
        ("Identity object/Product code", 0x36.to_string()),
        ("Manufacturer device name", "duocan".into()),
        ("Value", 0xCAFE_F00Du32.to_string()),
        ("Text", "duocan node over a real bus".into()),
        ("Consumer heartbeat time/3", "0".into()),
        ("Speed", "100".into()),
        ("Offset", "-5".into()),
        ("Gain", "0.5".into()),
        ("Node-relative", 0x4036.to_string()),
    ] {
        peer.send_line(&format!("read\t{name}")).await;
        assert_eq!(
            peer.expect("VALUE", 5).await,
            format!("VALUE\t{name}\t{value}")
        );
    }
    peer.send_line("write\tSpeed\t500").await;
    peer.expect("WROTE\tSpeed", 5).await;
    assert_eq!(d.read(0x2100, 0).await.unwrap(), 500u16.to_le_bytes());
    peer.send_line("write\tText\twritten by name").await;
    peer.expect("WROTE\tText", 5).await;
    assert_eq!(d.read(0x2001, 0).await.unwrap(), b"written by name");
    // The limit the EDS states is the node's: python's write of 2000 is refused with
    // 0x06090031 (value too high), which python prints in decimal.
    peer.send_line("write\tSpeed\t2000").await;
    assert_eq!(
        peer.expect("ERROR", 5).await,
        format!("ERROR write\tSpeed\t2000 SdoAbortedError({})", 0x0609_0031)
    );
    peer.stop().await;
    d.shutdown().await;
    let _ = std::fs::remove_file(&path);
}
