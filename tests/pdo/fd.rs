//! PDOs on a CANopen FD network (feature `fd`): a TPDO of up to 64 bytes leaves as a CAN FD
//! frame of the next CAN FD length (padding 0xCC, as CiA 1301 pads), an RPDO of 64 bytes is written into the
//! dictionary, a short one raises EMCY 0x8210 (itself sent as a CAN FD frame), the 512-bit
//! limit of a mapping, and another node decoding that EMCY.

use duocan::emcy::{code as emcy_code, EmcyMessage};
use duocan::node::NodeEventKind as K;
use duocan::od::{comm, Access, DataType, DynamicDictionary, ObjectDef, ObjectDictionary};
use duocan::pdo::{params, PdoEvent};
use duocan::{AbortCode, FdFrame, Frame, Id, Instant, Machine, Node, NodeConfig, NodeId};

type FdNode = Node<DynamicDictionary>;

/// Objects 0x6100–0x6107, UNSIGNED64, mappable both ways.
fn values() -> Vec<ObjectDef> {
    (0..8)
        .map(|i| {
            ObjectDef::new(0x6100 + i, 0, DataType::Unsigned64)
                .mappable()
                .access(Access::Rw)
        })
        .collect()
}

/// Mapping entries of `bits` bits each of 0x6100, 0x6101, ….
fn entries(bits: &[u8]) -> Vec<u32> {
    bits.iter()
        .enumerate()
        .map(|(i, b)| (0x6100 + i as u32) << 16 | u32::from(*b))
        .collect()
}

/// Node `id` on an FD network (or not), operational at boot, with TPDO1 (0x180 + id, type 254)
/// mapping `tx` and RPDO1 (on `rx_cob`, type 255) mapping `rx`.
fn fd_node(id: u8, fd: bool, tx: &[u8], rx: &[u8], rx_cob: u32) -> FdNode {
    fd_node_typed(id, fd, tx, rx, rx_cob, 255)
}

/// [`fd_node`] with RPDO1 of transmission type `rx_type`.
fn fd_node_typed(id: u8, fd: bool, tx: &[u8], rx: &[u8], rx_cob: u32, rx_type: u8) -> FdNode {
    let nid = NodeId::must(id);
    let mut od = comm::standard_dictionary(id, comm::Identity::default());
    od.insert_all(&values()).unwrap();
    od.insert_all(&params::tpdo_comm(
        1,
        params::predefined_tpdo_cob(1),
        254,
        0,
        0,
    ))
    .unwrap();
    od.insert_all(&params::tpdo_mapping::<65>(1, &entries(tx)))
        .unwrap();
    od.insert_all(&params::rpdo_comm(
        1,
        duocan::od::DefaultValue::Unsigned(u64::from(rx_cob)),
        rx_type,
        0,
    ))
    .unwrap();
    od.insert_all(&params::rpdo_mapping::<65>(1, &entries(rx)))
        .unwrap();
    let cfg = NodeConfig::slave(nid)
        .with_auto_start(true)
        .with_consume_emcy(true)
        .with_fd(fd);
    Node::new(cfg, od)
}

fn fd_frames(n: &mut FdNode) -> Vec<FdFrame> {
    std::iter::from_fn(|| n.poll_transmit_fd()).collect()
}

fn classic_frames(n: &mut FdNode) -> Vec<Frame> {
    std::iter::from_fn(|| n.poll_transmit()).collect()
}

const EIGHT_U64: [u8; 8] = [64; 8];

#[test]
fn a_64_byte_tpdo_leaves_as_one_can_fd_frame_and_fills_the_other_nodes_dictionary() {
    let t0 = Instant::from_millis(1);
    let mut rx = fd_node(1, true, &[], &EIGHT_U64, 0x185);
    rx.boot(t0);
    let mut tx = fd_node(5, true, &EIGHT_U64, &[], 0x201);
    for i in 0..8u16 {
        let v = 0x0102_0304_0506_0708u64.wrapping_mul(u64::from(i) + 3);
        tx.set(t0, 0x6100 + i, 0, v).unwrap();
    }
    tx.boot(t0);
    let frames = fd_frames(&mut tx);
    assert_eq!(
        frames.len(),
        1,
        "entering operational sends TPDO1 (type 254) once"
    );
    let f = frames[0];
    assert_eq!((f.id(), f.len()), (Id::Standard(0x185), 64));
    assert!(
        classic_frames(&mut tx)
            .iter()
            .all(|c| c.id() != Id::Standard(0x185)),
        "not as a classic frame too"
    );
    rx.handle_frame_fd(t0, &f);
    for i in 0..8u16 {
        let want = 0x0102_0304_0506_0708u64.wrapping_mul(u64::from(i) + 3);
        assert_eq!(rx.od().get_value::<u64>(0x6100 + i, 0), Ok(want));
    }
    assert!(std::iter::from_fn(|| rx.poll_event())
        .any(|e| e.kind == K::Pdo(PdoEvent::RpdoReceived { pdo: 1 })));
}

#[test]
fn odd_lengths_go_in_the_next_can_fd_length_padded_with_0xcc() {
    let t0 = Instant::ZERO;
    // 3 + 13 + 64 + 64 + 16 = 160 bits = 20 bytes: a 20-byte frame.
    let mut tx = fd_node(5, true, &[3, 13, 64, 64, 16], &[], 0x201);
    for i in 0..5u16 {
        tx.set(t0, 0x6100 + i, 0, u64::MAX).unwrap();
    }
    tx.boot(t0);
    let f = fd_frames(&mut tx)[0];
    assert_eq!(f.len(), 20);
    assert!(f.data().iter().all(|b| *b == 0xFF));
    // 168 bits = 21 bytes: a 24-byte frame, bytes 21..24 0xCC.
    let mut tx = fd_node(5, true, &[3, 13, 64, 64, 24], &[], 0x201);
    for i in 0..5u16 {
        tx.set(t0, 0x6100 + i, 0, u64::MAX).unwrap();
    }
    tx.boot(t0);
    let f = fd_frames(&mut tx)[0];
    assert_eq!(f.len(), 24);
    assert_eq!(&f.data()[20..], &[0xFF, 0xCC, 0xCC, 0xCC]);
}

