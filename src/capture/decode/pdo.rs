//! PDOs: raw bytes by the predefined COB-IDs, or the mapped values by name and type with a
//! layout (from a description's 0x1400../0x1600.. and 0x1800../0x1A00.. entries).

use super::frames::{DecodedFrame, Hex, N};
use super::kind::Kind;
use super::services::{bad, wrong_length};
use crate::cia301::pdo::params::{RPDO_COMM, RPDO_MAPPING, TPDO_COMM, TPDO_MAPPING};
use crate::cia301::pdo::{read_bits, read_bits_wide, Dir, MapEntry, FD_MAX_BITS, MAX_BITS};
use crate::eds::Description;
use crate::frame::cob_id::{predefined, CobId, NodeId};
use crate::frame::{FdFrame, Frame, Id};
use crate::od::DataType;
use core::fmt;

/// `TPDO1`, `RPDO2`: a PDO as the lines name it.
struct Label(Dir, u16);

impl fmt::Display for Label {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.0 {
            Dir::Transmit => write!(f, "TPDO{}", self.1),
            Dir::Receive => write!(f, "RPDO{}", self.1),
        }
    }
}

/// One mapped entry of a layout.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PdoFieldDef {
    /// Index (a data-type index 0x0001–0x001F with sub 0: a dummy, skipped).
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// Length in bits.
    pub bits: u8,
    /// The entry's name, from a description.
    pub name: Option<String>,
    /// The entry's type, from a description; `None` reads the bits as an unsigned number.
    pub data_type: Option<DataType>,
}

impl PdoFieldDef {
    /// An entry without name or type.
    #[must_use]
    pub fn new(entry: MapEntry) -> Self {
        PdoFieldDef {
            index: entry.index,
            sub: entry.sub,
            bits: entry.bits,
            name: None,
            data_type: None,
        }
    }
    /// With its name and type.
    #[must_use]
    pub fn with_name(mut self, name: &str, data_type: DataType) -> Self {
        self.name = Some(name.to_owned());
        self.data_type = Some(data_type);
        self
    }
}

/// How one PDO's frames are read.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PdoLayout {
    /// The node it belongs to.
    pub node: Option<NodeId>,
    /// Transmit (a TPDO) or receive (an RPDO), from the node's side.
    pub dir: Dir,
    /// The PDO's number (1-based: TPDO1 is 0x1800/0x1A00).
    pub number: u16,
    /// The mapped entries, in order.
    pub fields: Vec<PdoFieldDef>,
}

/// A mapped value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FieldValue {
    /// BOOLEAN.
    Bool(bool),
    /// The unsigned types, and any entry without a type.
    Unsigned(u64),
    /// The signed types (sign-extended from the mapped length).
    Signed(i64),
    /// REAL32 (mapped whole) and REAL64.
    Real(f64),
}

impl fmt::Display for FieldValue {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FieldValue::Bool(b) => write!(f, "{b}"),
            FieldValue::Unsigned(v) => write!(f, "{v}"),
            FieldValue::Signed(v) => write!(f, "{v}"),
            FieldValue::Real(v) => write!(f, "{v}"),
        }
    }
}

/// One value of a decoded PDO.
#[derive(Clone, Debug, PartialEq)]
pub struct PdoField {
    /// Index.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// Name, from the layout.
    pub name: Option<String>,
    /// The value.
    pub value: FieldValue,
}

/// A PDO frame.
#[derive(Clone, Debug, PartialEq)]
pub struct PdoInfo {
    /// The node, by the predefined COB-ID or the layout.
    pub node: Option<NodeId>,
    /// Transmit (a TPDO) or receive (an RPDO), from the node's side.
    pub dir: Dir,
    /// 1-based number.
    pub number: u16,
    /// A remote request for the PDO.
    pub remote: bool,
    /// The bytes.
    pub data: Vec<u8>,
    /// The mapped values, with a layout (empty without one).
    pub fields: Vec<PdoField>,
}

