//! What the network knows of the nodes' PDO mappings, inside its runtime: a node's TPDO is
//! decoded here when its frame arrives, a node's RPDO encoded here when it is sent.

use super::{PdoValue, PdoValues};
use crate::cia301::pdo::{read_bits, read_bits_wide, write_bits_wide, FD_MAX_BITS, MAX_BITS};
use crate::frame::cob_id::NodeId;
use crate::frame::{FdFrame, Frame, Id};
use crate::net::value::AnyValue;
use crate::od::DataType;
use std::collections::BTreeMap;
use std::sync::Arc;

/// The most PDO mappings the network keeps per direction (4 PDOs of every node twice over):
/// learning one more is an error, never growth.
pub const MAX_LEARNED: usize = 1024;

/// One mapped entry as the network decodes or encodes it.
#[derive(Clone, Debug)]
pub(crate) struct Slot {
    pub index: u16,
    pub sub: u8,
    pub bits: u8,
    pub data_type: Option<DataType>,
    pub name: Option<Arc<str>>,
    pub dummy: bool,
}

/// A learned PDO: whose it is and what it carries.
#[derive(Clone, Debug)]
pub(crate) struct Learned {
    pub node: NodeId,
    pub pdo: u16,
    pub id: Id,
    pub slots: Arc<[Slot]>,
}

/// A CAN identifier as one ordered key (bit 31: 29-bit).
fn key(id: Id) -> u32 {
    match id {
        Id::Standard(v) => u32::from(v),
        Id::Extended(v) => v | 1 << 31,
    }
}

/// The learned mappings: the nodes' TPDOs by identifier (what arrives), their RPDOs by node
/// and number (what is sent).
#[derive(Default)]
pub(crate) struct PdoTable {
    rx: BTreeMap<u32, Learned>,
    /// With the values last sent (zeros at first), for a send that names only some.
    tx: BTreeMap<(u8, u16), (Learned, Vec<AnyValue>)>,
}

/// The zero of an entry's type: what an RPDO entry carries until a value is given for it.
fn zero(t: Option<DataType>) -> AnyValue {
    match t {
        Some(DataType::Boolean) => AnyValue::Bool(false),
        Some(t) if t.is_real() => AnyValue::Real(0.0),
        Some(t) if t.is_signed() => AnyValue::Signed(0),
        Some(t) if t.fixed_size().is_none() => AnyValue::Bytes(Vec::new()),
        _ => AnyValue::Unsigned(0),
    }
}

impl PdoTable {
    /// Learns (or, with `learned = None`, forgets) a node's TPDO (`transmit`) or RPDO.
    pub fn learn(
        &mut self,
        transmit: bool,
        node: NodeId,
        pdo: u16,
        learned: Option<Learned>,
    ) -> Result<(), ()> {
        if transmit {
            self.rx.retain(|_, l| (l.node, l.pdo) != (node, pdo));
            if let Some(l) = learned {
                if self.rx.len() >= MAX_LEARNED {
                    return Err(());
                }
                self.rx.insert(key(l.id), l);
            }
        } else {
            let k = (node.raw(), pdo);
            match learned {
                None => {
                    self.tx.remove(&k);
                }
                Some(l) => {
                    if self.tx.len() >= MAX_LEARNED && !self.tx.contains_key(&k) {
                        return Err(());
                    }
                    let zeros = l
                        .slots
                        .iter()
                        .filter(|s| !s.dummy)
                        .map(|s| zero(s.data_type))
                        .collect();
                    self.tx.insert(k, (l, zeros));
                }
            }
        }
        Ok(())
    }

