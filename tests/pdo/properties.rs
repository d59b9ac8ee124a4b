//! Property tests of PDO bit packing against a bit-by-bit reference packer, end to end through a
//! TPDO and an RPDO, and of a PDO-configured node under random frames.

use crate::common::{node, Wire};
use duocan::od::{
    comm, Access, DataType, DefaultValue, DynamicDictionary, ObjectDef, ObjectDictionary,
};
use duocan::pdo::{mask, params, read_bits, write_bits};
use duocan::{Duration, Frame, Id, Instant, Machine, NmtState};
use proptest::prelude::*;

/// The simplest packer there is: one bit at a time, CiA 301 order (LSB of byte 0 first).
fn reference_pack(fields: &[(u32, u64)]) -> [u8; 8] {
    let mut out = [0u8; 8];
    let mut pos = 0u32;
    for &(len, v) in fields {
        for b in 0..len {
            if (v >> b) & 1 == 1 {
                out[(pos / 8) as usize] |= 1 << (pos % 8);
            }
            pos += 1;
        }
    }
    out
}

/// Field lengths (1–64 bits each, 64 in all at most) with values.
fn fields() -> impl Strategy<Value = Vec<(u32, u64)>> {
    proptest::collection::vec((1u32..=64, any::<u64>()), 1..20).prop_map(|v| {
        let mut total = 0;
        v.into_iter()
            .take_while(|(len, _)| {
                total += len;
                total <= 64
            })
            .collect()
    })
}

const TYPES: [DataType; 9] = [
    DataType::Boolean,
    DataType::Unsigned8,
    DataType::Integer8,
    DataType::Unsigned16,
    DataType::Integer16,
    DataType::Unsigned32,
    DataType::Integer32,
    DataType::Unsigned64,
    DataType::Integer64,
];

/// Mapped entries: a type, a mapped length up to its size, a value; 64 bits in all at most.
fn typed_fields() -> impl Strategy<Value = Vec<(DataType, u32, u64)>> {
    proptest::collection::vec((0..TYPES.len(), 1u32..=64, any::<u64>()), 1..16).prop_map(|v| {
        let mut total = 0;
        let mut out = vec![];
        for (t, len, value) in v {
            let t = TYPES[t];
            let len = len.min(t.bit_size().unwrap());
            if total + len > 64 {
                break;
            }
            total += len;
            out.push((t, len, value));
        }
        out
    })
}

/// Entries 0x6000 (8 bits) and 0x6001 (16 bits), TPDO1–3 of types 255 (inhibit and event
/// timer), 252 and 2, RPDO1 of type 0 with a timeout, RPDO2 of type 255 with a dummy entry.
pub(crate) fn every_pdo_type(od: &mut DynamicDictionary) {
    od.insert_all(&[
        ObjectDef::u8(0x6000, 0, Access::Rw, 0).mappable(),
        ObjectDef::u16(0x6001, 0, Access::Rw, 0).mappable(),
    ])
    .unwrap();
    od.insert_all(&params::tpdo_comm(
        1,
        params::predefined_tpdo_cob(1),
        255,
        10,
        5,
    ))
    .unwrap();
    od.insert_all(&params::tpdo_mapping::<3>(1, &[0x6001_0010, 0x6000_0003]))
        .unwrap();
    od.insert_all(&params::tpdo_comm(
        2,
        params::predefined_tpdo_cob(2),
        252,
        0,
        0,
    ))
    .unwrap();
    od.insert_all(&params::tpdo_mapping::<2>(2, &[0x6000_0008]))
        .unwrap();
    od.insert_all(&params::tpdo_comm(
        3,
        params::predefined_tpdo_cob(3),
        2,
        0,
        0,
    ))
    .unwrap();
    od.insert_all(&params::tpdo_mapping::<2>(3, &[0x6000_0008]))
        .unwrap();
    od.insert_all(&params::rpdo_comm(1, params::predefined_rpdo_cob(1), 0, 4))
        .unwrap();
    od.insert_all(&params::rpdo_mapping::<2>(1, &[0x6000_0008]))
        .unwrap();
    od.insert_all(&params::rpdo_comm(
        2,
        params::predefined_rpdo_cob(2),
        255,
        2,
    ))
    .unwrap();
    od.insert_all(&params::rpdo_mapping::<3>(2, &[0x6001_0010, 0x0005_0008]))
        .unwrap();
}

pub(crate) fn any_pdo_frame() -> impl Strategy<Value = Frame> {
    let id = prop_oneof![
        Just(0x80u16),
        Just(0x185),
        Just(0x205),
        Just(0x305),
        Just(0x000),
        0u16..=0x7FF
    ];
    (
        id,
        any::<bool>(),
        proptest::collection::vec(any::<u8>(), 0..=8),
    )
        .prop_map(|(id, rtr, d)| {
            if rtr {
                Frame::remote(Id::Standard(id), d.len() as u8).unwrap()
            } else {
                Frame::new(Id::Standard(id), &d).unwrap()
            }
        })
}

