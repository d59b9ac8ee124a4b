//! The description: what an EDS or a DCF says about a device, and the dictionary a duocan node
//! builds from it.

use super::error::Warning;
use super::value::{self, Value};
use super::{DOMAIN_CAPACITY, STRING_CAPACITY};
use crate::od::{comm, Access, DataType, DefaultValue, DynamicDictionary, ObjectDef, ObjectType};
use alloc::collections::BTreeMap;
use alloc::string::String;
use alloc::vec::Vec;

/// Which kind of file a description came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum FileKind {
    /// An electronic data sheet: what a device can do.
    Eds,
    /// A device configuration file: an EDS plus one node's configuration (`ParameterValue`s,
    /// `[DeviceComissioning]`).
    Dcf,
}

/// `[FileInfo]`: about the file itself.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
#[non_exhaustive]
pub struct FileInfo {
    /// `FileName`.
    pub file_name: String,
    /// `FileVersion`.
    pub file_version: u8,
    /// `FileRevision`.
    pub file_revision: u8,
    /// `EDSVersion` (`4.0`).
    pub eds_version: String,
    /// `Description`.
    pub description: String,
    /// `CreationTime` (`hh:mm(AM|PM)`).
    pub creation_time: String,
    /// `CreationDate` (`mm-dd-yyyy`).
    pub creation_date: String,
    /// `CreatedBy`.
    pub created_by: String,
    /// `ModificationTime`.
    pub modification_time: String,
    /// `ModificationDate`.
    pub modification_date: String,
    /// `ModifiedBy`.
    pub modified_by: String,
    /// `LastEDS` (a DCF: the EDS it was made from).
    pub last_eds: String,
}

/// `[DeviceInfo]`: what the device is and what it supports.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
#[non_exhaustive]
pub struct DeviceInfo {
    /// `VendorName`.
    pub vendor_name: String,
    /// `VendorNumber` (0x1018 sub 1).
    pub vendor_number: Option<u32>,
    /// `ProductName`.
    pub product_name: String,
    /// `ProductNumber` (0x1018 sub 2).
    pub product_number: Option<u32>,
    /// `RevisionNumber` (0x1018 sub 3).
    pub revision_number: Option<u32>,
    /// `OrderCode`.
    pub order_code: String,
    /// The bit rates the device supports, in kbit/s (`BaudRate_10` … `BaudRate_1000`), ascending.
    pub baud_rates: Vec<u16>,
    /// `SimpleBootUpMaster`.
    pub simple_boot_up_master: bool,
    /// `SimpleBootUpSlave`.
    pub simple_boot_up_slave: bool,
    /// `Granularity`: the PDO mapping granularity in bits (0: mapping not changeable).
    pub granularity: u8,
    /// `DynamicChannelsSupported` (CiA 302-4 dynamic SDO channels).
    pub dynamic_channels_supported: u8,
    /// `GroupMessaging`.
    pub group_messaging: bool,
    /// `NrOfRXPDO`.
    pub nr_of_rx_pdo: u16,
    /// `NrOfTXPDO`.
    pub nr_of_tx_pdo: u16,
    /// `LSS_Supported`.
    pub lss_supported: bool,
    /// `CompactPDO`: which PDO communication parameters are implied for PDOs the file does not
    /// describe (bit 0 COB-ID, 1 transmission type, 2 inhibit time, 3 reserved, 4 event
    /// timer, 5 SYNC start value).
    pub compact_pdo: u8,
}

/// `[DeviceComissioning]` (so spelled by CiA 306): a DCF's node.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
#[non_exhaustive]
pub struct Commissioning {
    /// `NodeID`.
    pub node_id: Option<u8>,
    /// `NodeName`.
    pub node_name: String,
    /// `Baudrate`, kbit/s.
    pub baud_rate: Option<u16>,
    /// `NetNumber`.
    pub net_number: Option<u32>,
    /// `NetworkName`.
    pub network_name: String,
    /// `CANopenManager`: the node is the network's manager.
    pub canopen_manager: bool,
    /// `LSS_SerialNumber`.
    pub lss_serial_number: Option<u32>,
}

/// CiA 301 object codes (`ObjectType`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ObjectCode {
    /// 0x0 NULL.
    Null,
    /// 0x2 DOMAIN: a VAR of type DOMAIN.
    Domain,
    /// 0x5 DEFTYPE: a data type definition.
    DefType,
    /// 0x6 DEFSTRUCT: a structure definition.
    DefStruct,
    /// 0x7 VAR.
    Var,
    /// 0x8 ARRAY.
    Array,
    /// 0x9 RECORD.
    Record,
}