    /// The node, PDO number and values of a CAN FD frame that is a learned TPDO of up to 64
    /// bytes (a node on a CANopen FD network); `None` for any other frame, and for one shorter
    /// than its mapping. An entry of more than 64 bits (a string or domain) is its bytes.
    pub fn decode_fd(&self, f: &FdFrame) -> Option<(NodeId, u16, PdoValues)> {
        let l = self.rx.get(&key(f.id()))?;
        let total: u32 = l.slots.iter().map(|s| u32::from(s.bits)).sum();
        let data = f.data();
        if data.len() * 8 < total as usize {
            return None;
        }
        let mut offset = 0u32;
        let mut values = Vec::with_capacity(l.slots.len());
        for s in l.slots.iter() {
            let bits = u32::from(s.bits);
            if !s.dummy {
                let value = if bits <= 64 {
                    AnyValue::from_bits(s.data_type, read_bits_wide(data, offset, bits), bits)
                } else {
                    let bytes = (0..bits.div_ceil(8))
                        .map(|k| read_bits_wide(data, offset + 8 * k, (bits - 8 * k).min(8)) as u8)
                        .collect();
                    AnyValue::Bytes(bytes)
                };
                values.push(PdoValue {
                    index: s.index,
                    sub: s.sub,
                    name: s.name.clone(),
                    value,
                });
            }
            offset += bits;
        }
        Some((l.node, l.pdo, PdoValues(values.into())))
    }

    /// The node, PDO number and values of a frame that is a learned TPDO; `None` for any other
    /// frame, and for one shorter than its mapping (CiA 301: such a PDO is not processed).
    pub fn decode(&self, f: &Frame) -> Option<(NodeId, u16, PdoValues)> {
        let l = self.rx.get(&key(f.id()))?;
        if f.is_remote() {
            return None;
        }
        let total: u32 = l.slots.iter().map(|s| u32::from(s.bits)).sum();
        let data = f.data();
        if data.len() * 8 < total as usize {
            return None;
        }
        let mut payload = [0u8; 8];
        payload[..data.len().min(8)].copy_from_slice(&data[..data.len().min(8)]);
        let mut offset = 0u32;
        let mut values = Vec::with_capacity(l.slots.len());
        for s in l.slots.iter() {
            let bits = u32::from(s.bits);
            if !s.dummy {
                let raw = read_bits(&payload, offset, bits);
                values.push(PdoValue {
                    index: s.index,
                    sub: s.sub,
                    name: s.name.clone(),
                    value: AnyValue::from_bits(s.data_type, raw, bits),
                });
            }
            offset += bits;
        }
        Some((l.node, l.pdo, PdoValues(values.into())))
    }

    /// The frame of a node's learned RPDO carrying `values` (one per entry that is not a
    /// dummy, in mapping order), or why it cannot be made; `None`: the RPDO is not known. On a
    /// CANopen FD network (`fd`) it is a CAN FD frame of up to 64 bytes, padded with 0xCC to the
    /// next CAN FD length as the nodes pad their TPDOs; else a classic frame of up to 8.
    pub fn encode(
        &mut self,
        node: NodeId,
        pdo: u16,
        values: &[AnyValue],
        fd: bool,
    ) -> Option<Result<AnyFrame, String>> {
        let (l, last) = self.tx.get_mut(&(node.raw(), pdo))?;
        let r = encode(l, values, fd);
        if r.is_ok() {
            last.clone_from_slice(values);
        }
        Some(r)
    }

    /// [`PdoTable::encode`] with the entries `named` (by name, without regard to case) set
    /// and every other one as last sent.
    pub fn encode_named(
        &mut self,
        node: NodeId,
        pdo: u16,
        named: &[(String, AnyValue)],
        fd: bool,
    ) -> Option<Result<AnyFrame, String>> {
        let (l, last) = self.tx.get(&(node.raw(), pdo))?;
        let mut values = last.clone();
        let names: Vec<Option<&str>> = l
            .slots
            .iter()
            .filter(|s| !s.dummy)
            .map(|s| s.name.as_deref())
            .collect();
        for (name, v) in named {
            let Some(k) = names
                .iter()
                .position(|n| n.is_some_and(|n| n.eq_ignore_ascii_case(name)))
            else {
                let known: Vec<String> = names.iter().flatten().map(|n| format!("{n:?}")).collect();
                return Some(Err(format!(
                    "it maps no entry named {name:?}; it maps {}",
                    if known.is_empty() {
                        "no named entries (attach the node's description before reading the mapping)".into()
                    } else {
                        known.join(", ")
                    }
                )));
            };
            values[k] = v.clone();
        }
        self.encode(node, pdo, &values, fd)
    }
}

