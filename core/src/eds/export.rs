//! Export: any duocan dictionary, static or dynamic, as an EDS or a DCF.
//!
//! Objects are grouped by index: an index whose entries are VARs at sub-index 0 is a VAR, any
//! other an ARRAY or RECORD (the object type of its sub-index 0), named after its sub-index 0
//! (duocan's tables name sub-index 0 of an array or record after the object). Defaults are
//! written as the dictionary makes them, `$NODEID+…` where the definition is node-relative;
//! limits as the dictionary compares them; string and domain capacities as `MaxLength` (not a
//! CiA 306 key; other tools ignore it). A DCF adds `[DeviceComissioning]` and every entry's
//! current value as its `ParameterValue`. Write hooks are code and are not exported.

use super::error::ExportError;
use super::model::AccessType;
use super::value::{self, unsigned_text};
use crate::od::{default_vec, DefaultValue, Limit, ObjectDef, ObjectDictionary, ObjectType};
use alloc::collections::BTreeMap;
use alloc::string::String;
use alloc::vec;
use alloc::vec::Vec;
use core::fmt::Write;

/// What the dictionary does not say about the device: file and device information, the
/// DCF's commissioning. Everything has a default.
#[derive(Clone, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub struct ExportOptions {
    /// `[FileInfo] FileName`.
    pub file_name: String,
    /// `[FileInfo] Description`.
    pub description: String,
    /// `[FileInfo] CreatedBy`.
    pub created_by: String,
    /// `[FileInfo] CreationDate` (`mm-dd-yyyy`; not written when empty).
    pub creation_date: String,
    /// `[FileInfo] CreationTime` (`hh:mm(AM|PM)`; not written when empty).
    pub creation_time: String,
    /// `[DeviceInfo] VendorName`.
    pub vendor_name: String,
    /// `[DeviceInfo] ProductName` (empty: the dictionary's 0x1008, else "duocan node").
    pub product_name: String,
    /// `[DeviceInfo] OrderCode`.
    pub order_code: String,
    /// `[DeviceInfo] BaudRate_…`: the bit rates in kbit/s (default: all eight of CiA 301).
    pub baud_rates: Vec<u16>,
    /// `[DeviceInfo] Granularity` (default 8).
    pub granularity: u8,
    /// `[DeviceInfo] LSS_Supported`.
    pub lss_supported: bool,
    /// `[DeviceInfo] SimpleBootUpMaster` (a master's dictionary).
    pub boot_up_master: bool,
    /// `[Comments]`, one string per line.
    pub comments: Vec<String>,
    /// DCF: `[DeviceComissioning] NodeName`.
    pub node_name: String,
    /// DCF: `[DeviceComissioning] Baudrate`, kbit/s.
    pub baud_rate: Option<u16>,
    /// DCF: `[DeviceComissioning] NetNumber`.
    pub net_number: Option<u32>,
    /// DCF: `[DeviceComissioning] NetworkName`.
    pub network_name: String,
    /// DCF: `[FileInfo] LastEDS`, the EDS the DCF was made from.
    pub last_eds: String,
}

impl Default for ExportOptions {
    fn default() -> Self {
        ExportOptions {
            file_name: String::new(),
            description: String::new(),
            created_by: "duocan".into(),
            creation_date: String::new(),
            creation_time: String::new(),
            vendor_name: String::new(),
            product_name: String::new(),
            order_code: String::new(),
            baud_rates: vec![10, 20, 50, 125, 250, 500, 800, 1000],
            granularity: 8,
            lss_supported: false,
            boot_up_master: false,
            comments: Vec::new(),
            node_name: String::new(),
            baud_rate: None,
            net_number: None,
            network_name: String::new(),
            last_eds: String::new(),
        }
    }
}