impl ObjectCode {
    /// The object code numbered `code`.
    #[must_use]
    pub const fn from_code(code: u32) -> Option<ObjectCode> {
        Some(match code {
            0 => ObjectCode::Null,
            2 => ObjectCode::Domain,
            5 => ObjectCode::DefType,
            6 => ObjectCode::DefStruct,
            7 => ObjectCode::Var,
            8 => ObjectCode::Array,
            9 => ObjectCode::Record,
            _ => return None,
        })
    }
    /// The number.
    #[must_use]
    pub const fn code(self) -> u8 {
        match self {
            ObjectCode::Null => 0,
            ObjectCode::Domain => 2,
            ObjectCode::DefType => 5,
            ObjectCode::DefStruct => 6,
            ObjectCode::Var => 7,
            ObjectCode::Array => 8,
            ObjectCode::Record => 9,
        }
    }
    /// True for the codes that hold sub-objects (ARRAY, RECORD, DEFSTRUCT).
    #[must_use]
    pub const fn has_subs(self) -> bool {
        matches!(
            self,
            ObjectCode::Array | ObjectCode::Record | ObjectCode::DefStruct
        )
    }
    /// The dictionary's object type, for the codes a dictionary holds (VAR, DOMAIN, ARRAY,
    /// RECORD).
    #[must_use]
    pub const fn object_type(self) -> Option<ObjectType> {
        match self {
            ObjectCode::Var | ObjectCode::Domain => Some(ObjectType::Var),
            ObjectCode::Array => Some(ObjectType::Array),
            ObjectCode::Record => Some(ObjectType::Record),
            _ => None,
        }
    }
}

/// `AccessType`: the access right from the bus, and for `rwr`/`rww` the PDO direction.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum AccessType {
    /// `ro`: read only.
    Ro,
    /// `wo`: write only.
    Wo,
    /// `rw`: read and write.
    Rw,
    /// `rwr`: read and write, mapped into TPDOs (a process input).
    Rwr,
    /// `rww`: read and write, mapped into RPDOs (a process output).
    Rww,
    /// `const`: read only, never changes.
    Const,
}

impl AccessType {
    /// Reads the CiA 306 spelling (any case).
    #[must_use]
    pub fn parse(text: &str) -> Option<AccessType> {
        let t = text.trim();
        [
            ("ro", AccessType::Ro),
            ("wo", AccessType::Wo),
            ("rw", AccessType::Rw),
            ("rwr", AccessType::Rwr),
            ("rww", AccessType::Rww),
            ("const", AccessType::Const),
        ]
        .into_iter()
        .find(|(s, _)| t.eq_ignore_ascii_case(s))
        .map(|(_, a)| a)
    }
    /// The CiA 306 spelling.
    #[must_use]
    pub const fn as_str(self) -> &'static str {
        match self {
            AccessType::Ro => "ro",
            AccessType::Wo => "wo",
            AccessType::Rw => "rw",
            AccessType::Rwr => "rwr",
            AccessType::Rww => "rww",
            AccessType::Const => "const",
        }
    }
    /// The dictionary's access right (`rwr` and `rww` are read-write).
    #[must_use]
    pub const fn access(self) -> Access {
        match self {
            AccessType::Ro => Access::Ro,
            AccessType::Wo => Access::Wo,
            AccessType::Rw | AccessType::Rwr | AccessType::Rww => Access::Rw,
            AccessType::Const => Access::Const,
        }
    }
    /// The access type a dictionary's access right is written as.
    #[must_use]
    pub const fn of(access: Access) -> AccessType {
        match access {
            Access::Ro => AccessType::Ro,
            Access::Wo => AccessType::Wo,
            Access::Rw => AccessType::Rw,
            Access::Const => AccessType::Const,
        }
    }
}

/// An object: a VAR, or an ARRAY or RECORD with its sub-objects.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub struct Object {
    /// Index.
    pub index: u16,
    /// `ParameterName`.
    pub name: String,
    /// `Denotation` (a DCF's name for this node's object).
    pub denotation: Option<String>,
    /// `ObjectType`.
    pub code: ObjectCode,
    /// The entries: sub-index 0 alone for a VAR.
    pub subs: BTreeMap<u8, SubObject>,
    /// `[xxxxObjectLinks]`: the objects this one links to.
    pub links: Vec<u16>,
    /// Written with `CompactSubObj`.
    pub compact: bool,
    /// Implied by `CompactPDO`, not written in the file.
    pub implicit: bool,
    /// The line of its section (0 for an implied object).
    pub line: u32,
}

