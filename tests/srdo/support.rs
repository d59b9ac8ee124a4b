//! A producer node and a consumer node with one SRDO each, configured as a tool would.

use crate::common::{node, TestNode, Wire};
use duocan::cia304::srdo::config::{self, signature, SrdoConfig, SrdoMapping};
use duocan::cia304::srdo::objects;
use duocan::od::{Access, ObjectDef};
use duocan::pdo::MapEntry;
use duocan::{Instant, NmtCommand, NmtTarget, NodeId};

pub const PRODUCER: usize = 0;
pub const CONSUMER: usize = 1;
pub const SCT_MS: u16 = 50;
pub const REFRESH_MS: u16 = 20;
pub const SRVT_MS: u8 = 10;
/// The producer's node-ID: its SRDO starts 2 × 0.5 ms after entering operational.
pub const P_ID: u8 = 2;
pub const C_ID: u8 = 3;
/// Node 2's default SRDO identifiers.
pub const NORMAL: u16 = 0x103;
pub const INVERTED: u16 = 0x104;

pub fn ms(v: u64) -> Instant {
    Instant::from_millis(v)
}

/// Application objects: 0x6000 (u16) and 0x6001 (u8) carried plain, 0x6010/0x6011 their
/// inverse.
pub fn app() -> Vec<ObjectDef> {
    [0x6000, 0x6010]
        .iter()
        .flat_map(|&i| {
            [
                ObjectDef::u16(i, 0, Access::Rw, 0).mappable(),
                ObjectDef::u8(i + 1, 0, Access::Rw, 0).mappable(),
            ]
        })
        .collect()
}

/// The mapping both sides use: 0x6000 (16 bits) and 0x6001 (8 bits), with their inverses.
pub fn mapping() -> SrdoMapping {
    SrdoMapping::pairs(&[
        (MapEntry::new(0x6000, 0, 16), MapEntry::new(0x6010, 0, 16)),
        (MapEntry::new(0x6001, 0, 8), MapEntry::new(0x6011, 0, 8)),
    ])
}

/// A node with the application objects and SRDO 1 unconfigured.
pub fn bare(id: u8) -> TestNode {
    with_config(node(id, false))
}

/// `n` with the application objects and SRDO 1 unconfigured.
pub fn with_config(mut n: TestNode) -> TestNode {
    n.od_mut().insert_all(&app()).unwrap();
    n.od_mut().insert_all(&objects::srdo(1, NORMAL)).unwrap();
    n.od_mut().insert_all(&objects::shared::<4>()).unwrap();
    n
}

/// Gives SRDO 1 its configuration through the node as a tool would, checksum included, and
/// marks it valid. `sct_ms` is the refresh time for a producer.
pub fn configure(n: &mut TestNode, transmit: bool, sct_ms: u16, srvt_ms: u8, m: &SrdoMapping) {
    let cfg = SrdoConfig::new(transmit, sct_ms, srvt_ms, NORMAL, *m);
    n.configure_srdo(Instant::ZERO, 1, &cfg).unwrap();
    n.srdo_mark_valid(Instant::ZERO).unwrap();
}

/// Computes SRDO 1's checksum as a tool would, writes it, then marks the configuration valid.
pub fn seal(n: &mut TestNode) {
    let (p, m) = config::read(n.od(), 1).unwrap().unwrap();
    n.set(Instant::ZERO, config::CHECKSUMS, 1, signature(&p, &m))
        .unwrap();
    n.set(Instant::ZERO, config::CONFIG_VALID, 0, config::VALID)
        .unwrap();
}

/// Producer (node 2, refresh 20 ms) and consumer (node 3, SCT 50 ms, SRVT 10 ms), booted, not
/// started.
pub fn pair() -> Wire {
    let mut p = bare(P_ID);
    configure(&mut p, true, REFRESH_MS, SRVT_MS, &mapping());
    let mut c = bare(C_ID);
    configure(&mut c, false, SCT_MS, SRVT_MS, &mapping());
    let mut w = Wire::new(vec![p, c]);
    w.boot_all();
    w
}

/// Starts every node by broadcast NMT (sent by the producer node on the wire's behalf).
pub fn start_all(w: &mut Wire) {
    let f = duocan::nmt::command_frame(duocan::Id::Standard(0), NmtCommand::Start, NmtTarget::All);
    for n in &mut w.nodes {
        duocan::Machine::handle_frame(n, w.now, &f);
    }
    w.flush();
}

/// The producer's value: 0x6000 and 0x6001 with their inverses, as its application writes them.
pub fn produce(w: &mut Wire, a: u16, b: u8) {
    let now = w.now;
    let p = &mut w.nodes[PRODUCER];
    p.set(now, 0x6000, 0, a).unwrap();
    p.set(now, 0x6001, 0, b).unwrap();
    p.set(now, 0x6010, 0, !a).unwrap();
    p.set(now, 0x6011, 0, !b).unwrap();
}

/// What the consumer's dictionary holds: (0x6000, 0x6001, 0x6010, 0x6011).
pub fn consumed(w: &Wire) -> (u16, u8, u16, u8) {
    use duocan::od::ObjectDictionary;
    let od = w.nodes[CONSUMER].od();
    (
        od.get_value(0x6000, 0).unwrap(),
        od.get_value(0x6001, 0).unwrap(),
        od.get_value(0x6010, 0).unwrap(),
        od.get_value(0x6011, 0).unwrap(),
    )
}

pub fn node_id(id: u8) -> NodeId {
    NodeId::must(id)
}
