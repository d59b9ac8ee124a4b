//! Multiplexed PDOs on a CANopen FD network (features `fd` and `mpdo`): the master's
//! destination-address writes and a node's source-address values travel as FD MPDOs (the
//! classic four header bytes, the value from byte 4, up to 60 bytes, zero-filled to the next
//! CAN FD length), so objects of more than four bytes go in one frame; a value of up to four
//! bytes is the classic MPDO's eight bytes exactly. A receiver still takes classic MPDOs, and
//! counts an FD frame of no MPDO length as malformed.
// List entries are written in their fields' groups (block_index_sub, …), not in bytes.
#![allow(clippy::unusual_byte_groupings)]

use duocan::mpdo::{dispatcher_list, scanner_list, DispatcherEntry, MpdoError};
use duocan::node::NodeEventKind as K;
use duocan::od::ObjectDictionary;
use duocan::od::{comm, Access, DataType, DefaultValue, DynamicDictionary, ObjectDef};
use duocan::pdo::PdoEvent;
use duocan::{FdFrame, Frame, Id, Instant, Machine, NmtState, Node, NodeConfig, NodeId};

type FdNode = Node<DynamicDictionary>;

use super::mpdo::{comm as comm_params, mpdo_mapping, DAM_COB, MASTER, N5, N6, SAM_COB};

/// Node `id` (on a CANopen FD network if `fd`), operational, with 0x2000 (UNSIGNED16),
/// 0x2200 (UNSIGNED64), 0x2201 (UNSIGNED64) writable and mappable, 0x6002 (UNSIGNED64)
/// read-only and mappable, and `tables`.
fn fd_node(id: u8, master: bool, fd: bool, tables: &[Vec<ObjectDef>]) -> FdNode {
    let mut od = comm::standard_dictionary(id, comm::Identity::default());
    od.insert_all(&[
        ObjectDef::u16(0x2000, 0, Access::Rw, 0).mappable(),
        ObjectDef::new(0x2200, 0, DataType::Unsigned64)
            .mappable()
            .access(Access::Rw),
        ObjectDef::new(0x2201, 0, DataType::Unsigned64)
            .mappable()
            .access(Access::Rw),
        ObjectDef::new(0x6002, 0, DataType::Unsigned64)
            .mappable()
            .access(Access::Ro)
            .default(DefaultValue::Unsigned(0x1122_3344_5566_7788)),
    ])
    .unwrap();
    for t in tables {
        od.insert_all(t).unwrap();
    }
    let nid = NodeId::must(id);
    let cfg = if master {
        NodeConfig::master(nid)
    } else {
        NodeConfig::slave(nid)
    };
    let mut n = Node::new(cfg.with_fd(fd), od);
    n.boot(Instant::ZERO);
    n.set_nmt_state(Instant::ZERO, NmtState::Operational);
    n
}

/// A zero-latency wire of FD nodes: every frame one sends reaches all the others.
struct FdWire {
    nodes: Vec<FdNode>,
    /// Every CAN FD frame sent, with its sender.
    fd_log: Vec<(usize, FdFrame)>,
    /// Every classic frame sent, with its sender.
    log: Vec<(usize, Frame)>,
    events: Vec<Vec<K>>,
}

impl FdWire {
    /// Master (node 1): DAM on TPDO1, SAM consumer on RPDO1 with node 5's 0x6002 dispatched
    /// to its 0x2201. Node 5: DAM consumer on RPDO1, SAM producer on TPDO1 allowed 0x6002.
    /// Node 6: DAM consumer on RPDO1. All operational, on an FD network if `fd`.
    fn new(fd: bool) -> FdWire {
        let scan = scanner_list::<2>(0, &[0x01_6002_00]);
        let dispatch = dispatcher_list::<2>(
            0,
            &[DispatcherEntry {
                producer: 5,
                producer_index: 0x6002,
                producer_sub: 0,
                local_index: 0x2201,
                local_sub: 0,
                block: 1,
            }
            .raw()],
        );
        let master = fd_node(
            1,
            true,
            fd,
            &[
                comm_params(true, 1, DAM_COB.into()),
                mpdo_mapping(true, 1, 0xFF),
                comm_params(false, 1, SAM_COB.into()),
                mpdo_mapping(false, 1, 0xFE),
                dispatch.to_vec(),
            ],
        );
        let n5 = fd_node(
            5,
            false,
            fd,
            &[
                comm_params(false, 1, DAM_COB.into()),
                mpdo_mapping(false, 1, 0xFF),
                comm_params(true, 1, SAM_COB.into()),
                mpdo_mapping(true, 1, 0xFE),
                scan.to_vec(),
            ],
        );
        let n6 = fd_node(
            6,
            false,
            fd,
            &[
                comm_params(false, 1, DAM_COB.into()),
                mpdo_mapping(false, 1, 0xFF),
            ],
        );
        let mut w = FdWire {
            nodes: vec![master, n5, n6],
            fd_log: Vec::new(),
            log: Vec::new(),
            events: vec![Vec::new(); 3],
        };
        w.flush();
        w.fd_log.clear();
        w.log.clear();
        w.events.iter_mut().for_each(Vec::clear);
        w
    }