/// An RPDO's frame as the network sends it: classic, or CAN FD on a CANopen FD network.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) enum AnyFrame {
    /// Up to 8 bytes, on a classic network.
    Classic(Frame),
    /// Up to 64 bytes, padded to a CAN FD length, on a CANopen FD network.
    Fd(FdFrame),
}

/// The PDO padding byte of CiA 1301 (as the nodes' TPDOs and the USDO frames have).
const PAD: u8 = 0xCC;

fn encode(l: &Learned, values: &[AnyValue], fd: bool) -> Result<AnyFrame, String> {
    let wanted = l.slots.iter().filter(|s| !s.dummy).count();
    if values.len() != wanted {
        return Err(format!(
            "its mapping carries {wanted} value(s) but {} were given: give one per mapped entry, in mapping order",
            values.len()
        ));
    }
    let most = if fd { FD_MAX_BITS } else { MAX_BITS };
    let mut payload = [0u8; 64];
    let mut offset = 0u32;
    let mut given = values.iter();
    for s in l.slots.iter() {
        let bits = u32::from(s.bits);
        if offset + bits > most {
            return Err(if fd {
                "its mapping is longer than 512 bits (64 bytes)".into()
            } else {
                "its mapping is longer than 64 bits: a classic network carries 8 bytes (a CANopen FD network 64)".into()
            });
        }
        if !s.dummy {
            let v = given.next().ok_or("too few values")?;
            let name = || {
                let name = s
                    .name
                    .as_deref()
                    .map_or(String::new(), |n| format!(" {n:?}"));
                format!("entry {:#06x} sub {}{name}", s.index, s.sub)
            };
            if bits <= 64 {
                let raw = v
                    .to_bits(s.data_type, bits)
                    .map_err(|why| format!("{}: {why}", name()))?;
                write_bits_wide(&mut payload, offset, bits, raw);
            } else {
                // An entry over 64 bits (a string or domain): its bytes, zeros after them.
                let bytes: &[u8] = match v {
                    AnyValue::Bytes(b) => b,
                    AnyValue::Text(t) => t.as_bytes(),
                    other => {
                        return Err(format!(
                            "{}: {bits} bits carry bytes or text, not {other:?}",
                            name()
                        ))
                    }
                };
                if bytes.len() * 8 > bits as usize {
                    return Err(format!(
                        "{}: {} byte(s) do not fit in {bits} bits",
                        name(),
                        bytes.len()
                    ));
                }
                for k in 0..bits.div_ceil(8) {
                    let byte = bytes.get(k as usize).copied().unwrap_or(0);
                    write_bits_wide(
                        &mut payload,
                        offset + 8 * k,
                        (bits - 8 * k).min(8),
                        byte.into(),
                    );
                }
            }
        }
        offset += bits;
    }
    let data = &payload[..offset.div_ceil(8) as usize];
    if fd {
        FdFrame::padded(l.id, data, PAD)
            .map(AnyFrame::Fd)
            .map_err(|e| format!("{e:?}"))
    } else {
        Frame::new(l.id, data)
            .map(AnyFrame::Classic)
            .map_err(|e| format!("{e:?}"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn learned(id: Id, slots: &[(u8, Option<DataType>, bool)]) -> Learned {
        Learned {
            node: NodeId::must(5),
            pdo: 1,
            id,
            slots: slots
                .iter()
                .enumerate()
                .map(|(k, &(bits, data_type, dummy))| Slot {
                    index: if dummy { 5 } else { 0x6000 },
                    sub: if dummy { 0 } else { k as u8 + 1 },
                    bits,
                    data_type,
                    name: None,
                    dummy,
                })
                .collect::<Vec<_>>()
                .into(),
        }
    }

    proptest! {
        /// Any frame on a learned identifier decodes without a panic, and only when it carries
        /// the whole mapping; what is encoded decodes back to the same values.
        #[test]
        fn frames_decode_safely_and_round_trip(
            widths in proptest::collection::vec((1u8..=16, any::<bool>(), any::<bool>()), 1..5),
            data in proptest::collection::vec(any::<u8>(), 0..=8),
        ) {
            let slots: Vec<_> = widths
                .iter()
                .map(|&(b, signed, dummy)| {
                    (b, Some(if signed { DataType::Integer16 } else { DataType::Unsigned16 }), dummy)
                })
                .collect();
            let total: u32 = slots.iter().map(|s| u32::from(s.0)).sum();
            let id = Id::Standard(0x185);
            let mut t = PdoTable::default();
            t.learn(true, NodeId::must(5), 1, Some(learned(id, &slots))).unwrap();
            t.learn(false, NodeId::must(5), 1, Some(learned(id, &slots))).unwrap();
            let f = Frame::new(id, &data).unwrap();
            match t.decode(&f) {
                Some((_, _, values)) => {
                    prop_assert!(data.len() as u32 * 8 >= total);
                    let given: Vec<AnyValue> = values.iter().map(|v| v.value.clone()).collect();
                    let AnyFrame::Classic(back) = t.encode(NodeId::must(5), 1, &given, false).unwrap().unwrap() else {
                        panic!("a classic frame on a classic network");
                    };
                    let again = t.decode(&back).unwrap().2;
                    prop_assert_eq!(again, values);
                }
                None => prop_assert!((data.len() as u32 * 8) < total),
            }
            prop_assert!(t.decode(&Frame::new(Id::Standard(0x186), &data).unwrap()).is_none());
        }
    }

    #[test]
    fn a_64_byte_can_fd_tpdo_is_decoded_at_odd_offsets() {
        let mut t = PdoTable::default();
        let id = Id::Standard(0x185);
        // 3 + 13 + 7 × 64 + 48 bits = 512 bits.
        let mut slots = vec![
            (3, Some(DataType::Unsigned8), false),
            (13, Some(DataType::Integer16), false),
        ];
        slots.extend([(64, Some(DataType::Unsigned64), false); 7]);
        slots.push((48, None, true));
        t.learn(true, NodeId::must(5), 1, Some(learned(id, &slots)))
            .unwrap();
        let mut data = [0u8; 64];
        crate::cia301::pdo::write_bits_wide(&mut data, 0, 3, 5);
        crate::cia301::pdo::write_bits_wide(&mut data, 3, 13, 0x1FFE); // -2
        for k in 0..7u32 {
            crate::cia301::pdo::write_bits_wide(
                &mut data,
                16 + 64 * k,
                64,
                u64::MAX - u64::from(k),
            );
        }
        let f = FdFrame::new(id, &data).unwrap();
        let (node, pdo, v) = t.decode_fd(&f).unwrap();
        assert_eq!((node, pdo, v.len()), (NodeId::must(5), 1, 9));
        assert_eq!(v[0].value, AnyValue::Unsigned(5));
        assert_eq!(v[1].value, AnyValue::Signed(-2));
        assert_eq!(v[8].value, AnyValue::Unsigned(u64::MAX - 6));
        let short = FdFrame::new(id, &data[..48]).unwrap();
        assert!(t.decode_fd(&short).is_none(), "shorter than its mapping");
    }

    #[test]
    fn learning_is_bounded_and_forgetting_works() {
        let mut t = PdoTable::default();
        for k in 0..MAX_LEARNED as u16 {
            let l = Learned {
                pdo: k + 1,
                ..learned(Id::Standard(0x200 + k), &[(8, None, false)])
            };
            t.learn(true, NodeId::must(5), k + 1, Some(l)).unwrap();
        }
        let one_more = learned(Id::Extended(0x1234), &[(8, None, false)]);
        assert_eq!(t.learn(true, NodeId::must(6), 1, Some(one_more)), Err(()));
        let f = Frame::new(Id::Standard(0x200), &[42]).unwrap();
        assert_eq!(t.decode(&f).unwrap().2[0].value, AnyValue::Unsigned(42));
        t.learn(true, NodeId::must(5), 1, None).unwrap();
        assert!(t.decode(&f).is_none());
    }
}