proptest! {
    #[test]
    fn write_bits_matches_the_reference_packer(fields in fields()) {
        let mut p = [0u8; 8];
        let mut off = 0;
        for &(len, v) in &fields {
            write_bits(&mut p, off, len, v);
            off += len;
        }
        prop_assert_eq!(p, reference_pack(&fields));
        let mut off = 0;
        for &(len, v) in &fields {
            prop_assert_eq!(read_bits(&p, off, len), v & mask(len));
            off += len;
        }
    }

    /// Values of every integer type, mapped with odd lengths that straddle byte boundaries, go
    /// through a TPDO of one node and an RPDO of another: the frame is what the reference packer
    /// builds, and the receiver holds each value cut to its length (sign-extended when signed).
    #[test]
    fn tpdo_to_rpdo_round_trip(fields in typed_fields()) {
        let n = fields.len();
        let defs = |access| -> Vec<ObjectDef> {
            fields
                .iter()
                .enumerate()
                .map(|(i, (t, _, _))| ObjectDef::new(0x2100 + i as u16, 0, *t).mappable().access(access))
                .collect()
        };
        let map: Vec<u32> = fields
            .iter()
            .enumerate()
            .map(|(i, (_, len, _))| ((0x2100 + i as u32) << 16) | len)
            .collect();
        let mut tx = node(5, false);
        tx.od_mut().insert_all(&defs(Access::Rw)).unwrap();
        tx.od_mut().insert_all(&params::tpdo_comm(1, params::predefined_tpdo_cob(1), 254, 0, 0)).unwrap();
        tx.od_mut().insert_all(&params::tpdo_mapping::<65>(1, &map)).unwrap();
        let mut rx = node(1, true);
        rx.od_mut().insert_all(&defs(Access::Rw)).unwrap();
        rx.od_mut().insert_all(&params::rpdo_comm(1, DefaultValue::Unsigned(0x185), 255, 0)).unwrap();
        rx.od_mut().insert_all(&params::rpdo_mapping::<65>(1, &map)).unwrap();
        let mut w = Wire::new(vec![tx, rx]);
        w.boot_all();
        w.nodes[0].set_nmt_state(w.now, NmtState::Operational);
        let mut sent = vec![];
        for (i, (t, len, v)) in fields.iter().enumerate() {
            let size = t.fixed_size().unwrap();
            let v = if *t == DataType::Boolean { v & 1 } else { *v };
            w.nodes[0].write(w.now, 0x2100 + i as u16, 0, &v.to_le_bytes()[..size]).unwrap();
            sent.push((*len, v));
        }
        w.flush();
        let last = w.sent(0, 0x185).last().unwrap().1;
        let bytes = sent.iter().map(|(l, _)| l).sum::<u32>().div_ceil(8) as usize;
        prop_assert_eq!(last.data(), &reference_pack(&sent)[..bytes]);
        prop_assert_eq!(w.nodes[1].rpdo_status(1).unwrap().received as usize, n + 1, "one frame at start, one per write");
        for (i, (len, v)) in sent.iter().enumerate() {
            let dt = fields[i].0;
            let raw = v & mask(*len);
            let expect = if matches!(dt, DataType::Integer8 | DataType::Integer16 | DataType::Integer32 | DataType::Integer64)
                && *len < 64
                && (raw >> (len - 1)) & 1 == 1
            {
                raw | !mask(*len)
            } else {
                raw
            };
            let size = dt.fixed_size().unwrap();
            prop_assert_eq!(
                w.nodes[1].od().read(0x2100 + i as u16, 0).unwrap(),
                &expect.to_le_bytes()[..size],
                "entry {} ({:?}, {} bits)", i, dt, len
            );
        }
    }

    /// Random frames (SYNC, RPDOs of every length, RTRs, anything) at random times, with NMT
    /// changes and writes to mapped entries, to a node running every PDO type: nothing panics,
    /// queues stay bounded, no deadline is left in the past.
    #[test]
    fn random_frames_never_break_a_pdo_node(
        ops in proptest::collection::vec((any_pdo_frame(), 0u64..3_000, 0u8..20, any::<u16>()), 1..300)
    ) {
        let mut n = node(5, false);
        every_pdo_type(n.od_mut());
        let mut now = Instant::ZERO;
        n.boot(now);
        n.set_nmt_state(now, NmtState::Operational);
        n.set(now, comm::EMCY_INHIBIT, 0, 0u16).unwrap();
        for (f, dt, op, v) in ops {
            now += Duration::from_micros(dt);
            if n.poll_timeout().is_some_and(|t| t <= now) {
                n.handle_timeout(now);
                prop_assert!(n.poll_timeout().is_none_or(|t| t > now));
            }
            match op {
                0 => n.set_nmt_state(now, NmtState::PreOperational),
                1 => n.set_nmt_state(now, NmtState::Operational),
                2..=5 => { let _ = n.set(now, 0x6001, 0, v); }
                6 => { let _ = n.tpdo_request(now, v % 6); }
                _ => {}
            }
            n.handle_frame(now, &f);
            let mut k = 0;
            while n.poll_transmit().is_some() { k += 1; }
            prop_assert!(k <= duocan::node::TX_QUEUE);
            let mut e = 0;
            while n.poll_event().is_some() { e += 1; }
            prop_assert!(e <= duocan::node::EVENT_QUEUE);
            for p in 1..=4 {
                let s = n.tpdo_status(p).unwrap();
                prop_assert!(s.mapped_bits <= 64);
            }
        }
    }
}