/// One entry (index, sub-index) with everything the file says about it.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub struct SubObject {
    /// Index.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// `ParameterName`.
    pub name: String,
    /// `Denotation`.
    pub denotation: Option<String>,
    /// `DataType`.
    pub data_type: DataType,
    /// `AccessType`.
    pub access: AccessType,
    /// `PDOMapping`.
    pub pdo_mapping: bool,
    /// `DefaultValue`; `None`: zero (empty for strings and domains).
    pub default: Option<Value>,
    /// `LowLimit`.
    pub low: Option<Value>,
    /// `HighLimit`.
    pub high: Option<Value>,
    /// `ParameterValue` (DCF): the value this node is configured with.
    pub value: Option<Value>,
    /// `UploadFile`: the file a DOMAIN's value is read into (name only; not read).
    pub upload_file: Option<String>,
    /// `DownloadFile`: the file a DOMAIN's value is written from (name only; not read).
    pub download_file: Option<String>,
    /// `ObjFlags`.
    pub obj_flags: u32,
    /// `MaxLength` (strings and domains): the largest value in bytes. Not a CiA 306 key:
    /// duocan writes it so that a dictionary's capacities survive the round trip; other tools
    /// ignore it.
    pub max_length: Option<u32>,
    /// The line of its section (0 for an implied entry).
    pub line: u32,
}

impl SubObject {
    /// The default's bytes on node `node_id` (zero, or empty for strings, without one).
    #[must_use]
    pub fn default_bytes(&self, node_id: u8) -> Vec<u8> {
        match &self.default {
            Some(v) => v.to_bytes(self.data_type, node_id),
            None => alloc::vec![0; self.data_type.fixed_size().unwrap_or(0)],
        }
    }

    /// The value the node is configured with: the DCF's `ParameterValue`, else the default.
    #[must_use]
    pub fn value_bytes(&self, node_id: u8) -> Vec<u8> {
        match &self.value {
            Some(v) => v.to_bytes(self.data_type, node_id),
            None => self.default_bytes(node_id),
        }
    }

    /// The capacity a dictionary entry gets: `MaxLength`, else the default's size (at least
    /// [`STRING_CAPACITY`] or [`DOMAIN_CAPACITY`]), and always room for the default and the
    /// value. Zero for fixed-size types.
    #[must_use]
    pub fn capacity(&self) -> u32 {
        if self.data_type.fixed_size().is_some() {
            return 0;
        }
        let len = |v: &Option<Value>| match v {
            Some(Value::Bytes(b)) => b.len() as u32,
            _ => 0,
        };
        let floor = match self.max_length {
            Some(m) => m,
            None if self.data_type == DataType::Domain => DOMAIN_CAPACITY,
            None => STRING_CAPACITY,
        };
        floor.max(len(&self.default)).max(len(&self.value))
    }

    /// The dictionary definition on node `node_id`, without its name, and the default's bytes
    /// when the definition cannot hold them (strings and domains).
    #[must_use]
    pub fn def(&self, object_type: ObjectType, node_id: u8) -> (ObjectDef, Option<Vec<u8>>) {
        let t = self.data_type;
        let mut def = ObjectDef::new(self.index, self.sub, t)
            .access(self.access.access())
            .object_type(object_type);
        def.pdo_mappable = self.pdo_mapping;
        def.capacity = self.capacity();
        def = def.bounds(
            self.low.as_ref().and_then(|v| v.to_limit(t, node_id)),
            self.high.as_ref().and_then(|v| v.to_limit(t, node_id)),
        );
        let mut owned = None;
        let default = match &self.default {
            None => DefaultValue::Zero,
            Some(Value::Unsigned(v)) => DefaultValue::Unsigned(*v),
            Some(Value::Signed(v)) => DefaultValue::Signed(*v),
            Some(Value::Real(v)) => DefaultValue::Real(*v),
            Some(Value::NodeIdPlus(v)) => DefaultValue::NodeIdPlus(*v),
            Some(Value::Bytes(b)) if value::is_number(t) => {
                // Bytes for a number: as the bus carries them.
                let mut buf = [0u8; 8];
                let n = b.len().min(8);
                buf[..n].copy_from_slice(&b[..n]);
                DefaultValue::Unsigned(u64::from_le_bytes(buf))
            }
            Some(Value::Bytes(b)) => {
                owned = Some(b.clone());
                DefaultValue::Zero
            }
        };
        def = def.default(default);
        (def, owned)
    }
}

