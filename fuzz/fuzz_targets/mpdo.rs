//! MPDO (CiA 301 multiplexed PDOs): the classic and FD decoders, and a node whose RPDO1 takes
//! MPDOs (destination- and source-address mode, a dispatcher list) fed arbitrary frames: one
//! on a classic network fed classic frames, one on a CANopen FD network fed CAN FD frames of
//! every CAN FD length and classic ones.
//! The decoders answer any bytes with an MPDO or an error, and an MPDO they return encodes to
//! the same bytes; the node never panics, counts every frame it takes on the MPDO's identifier
//! exactly once, and writes only the objects its rules allow.
#![no_main]
// List entries are written in their fields' groups (block_index_sub, …), not in bytes.
#![allow(clippy::unusual_byte_groupings)]

use duocan::mpdo::{dispatcher_list, FdMpdo, Mpdo};
use duocan::od::{comm, Access, DefaultValue, ObjectDef, ObjectDictionary};
use duocan::pdo::params;
use duocan::{FdFrame, Frame, Id, Instant, Machine, Node, NodeConfig, NodeId, NmtState};
use libfuzzer_sys::fuzz_target;

const COB: u16 = 0x300;

fuzz_target!(|data: &[u8]| {
    if let Ok(m) = Mpdo::decode(data) {
        assert_eq!(&m.to_bytes()[..], data);
    }
    if let Ok(m) = FdMpdo::decode(data) {
        assert_eq!(m.frame(Id::Standard(COB)).data(), data);
    }

    run(data, false);
    run(data, true);
});

/// Node 5 (on a CANopen FD network if `fd`) fed the records of `data` on its MPDO identifier:
/// a length byte, then the frame's data (a CAN FD frame when `fd` and the length is one of
/// CAN FD's, a classic one up to 8 bytes otherwise).
fn run(data: &[u8], fd: bool) {
    let mut od = comm::standard_dictionary(5, comm::Identity::default());
    let mut mapping = params::rpdo_mapping::<2>(1, &[]);
    mapping[0] = ObjectDef::u8(0x1600, 0, Access::Rw, 0xFF);
    od.insert_all(&params::rpdo_comm(1, DefaultValue::Unsigned(COB as u64), 254, 0))
        .unwrap();
    od.insert_all(&mapping).unwrap();
    od.insert_all(&[
        ObjectDef::u16(0x2000, 0, Access::Rw, 0).mappable(),
        ObjectDef::u16(0x2001, 0, Access::Ro, 7).mappable(),
        ObjectDef::u32(0x2002, 0, Access::Rw, 0),
    ])
    .unwrap();
    od.insert_all(&dispatcher_list::<3>(0, &[0x01_2000_00_6000_00_07, 0xFF_2000_00_6000_00_08]))
        .unwrap();
    let mut node = Node::new(NodeConfig::slave(NodeId::must(5)).with_fd(fd), od);
    node.boot(Instant::ZERO);
    node.set_nmt_state(Instant::ZERO, NmtState::Operational);
    while node.poll_transmit().is_some() {}
    while node.poll_transmit_fd().is_some() {}

    // Input: records of a length byte then the frame's data, all on the MPDO's identifier.
    let mut rest = data;
    let mut frames = 0u32;
    let mut now = Instant::ZERO;
    while let [len, tail @ ..] = rest {
        let want = if fd { usize::from(*len % 65) } else { usize::from(*len % 9) };
        let n = want.min(tail.len());
        let (bytes, next) = tail.split_at(n);
        rest = next;
        now += duocan::Duration::from_millis(1);
        match FdFrame::new(Id::Standard(COB), bytes) {
            Ok(f) if fd && n > 8 || fd && len & 0x80 != 0 => node.handle_frame_fd(now, &f),
            _ if n <= 8 => node.handle_frame(now, &Frame::new(Id::Standard(COB), bytes).unwrap()),
            // No CAN FD length: no frame.
            _ => continue,
        }
        frames += 1;
        while node.poll_transmit().is_some() {}
        while node.poll_transmit_fd().is_some() {}
        while node.poll_event().is_some() {}
    }
    let st = node.mpdo_stats();
    assert_eq!(
        st.written + st.refused + st.other_node + st.not_dispatched + st.malformed,
        frames
    );
    assert_eq!(node.od().get_value::<u16>(0x2001, 0), Ok(7), "read-only stays");
    assert_eq!(node.od().get_value::<u32>(0x2002, 0), Ok(0), "not mappable stays");
}