    /// Delivers everything pending until quiet.
    fn flush(&mut self) {
        let now = Instant::from_millis(1);
        loop {
            let mut moved = false;
            for i in 0..self.nodes.len() {
                while let Some(e) = self.nodes[i].poll_event() {
                    self.events[i].push(e.kind);
                }
                while let Some(f) = self.nodes[i].poll_transmit() {
                    moved = true;
                    for j in (0..self.nodes.len()).filter(|&j| j != i) {
                        self.nodes[j].handle_frame(now, &f);
                    }
                    self.log.push((i, f));
                }
                while let Some(f) = self.nodes[i].poll_transmit_fd() {
                    moved = true;
                    for j in (0..self.nodes.len()).filter(|&j| j != i) {
                        self.nodes[j].handle_frame_fd(now, &f);
                    }
                    self.fd_log.push((i, f));
                }
            }
            if !moved {
                break;
            }
        }
    }

    /// Delivers `f` from outside to every node.
    fn inject_fd(&mut self, f: &FdFrame) {
        for n in &mut self.nodes {
            n.handle_frame_fd(Instant::from_millis(1), f);
        }
        self.flush();
    }

    fn u64_at(&self, i: usize, index: u16) -> u64 {
        self.nodes[i].od().get_value::<u64>(index, 0).unwrap()
    }
}

#[test]
fn a_dam_of_eight_bytes_goes_in_one_fd_mpdo_to_the_addressed_node_only() {
    let mut w = FdWire::new(true);
    let v = 0x0102_0304_0506_0708u64;
    w.nodes[MASTER]
        .mpdo_send_dam(Instant::from_millis(1), 1, 5, 0x2200, 0, &v.to_le_bytes())
        .unwrap();
    w.flush();
    // One CAN FD frame of 12 bytes: the classic header, then the value.
    assert_eq!(w.fd_log.len(), 1, "{:?}", w.fd_log);
    let (from, f) = &w.fd_log[0];
    assert_eq!((*from, f.id()), (MASTER, Id::Standard(DAM_COB)));
    let mut want = vec![0x85, 0x00, 0x22, 0x00];
    want.extend(v.to_le_bytes());
    assert_eq!(f.data(), &want[..]);
    assert!(w.log.iter().all(|(_, f)| f.id() != Id::Standard(DAM_COB)));
    assert_eq!(w.u64_at(N5, 0x2200), v);
    assert_eq!(w.u64_at(N6, 0x2200), 0, "addressed to node 5 only");
    assert_eq!(w.nodes[N5].mpdo_stats().written, 1);
    assert_eq!(w.nodes[N6].mpdo_stats().other_node, 1);
    assert!(w.events[N5].contains(&K::Pdo(PdoEvent::MpdoWritten {
        pdo: 1,
        index: 0x2200,
        sub: 0
    })));
}