impl ExportOptions {
    /// Sets the file name.
    #[must_use]
    pub fn with_file_name(mut self, name: &str) -> Self {
        self.file_name = name.into();
        self
    }
    /// Sets the vendor's name.
    #[must_use]
    pub fn with_vendor_name(mut self, name: &str) -> Self {
        self.vendor_name = name.into();
        self
    }
    /// Sets the product's name.
    #[must_use]
    pub fn with_product_name(mut self, name: &str) -> Self {
        self.product_name = name.into();
        self
    }
    /// Sets the file's description.
    #[must_use]
    pub fn with_description(mut self, text: &str) -> Self {
        self.description = text.into();
        self
    }
    /// Sets the supported bit rates (kbit/s).
    #[must_use]
    pub fn with_baud_rates(mut self, rates: &[u16]) -> Self {
        self.baud_rates = rates.into();
        self
    }
    /// Sets the comment lines.
    #[must_use]
    pub fn with_comments(mut self, lines: &[&str]) -> Self {
        self.comments = lines.iter().map(|l| String::from(*l)).collect();
        self
    }
    /// Sets the DCF's node name.
    #[must_use]
    pub fn with_node_name(mut self, name: &str) -> Self {
        self.node_name = name.into();
        self
    }
    /// Sets the DCF's bit rate (kbit/s).
    #[must_use]
    pub fn with_baud_rate(mut self, kbit: u16) -> Self {
        self.baud_rate = Some(kbit);
        self
    }
    /// Marks the dictionary as a master's (`SimpleBootUpMaster=1`).
    #[must_use]
    pub fn with_boot_up_master(mut self, master: bool) -> Self {
        self.boot_up_master = master;
        self
    }
}

/// One entry, copied out of the dictionary.
struct Snap {
    def: ObjectDef,
    data: Vec<u8>,
    name: String,
    default: Option<Vec<u8>>,
}

/// Writes `od` as an EDS.
pub fn export_eds<D: ObjectDictionary + ?Sized>(
    od: &D,
    opts: &ExportOptions,
) -> Result<String, ExportError> {
    write(od, opts, false)
}

/// Writes `od` as the DCF of its node (`[DeviceComissioning] NodeID` is the dictionary's
/// node-ID): the EDS plus every entry's current value as its `ParameterValue`.
pub fn export_dcf<D: ObjectDictionary + ?Sized>(
    od: &D,
    opts: &ExportOptions,
) -> Result<String, ExportError> {
    write(od, opts, true)
}

fn write<D: ObjectDictionary + ?Sized>(
    od: &D,
    opts: &ExportOptions,
    dcf: bool,
) -> Result<String, ExportError> {
    let mut objects: BTreeMap<u16, Vec<Snap>> = BTreeMap::new();
    od.for_each(&mut |e| {
        objects.entry(e.def.index).or_default().push(Snap {
            def: *e.def,
            data: e.data.to_vec(),
            name: e.name.into(),
            default: e.default_bytes.map(<[u8]>::to_vec),
        });
    });
    for subs in objects.values_mut() {
        subs.sort_by_key(|s| s.def.sub);
    }
    let node_id = od.node_id();
    let mut out = String::new();
    header(&mut out, &objects, opts, node_id, dcf)?;
    for (index, subs) in &objects {
        object(&mut out, *index, subs, node_id, dcf)?;
    }
    Ok(out)
}

fn u32_default(
    objects: &BTreeMap<u16, Vec<Snap>>,
    index: u16,
    sub: u8,
    node_id: u8,
) -> Option<u32> {
    let s = objects.get(&index)?.iter().find(|s| s.def.sub == sub)?;
    let b = default_bytes(s, node_id);
    Some(u32::from_le_bytes(b.get(..4)?.try_into().ok()?))
}