impl PdoInfo {
    /// `TPDO1`, `RPDO2`.
    #[must_use]
    pub fn label(&self) -> String {
        Label(self.dir, self.number).to_string()
    }
}

impl fmt::Display for PdoInfo {
    /// `node 5 TPDO1 Input 1 = 17, Input 2 = -3`, `node 5 RPDO2 01 02`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(n) = self.node {
            write!(f, "{} ", N(n))?;
        }
        write!(f, "{}", self.label())?;
        if self.remote {
            return f.write_str(" remote request");
        }
        if self.fields.is_empty() {
            return match self.data.is_empty() {
                true => f.write_str(" (no data)"),
                false => write!(f, " {}", Hex(&self.data)),
            };
        }
        for (i, v) in self.fields.iter().enumerate() {
            f.write_str(if i == 0 { " " } else { ", " })?;
            match &v.name {
                Some(name) => write!(f, "{name} = {}", v.value)?,
                None => write!(f, "{:#06x}:{:02x} = {}", v.index, v.sub, v.value)?,
            }
        }
        Ok(())
    }
}

/// A PDO on its predefined COB-ID: the raw bytes.
pub(super) fn raw(node: NodeId, dir: Dir, number: u8, frame: &Frame) -> DecodedFrame {
    DecodedFrame::Pdo(PdoInfo {
        node: Some(node),
        dir,
        number: number as u16,
        remote: frame.is_remote(),
        data: frame.data().to_vec(),
        fields: Vec::new(),
    })
}

/// A PDO by its layout.
pub(super) fn decode(layout: &PdoLayout, frame: &Frame) -> DecodedFrame {
    let mut info = PdoInfo {
        node: layout.node,
        dir: layout.dir,
        number: layout.number,
        remote: frame.is_remote(),
        data: frame.data().to_vec(),
        fields: Vec::new(),
    };
    if info.remote {
        return DecodedFrame::Pdo(info);
    }
    let needed: u32 = layout.fields.iter().map(|e| e.bits as u32).sum();
    let have = frame.data().len() as u32 * 8;
    if needed > have {
        return bad(
            Kind::Pdo,
            layout.node,
            format!(
                "{}: {}",
                Label(layout.dir, layout.number),
                wrong_length(frame, "its mapping", &needed.div_ceil(8).to_string()),
            ),
        );
    }
    let mut payload = [0u8; 8];
    payload[..frame.data().len()].copy_from_slice(frame.data());
    let mut offset = 0u32;
    for e in &layout.fields {
        let bits = e.bits as u32;
        let entry = MapEntry::new(e.index, e.sub, e.bits);
        if !entry.is_dummy() && offset + bits <= MAX_BITS {
            info.fields.push(PdoField {
                index: e.index,
                sub: e.sub,
                name: e.name.clone(),
                value: value(e.data_type, read_bits(&payload, offset, bits), bits),
            });
        }
        offset += bits;
    }
    DecodedFrame::Pdo(info)
}

/// A PDO of up to 64 bytes in a CAN FD frame (a CANopen FD network), on its predefined COB-ID:
/// the raw bytes (padding included).
pub(super) fn raw_fd(node: NodeId, dir: Dir, number: u8, frame: &FdFrame) -> DecodedFrame {
    DecodedFrame::Pdo(PdoInfo {
        node: Some(node),
        dir,
        number: number as u16,
        remote: false,
        data: frame.data().to_vec(),
        fields: Vec::new(),
    })
}