#[test]
fn a_classic_node_keeps_classic_frames_and_the_64_bit_limit() {
    let t0 = Instant::ZERO;
    let mut tx = fd_node(5, false, &[16, 8], &[], 0x201);
    tx.set(t0, 0x6100, 0, 0xBEEFu64).unwrap();
    tx.boot(t0);
    assert!(fd_frames(&mut tx).is_empty());
    let pdo: Vec<Frame> = classic_frames(&mut tx)
        .into_iter()
        .filter(|f| f.id() == Id::Standard(0x185))
        .collect();
    assert_eq!(pdo.len(), 1);
    assert_eq!(pdo[0].data(), &[0xEF, 0xBE, 0]);
    // 72 bits do not fit a classic PDO: the stored mapping is unusable.
    let mut tx = fd_node(5, false, &[64, 8], &[], 0x201);
    tx.boot(t0);
    assert_eq!(
        tx.tpdo_status(1).unwrap().error,
        Some(AbortCode::PDO_LENGTH)
    );
}

#[test]
fn mapping_writes_are_checked_against_512_bits() {
    let t0 = Instant::ZERO;
    let mut n = fd_node(5, true, &[], &[], 0x201);
    n.boot(t0);
    // TPDO1 invalid, then eight 64-bit entries and a ninth of 1 bit.
    n.set(t0, 0x1800, 1, 0x8000_0185u32).unwrap();
    for (s, e) in entries(&EIGHT_U64).iter().enumerate() {
        n.set(t0, 0x1A00, s as u8 + 1, *e).unwrap();
    }
    n.set(t0, 0x1A00, 9, 0x6100_0001u32).unwrap();
    assert_eq!(
        n.set(t0, 0x1A00, 0, 9u8),
        Err(AbortCode::PDO_LENGTH),
        "513 bits"
    );
    n.set(t0, 0x1A00, 0, 8u8).unwrap();
    n.set(t0, 0x1800, 1, 0x0000_0185u32).unwrap();
    assert_eq!(n.tpdo_status(1).unwrap().mapped_bits, 512);
}

#[test]
fn a_short_can_fd_rpdo_raises_emcy_0x8210_in_a_can_fd_frame_which_another_node_decodes() {
    let t0 = Instant::ZERO;
    let mut rx = fd_node(1, true, &[], &EIGHT_U64, 0x185);
    rx.boot(t0);
    let _ = fd_frames(&mut rx);
    let short = FdFrame::new(Id::Standard(0x185), &[0xAA; 48]).unwrap();
    rx.handle_frame_fd(t0, &short);
    assert!(std::iter::from_fn(|| rx.poll_event()).any(|e| e.kind
        == K::Pdo(PdoEvent::RpdoTooShort {
            pdo: 1,
            expected: 64,
            got: 48
        })));
    assert_eq!(rx.od().get_value::<u64>(0x6100, 0), Ok(0), "not applied");
    rx.handle_timeout(t0);
    let emcy: Vec<FdFrame> = fd_frames(&mut rx)
        .into_iter()
        .filter(|f| f.id() == Id::Standard(0x81))
        .collect();
    assert_eq!(emcy.len(), 1, "EMCY in its CAN FD form");
    let (msg, rest) = EmcyMessage::from_fd_frame(&emcy[0]).unwrap();
    assert_eq!(msg.code, emcy_code::PDO_LENGTH);
    assert!(rest.is_empty());
    // Another node on the network decodes it.
    let mut other = fd_node(7, true, &[], &[], 0x201);
    other.boot(t0);
    while other.poll_event().is_some() {}
    other.handle_frame_fd(t0, &emcy[0]);
    let got: Vec<K> = std::iter::from_fn(|| other.poll_event())
        .map(|e| e.kind)
        .collect();
    assert!(got.contains(&K::Emcy {
        node: NodeId::must(1),
        msg
    }));
    // A CAN FD EMCY shorter than 8 bytes is malformed.
    let bad = FdFrame::new(Id::Standard(0x81), &[0x10, 0x82]).unwrap();
    other.handle_frame_fd(t0, &bad);
    assert!(
        std::iter::from_fn(|| other.poll_event()).any(|e| matches!(e.kind, K::Malformed { .. }))
    );
}

#[test]
fn a_synchronous_64_byte_rpdo_takes_effect_at_the_sync() {
    let t0 = Instant::ZERO;
    let mut rx = fd_node_typed(1, true, &[], &EIGHT_U64, 0x185, 1);
    rx.boot(t0);
    let mut data = [0u8; 64];
    for (i, b) in data.iter_mut().enumerate() {
        *b = i as u8;
    }
    rx.handle_frame_fd(t0, &FdFrame::new(Id::Standard(0x185), &data).unwrap());
    assert_eq!(
        rx.od().get_value::<u64>(0x6107, 0),
        Ok(0),
        "waits for the SYNC"
    );
    rx.handle_frame(t0, &Frame::new(Id::Standard(0x80), &[]).unwrap());
    let want = u64::from_le_bytes([56, 57, 58, 59, 60, 61, 62, 63]);
    assert_eq!(rx.od().get_value::<u64>(0x6107, 0), Ok(want));
    assert_eq!(rx.pdo_wide_dropped(), 0);
}