fn header(
    out: &mut String,
    objects: &BTreeMap<u16, Vec<Snap>>,
    opts: &ExportOptions,
    node_id: u8,
    dcf: bool,
) -> Result<(), ExportError> {
    let kv = |out: &mut String, k: &str, v: &str| {
        let _ = writeln!(out, "{k}={v}");
    };
    out.push_str("[FileInfo]\n");
    kv(out, "FileName", &opts.file_name);
    kv(out, "FileVersion", "1");
    kv(out, "FileRevision", "0");
    kv(out, "EDSVersion", "4.0");
    kv(out, "Description", &opts.description);
    if !opts.creation_date.is_empty() {
        kv(out, "CreationDate", &opts.creation_date);
    }
    if !opts.creation_time.is_empty() {
        kv(out, "CreationTime", &opts.creation_time);
    }
    kv(out, "CreatedBy", &opts.created_by);
    if dcf && !opts.last_eds.is_empty() {
        kv(out, "LastEDS", &opts.last_eds);
    }
    out.push_str("\n[DeviceInfo]\n");
    kv(out, "VendorName", &opts.vendor_name);
    if let Some(v) = u32_default(objects, 0x1018, 1, node_id) {
        kv(out, "VendorNumber", &unsigned_text(v as u64));
    }
    let product = if !opts.product_name.is_empty() {
        opts.product_name.clone()
    } else {
        objects
            .get(&0x1008)
            .and_then(|s| s.first())
            .and_then(|s| String::from_utf8(default_bytes(s, node_id)).ok())
            .filter(|s| {
                !s.is_empty()
                    && value::write(crate::od::DataType::VisibleString, s.as_bytes()).is_ok()
            })
            .unwrap_or_else(|| "duocan node".into())
    };
    kv(out, "ProductName", &product);
    if let Some(v) = u32_default(objects, 0x1018, 2, node_id) {
        kv(out, "ProductNumber", &unsigned_text(v as u64));
    }
    if let Some(v) = u32_default(objects, 0x1018, 3, node_id) {
        kv(out, "RevisionNumber", &unsigned_text(v as u64));
    }
    kv(out, "OrderCode", &opts.order_code);
    for rate in [10u16, 20, 50, 125, 250, 500, 800, 1000] {
        let on = opts.baud_rates.contains(&rate) as u8;
        let _ = writeln!(out, "BaudRate_{rate}={on}");
    }
    let _ = writeln!(out, "SimpleBootUpMaster={}", opts.boot_up_master as u8);
    let _ = writeln!(out, "SimpleBootUpSlave={}", !opts.boot_up_master as u8);
    let _ = writeln!(out, "Granularity={}", opts.granularity);
    out.push_str("DynamicChannelsSupported=0\nGroupMessaging=0\n");
    let count = |r: core::ops::RangeInclusive<u16>| objects.range(r).count();
    let _ = writeln!(out, "NrOfRXPDO={}", count(0x1400..=0x15FF));
    let _ = writeln!(out, "NrOfTXPDO={}", count(0x1800..=0x19FF));
    let _ = writeln!(out, "LSS_Supported={}", opts.lss_supported as u8);
    out.push_str("CompactPDO=0\n");
    // The PDO engine maps every fixed-size type as a dummy; CiA 306 lists the first seven.
    out.push_str("\n[DummyUsage]\n");
    for code in 1..=7 {
        let _ = writeln!(out, "Dummy{code:04X}=1");
    }
    if !opts.comments.is_empty() {
        let _ = writeln!(out, "\n[Comments]\nLines={}", opts.comments.len());
        for (i, l) in opts.comments.iter().enumerate() {
            if l.contains(['\n', '\r']) {
                return Err(ExportError::Unrepresentable {
                    index: 0,
                    sub: 0,
                    why: "a comment line holds a line break",
                });
            }
            let _ = writeln!(out, "Line{}={l}", i + 1);
        }
    }
    let mandatory: Vec<u16> = [0x1000, 0x1001, 0x1018]
        .into_iter()
        .filter(|i| objects.contains_key(i))
        .collect();
    let manufacturer: Vec<u16> = objects.range(0x2000..=0x5FFF).map(|(i, _)| *i).collect();
    let optional: Vec<u16> = objects
        .keys()
        .copied()
        .filter(|i| !mandatory.contains(i) && !(0x2000..=0x5FFF).contains(i))
        .collect();
    for (name, list) in [
        ("MandatoryObjects", mandatory),
        ("OptionalObjects", optional),
        ("ManufacturerObjects", manufacturer),
    ] {
        let _ = writeln!(out, "\n[{name}]\nSupportedObjects={}", list.len());
        for (i, index) in list.iter().enumerate() {
            let _ = writeln!(out, "{}=0x{index:04X}", i + 1);
        }
    }
    if dcf {
        let _ = writeln!(out, "\n[DeviceComissioning]\nNodeID={node_id}");
        kv(out, "NodeName", &opts.node_name);
        if let Some(b) = opts.baud_rate {
            let _ = writeln!(out, "Baudrate={b}");
        }
        if let Some(n) = opts.net_number {
            let _ = writeln!(out, "NetNumber={n}");
        }
        kv(out, "NetworkName", &opts.network_name);
        let _ = writeln!(out, "CANopenManager={}", opts.boot_up_master as u8);
    }
    Ok(())
}