/// A PDO of up to 64 bytes in a CAN FD frame, by its layout: every entry of up to 64 bits at
/// its bit offset (an entry over 64 bits, a string or domain, is skipped as a dummy is); the
/// bytes after the mapping (the 0xCC padding) are not read.
pub(super) fn decode_fd(layout: &PdoLayout, frame: &FdFrame) -> DecodedFrame {
    let data = frame.data();
    let mut info = PdoInfo {
        node: layout.node,
        dir: layout.dir,
        number: layout.number,
        remote: false,
        data: data.to_vec(),
        fields: Vec::new(),
    };
    let needed: u32 = layout.fields.iter().map(|e| e.bits as u32).sum();
    let have = data.len() as u32 * 8;
    if needed > have {
        return bad(
            Kind::Pdo,
            layout.node,
            format!(
                "{}: CAN FD frame of {} bytes, its mapping has {}",
                Label(layout.dir, layout.number),
                data.len(),
                needed.div_ceil(8)
            ),
        );
    }
    let mut offset = 0u32;
    for e in &layout.fields {
        let bits = e.bits as u32;
        let entry = MapEntry::new(e.index, e.sub, e.bits);
        if !entry.is_dummy() && bits <= 64 && offset + bits <= FD_MAX_BITS {
            info.fields.push(PdoField {
                index: e.index,
                sub: e.sub,
                name: e.name.clone(),
                value: value(e.data_type, read_bits_wide(data, offset, bits), bits),
            });
        }
        offset += bits;
    }
    DecodedFrame::Pdo(info)
}

/// The `bits`-bit value `raw` as type `t`.
fn value(t: Option<DataType>, raw: u64, bits: u32) -> FieldValue {
    match t {
        Some(DataType::Boolean) => FieldValue::Bool(raw != 0),
        Some(t) if t.is_signed() && (1..64).contains(&bits) => {
            let shift = 64 - bits;
            FieldValue::Signed(((raw << shift) as i64) >> shift)
        }
        Some(t) if t.is_signed() => FieldValue::Signed(raw as i64),
        Some(DataType::Real32) if bits == 32 => FieldValue::Real(f32::from_bits(raw as u32) as f64),
        Some(DataType::Real64) if bits == 64 => FieldValue::Real(f64::from_bits(raw)),
        _ => FieldValue::Unsigned(raw),
    }
}

/// The unsigned value of an entry on node `node`, as the DCF configures it or the EDS defaults.
fn number(desc: &Description, node: NodeId, index: u16, sub: u8) -> Option<u64> {
    let e = desc.entry_at(index, sub)?;
    let b = e.value_bytes(node.raw());
    let mut buf = [0u8; 8];
    let n = b.len().min(8);
    buf[..n].copy_from_slice(&b[..n]);
    Some(u64::from_le_bytes(buf))
}

/// Every PDO of `node` that its description maps, by identifier.
pub(super) fn from_description(node: NodeId, desc: &Description) -> Vec<(Id, PdoLayout)> {
    let mut out = Vec::new();
    for (dir, comm, map) in [
        (Dir::Transmit, TPDO_COMM, TPDO_MAPPING),
        (Dir::Receive, RPDO_COMM, RPDO_MAPPING),
    ] {
        // 512 PDOs of each kind at most: the index ranges of CiA 301.
        for k in 0..512u16 {
            let Some(count) = number(desc, node, map + k, 0) else {
                continue;
            };
            let fields: Vec<PdoFieldDef> = (1..=count.min(64) as u8)
                .filter_map(|s| number(desc, node, map + k, s))
                .map(|raw| {
                    let entry = MapEntry::from_raw(raw as u32);
                    let def = PdoFieldDef::new(entry);
                    match desc.entry_at(entry.index, entry.sub) {
                        Some(e) if !entry.is_dummy() => def.with_name(&e.name, e.data_type),
                        _ => def,
                    }
                })
                .collect();
            if fields.is_empty() {
                continue;
            }
            let id = match number(desc, node, comm + k, 1) {
                Some(raw) => CobId(raw as u32).with_valid(true).can_id(),
                None if k < 4 => Some(match dir {
                    Dir::Transmit => predefined::tpdo(k as u8 + 1, node),
                    Dir::Receive => predefined::rpdo(k as u8 + 1, node),
                }),
                None => None,
            };
            // A switched-off PDO keeps its identifier in the low bits; one without (0) would
            // shadow NMT.
            if let Some(id) = id.filter(|id| id.raw() != 0) {
                let layout = PdoLayout {
                    node: Some(node),
                    dir,
                    number: k + 1,
                    fields,
                };
                out.push((id, layout));
            }
        }
    }
    out
}