#[test]
fn a_short_value_is_the_classic_eight_bytes_in_a_can_fd_frame_and_node_0_is_everyone() {
    let mut w = FdWire::new(true);
    w.nodes[MASTER]
        .mpdo_send_dam(Instant::from_millis(1), 1, 0, 0x2000, 0, &[0x34, 0x12])
        .unwrap();
    w.flush();
    assert_eq!(w.fd_log.len(), 1);
    assert_eq!(
        w.fd_log[0].1.data(),
        &[0x80, 0x00, 0x20, 0x00, 0x34, 0x12, 0, 0],
        "byte for byte the classic MPDO"
    );
    for i in [N5, N6] {
        assert_eq!(w.nodes[i].od().get_value::<u16>(0x2000, 0), Ok(0x1234));
    }
    // More than 60 bytes is no FD MPDO.
    assert_eq!(
        w.nodes[MASTER].mpdo_send_dam(Instant::from_millis(1), 1, 5, 0x2200, 0, &[0; 61]),
        Err(MpdoError::BadRequest)
    );
}

#[test]
fn a_sam_value_of_eight_bytes_reaches_the_master_through_its_dispatcher_list() {
    let mut w = FdWire::new(true);
    w.nodes[N5]
        .mpdo_send_sam(Instant::from_millis(1), 1, 0x6002, 0)
        .unwrap();
    w.flush();
    assert_eq!(w.fd_log.len(), 1);
    let (from, f) = &w.fd_log[0];
    assert_eq!((*from, f.id()), (N5, Id::Standard(SAM_COB)));
    assert_eq!(&f.data()[..4], &[0x05, 0x02, 0x60, 0x00], "SAM from node 5");
    assert_eq!(f.data().len(), 12);
    assert_eq!(w.u64_at(MASTER, 0x2201), 0x1122_3344_5566_7788);
    assert_eq!(w.nodes[MASTER].mpdo_stats().written, 1);
    // Not in the scanner list: nothing goes out.
    assert!(w.nodes[N5]
        .mpdo_send_sam(Instant::from_millis(1), 1, 0x2200, 0)
        .is_err());
    w.flush();
    assert_eq!(w.fd_log.len(), 1);
}

#[test]
fn a_receiver_takes_classic_mpdos_and_counts_fd_frames_of_no_mpdo_length() {
    let mut w = FdWire::new(true);
    // A classic MPDO on the DAM channel, from a classic sender.
    let classic = Frame::new(
        Id::Standard(DAM_COB),
        &[0x86, 0x00, 0x20, 0x00, 0x07, 0x00, 0, 0],
    )
    .unwrap();
    w.nodes[N6].handle_frame(Instant::from_millis(1), &classic);
    w.flush();
    assert_eq!(w.nodes[N6].od().get_value::<u16>(0x2000, 0), Ok(7));
    // Seven bytes (a CAN FD length below the MPDO's eight): malformed, counted, not written.
    let short = FdFrame::new(Id::Standard(DAM_COB), &[0x86, 0x00, 0x20, 0x00, 9, 0, 0]).unwrap();
    w.inject_fd(&short);
    assert_eq!(w.nodes[N6].mpdo_stats().malformed, 1);
    assert_eq!(w.nodes[N6].od().get_value::<u16>(0x2000, 0), Ok(7));
    // A 64-byte FD MPDO for a 2-byte object: the object takes its two bytes.
    let mut long = [0u8; 64];
    long[..6].copy_from_slice(&[0x86, 0x00, 0x20, 0x00, 0x2A, 0x00]);
    w.inject_fd(&FdFrame::new(Id::Standard(DAM_COB), &long).unwrap());
    assert_eq!(w.nodes[N6].od().get_value::<u16>(0x2000, 0), Ok(42));
}

#[test]
fn on_a_classic_network_mpdos_stay_classic_and_four_bytes() {
    let mut w = FdWire::new(false);
    w.nodes[MASTER]
        .mpdo_send_dam(Instant::from_millis(1), 1, 5, 0x2000, 0, &[1, 0])
        .unwrap();
    w.flush();
    assert!(w.fd_log.is_empty());
    assert!(w
        .log
        .iter()
        .any(|(_, f)| f.id() == Id::Standard(DAM_COB) && f.data().len() == 8));
    assert_eq!(w.nodes[N5].od().get_value::<u16>(0x2000, 0), Ok(1));
    assert_eq!(
        w.nodes[MASTER].mpdo_send_dam(Instant::from_millis(1), 1, 5, 0x2200, 0, &[0; 8]),
        Err(MpdoError::BadRequest)
    );
}