/// Whether zero lies within the limits `low` and `high` (each absent: no bound).
fn zero_within(low: Option<Limit>, high: Option<Limit>) -> bool {
    let sign = |l: Limit| match l {
        Limit::Unsigned(v) => v.cmp(&0),
        Limit::Signed(v) => v.cmp(&0),
        Limit::Real(v) => v.partial_cmp(&0.0).unwrap_or(core::cmp::Ordering::Equal),
    };
    low.is_none_or(|l| sign(l).is_le()) && high.is_none_or(|h| sign(h).is_ge())
}

fn default_bytes(s: &Snap, node_id: u8) -> Vec<u8> {
    match &s.default {
        Some(d) => d.clone(),
        None => default_vec(&s.def, node_id),
    }
}

fn object(
    out: &mut String,
    index: u16,
    subs: &[Snap],
    node_id: u8,
    dcf: bool,
) -> Result<(), ExportError> {
    let Some(first) = subs.first() else {
        return Ok(());
    };
    let var = subs.len() == 1 && first.def.sub == 0 && first.def.object_type == ObjectType::Var;
    if var {
        let _ = writeln!(out, "\n[{index:04X}]");
        return entry(out, first, &first.name, node_id, dcf);
    }
    let (code, sub0_name) = match first.def.object_type {
        ObjectType::Array => (8, "Number of entries"),
        _ => (9, "Highest sub-index supported"),
    };
    let _ = writeln!(
        out,
        "\n[{index:04X}]\nParameterName={}\nObjectType=0x{code:X}\nSubNumber=0x{:X}",
        text(&first.name, index, first.def.sub)?,
        subs.len()
    );
    for s in subs {
        let _ = writeln!(out, "\n[{index:04X}sub{:X}]", s.def.sub);
        let name = if s.def.sub == 0 { sub0_name } else { &s.name };
        entry(out, s, name, node_id, dcf)?;
    }
    Ok(())
}

/// A name as a value: the file cannot carry line breaks or surrounding spaces.
fn text(name: &str, index: u16, sub: u8) -> Result<&str, ExportError> {
    value::write(crate::od::DataType::VisibleString, name.as_bytes())
        .map(|_| name)
        .map_err(|why| ExportError::Unrepresentable { index, sub, why })
}

fn entry(
    out: &mut String,
    s: &Snap,
    name: &str,
    node_id: u8,
    dcf: bool,
) -> Result<(), ExportError> {
    let d = &s.def;
    let t = d.data_type;
    let err = |why| ExportError::Unrepresentable {
        index: d.index,
        sub: d.sub,
        why,
    };
    let _ = writeln!(out, "ParameterName={}", text(name, d.index, d.sub)?);
    let _ = writeln!(out, "ObjectType=0x7\nDataType=0x{:04X}", t as u16);
    let _ = writeln!(out, "AccessType={}", AccessType::of(d.access).as_str());
    let default = match d.default_value() {
        DefaultValue::NodeIdPlus(x) if s.default.is_none() && t.fixed_size().is_some() => {
            Some(alloc::format!("$NODEID+0x{x:X}"))
        }
        // No default given, and zero outside the limits: none written (a reader takes the
        // entry's limits to be kept; `DefaultValue=0` made the file invalid).
        DefaultValue::Zero if s.default.is_none() && !zero_within(d.low(), d.high()) => None,
        _ => Some(value::write(t, &default_bytes(s, node_id)).map_err(err)?),
    };
    if let Some(default) = default {
        let _ = writeln!(out, "DefaultValue={default}");
    }
    let _ = writeln!(out, "PDOMapping={}", d.pdo_mappable as u8);
    for (key, limit) in [("LowLimit", d.low()), ("HighLimit", d.high())] {
        if let Some(text) = limit.and_then(|l| value::write_limit(t, l)) {
            let _ = writeln!(out, "{key}={text}");
        }
    }
    if t.fixed_size().is_none() {
        let _ = writeln!(out, "MaxLength={}", d.capacity);
    }
    if dcf {
        let _ = writeln!(
            out,
            "ParameterValue={}",
            value::write(t, &s.data).map_err(err)?
        );
    }
    Ok(())
}