/// What an EDS or DCF describes: the file's and device's information and every object, with
/// names, types, limits, access, defaults, PDO mappability and (a DCF) the configured values.
///
/// Read one with [`Description::read`] or [`Description::parse`]; look entries up by name or
/// address with [`entry`](Description::entry); build a node's dictionary with
/// [`dictionary`](Description::dictionary).
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub struct Description {
    /// The file's name, as errors and warnings name it.
    pub source: String,
    /// EDS or DCF: a DCF has `[DeviceComissioning]` or `ParameterValue`s.
    pub kind: FileKind,
    /// `[FileInfo]`.
    pub file_info: FileInfo,
    /// `[DeviceInfo]`.
    pub device_info: DeviceInfo,
    /// `[DummyUsage]`: bit `n` set when data type `n` may be mapped as a PDO dummy
    /// (`Dummy000n=1`).
    pub dummy_usage: u32,
    /// `[Comments]`, one string per line.
    pub comments: Vec<String>,
    /// `[DeviceComissioning]` of a DCF.
    pub commissioning: Option<Commissioning>,
    /// Every object, by index.
    pub objects: BTreeMap<u16, Object>,
    /// What a lenient import accepted although the file got it wrong (at most
    /// [`MAX_WARNINGS`](super::MAX_WARNINGS)).
    pub warnings: Vec<Warning>,
    /// Warnings beyond [`MAX_WARNINGS`](super::MAX_WARNINGS), counted.
    pub warnings_dropped: usize,
}

impl Description {
    /// The object at `index`.
    #[must_use]
    pub fn object_at(&self, index: u16) -> Option<&Object> {
        self.objects.get(&index)
    }

    /// The entry at (`index`, `sub`).
    #[must_use]
    pub fn entry_at(&self, index: u16, sub: u8) -> Option<&SubObject> {
        self.objects.get(&index)?.subs.get(&sub)
    }

    /// Every entry, by index and sub-index.
    pub fn entries(&self) -> impl Iterator<Item = &SubObject> {
        self.objects.values().flat_map(|o| o.subs.values())
    }

    /// The number of entries.
    #[must_use]
    pub fn len(&self) -> usize {
        self.objects.values().map(|o| o.subs.len()).sum()
    }

    /// True when the file describes no object.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.objects.is_empty()
    }

    /// The entries a DCF configures (those with a `ParameterValue`), by index and sub-index.
    pub fn parameter_values(&self) -> impl Iterator<Item = &SubObject> {
        self.entries().filter(|s| s.value.is_some())
    }

    /// True when `[DummyUsage]` allows data type `t` as a PDO dummy.
    #[must_use]
    pub fn dummy_allowed(&self, t: DataType) -> bool {
        let code = t as u16;
        code < 32 && self.dummy_usage & (1 << code) != 0
    }

    /// The dictionary of a duocan node with node-ID `node_id` built from the description:
    /// every VAR, ARRAY and RECORD entry with its name, type, access, PDO mappability, limits
    /// and default, holding the DCF's `ParameterValue` where there is one (its default
    /// elsewhere). Type definitions (DEFTYPE, DEFSTRUCT) are not entries. Sub-index 0 of an
    /// array or record carries the object's name, as duocan's own tables do, and the
    /// communication objects CiA 301 restricts get the stack's write hooks
    /// ([`comm::HOOKS`]).
    #[must_use]
    pub fn dictionary(&self, node_id: u8) -> DynamicDictionary {
        let mut od = DynamicDictionary::new(node_id);
        for o in self.objects.values() {
            let Some(ot) = o.code.object_type() else {
                continue;
            };
            for s in o.subs.values() {
                let (mut def, owned) = s.def(ot, node_id);
                def.hook = comm::hook(s.index, s.sub);
                let name = if s.sub == 0 && ot != ObjectType::Var {
                    &o.name
                } else {
                    &s.name
                };
                // Keys are unique and capacities hold the defaults: this cannot fail.
                let _ = od.insert_owned(def, name, owned.as_deref());
                if s.value.is_some() {
                    let _ = crate::od::ObjectDictionary::store(
                        &mut od,
                        s.index,
                        s.sub,
                        &s.value_bytes(node_id),
                    );
                }
            }
        }
        od
    }
}
