//! One file per quirk of real device descriptions, each imported strict and lenient alike,
//! and what was read from it.

use crate::clean;
use duocan::eds::{AccessType, FileKind, ObjectCode, Value};
use duocan::od::{Access, DataType, Limit, ObjectDictionary, ObjectType};
use duocan::AbortCode;

#[test]
fn sections_and_keys_in_any_case_with_comments_and_crlf() {
    let d = clean("case_and_comments.eds");
    assert_eq!(
        d.device_info.vendor_name, "duocan tests",
        "[DEVICEINFO] vendorname="
    );
    assert_eq!(
        d.entry_at(0x1018, 1).unwrap().name,
        "Vendor-ID",
        "[1018SUB1]"
    );
    let e = d.entry_at(0x2000, 0).unwrap();
    assert_eq!(e.name, "Lower case keys");
    assert_eq!(e.access, AccessType::Rw, "ACCESSTYPE=RW");
    assert_eq!(e.data_type, DataType::Unsigned32);
    assert_eq!(
        e.default,
        Some(Value::Unsigned(0x1234_5678)),
        "comment after a number"
    );
    // A string keeps what follows its `;`: only numbers have comments.
    let s = d.entry_at(0x2001, 0).unwrap();
    assert_eq!(s.name, "Text with a ; inside");
    assert_eq!(
        s.default,
        Some(Value::Bytes(
            b"a;b ; strings keep their semicolons".to_vec()
        ))
    );
    assert_eq!(e.line, 113, "lines count from 1, CRLF or not");
}

#[test]
fn decimal_hex_and_octal_numbers() {
    let d = clean("numbers.eds");
    let default = |i| d.entry_at(i, 0).unwrap().default.clone().unwrap();
    assert_eq!(default(0x2000), Value::Unsigned(1000));
    assert_eq!(default(0x2001), Value::Unsigned(1000));
    assert_eq!(default(0x2002), Value::Unsigned(1000), "01750 is octal");
    assert_eq!(
        default(0x2003),
        Value::Signed(-1),
        "0xFFFF of INTEGER16 is −1"
    );
    assert_eq!(default(0x2004), Value::Signed(-1000));
    let l = d.entry_at(0x2005, 0).unwrap();
    assert_eq!(l.low, Some(Value::Signed(-16)), "-0x10");
    assert_eq!(l.high, Some(Value::Signed(i32::MAX as i64)));
    assert_eq!(
        d.entry_at(0x2006, 0).unwrap().data_type,
        DataType::Unsigned8,
        "DataType=5"
    );
    assert_eq!(default(0x2007), Value::Unsigned(u64::MAX));
    let od = d.dictionary(1);
    assert_eq!(od.get_value::<i16>(0x2003, 0), Ok(-1));
    assert_eq!(od.get_value::<u16>(0x2002, 0), Ok(1000));
}

#[test]
fn node_id_expressions_either_way_round() {
    let d = clean("nodeid.eds");
    assert_eq!(
        d.entry_at(0x1014, 0).unwrap().default,
        Some(Value::NodeIdPlus(0x80))
    );
    assert_eq!(
        d.entry_at(0x1200, 1).unwrap().default,
        Some(Value::NodeIdPlus(0x600))
    );
    assert_eq!(
        d.entry_at(0x1200, 2).unwrap().default,
        Some(Value::NodeIdPlus(0x580))
    );
    assert_eq!(
        d.entry_at(0x2000, 0).unwrap().default,
        Some(Value::NodeIdPlus(0))
    );
    for node in [5u8, 0x7F] {
        let od = d.dictionary(node);
        assert_eq!(od.get_value::<u32>(0x1014, 0), Ok(0x80 + node as u32));
        assert_eq!(od.get_value::<u32>(0x1200, 1), Ok(0x600 + node as u32));
        assert_eq!(od.get_value::<u32>(0x1200, 2), Ok(0x580 + node as u32));
        assert_eq!(od.get_value::<u8>(0x2000, 0), Ok(node));
    }
}

#[test]
fn compact_sub_objects_with_their_names() {
    let d = clean("compact_subobj.eds");
    let o = d.object_at(0x1016).unwrap();
    assert!(o.compact);
    assert_eq!(o.code, ObjectCode::Array);
    assert_eq!(o.subs.keys().copied().collect::<Vec<_>>(), [0, 1, 2, 3, 4]);
    let s0 = &o.subs[&0];
    assert_eq!(
        (s0.name.as_str(), s0.data_type, s0.access),
        ("NrOfObjects", DataType::Unsigned8, AccessType::Ro)
    );
    assert_eq!(s0.default, Some(Value::Unsigned(4)));
    assert_eq!(o.subs[&1].name, "Heartbeat of node 2", "[1016Name] 1=");
    assert_eq!(
        o.subs[&2].name, "Consumer heartbeat time2",
        "no name given: object name + sub-index"
    );
    assert_eq!(o.subs[&3].name, "Heartbeat of node 4");
    assert_eq!(o.subs[&4].data_type, DataType::Unsigned32);
    assert_eq!(o.subs[&4].access, AccessType::Rw);
    let gain = d.object_at(0x2000).unwrap();
    assert_eq!(gain.subs.len(), 4);
    assert!(gain
        .subs
        .values()
        .skip(1)
        .all(|s| s.pdo_mapping && s.default == Some(Value::Unsigned(7))));
    let od = d.dictionary(1);
    assert_eq!(od.get_value::<u8>(0x1016, 0), Ok(4));
    assert_eq!(
        od.get(0x1016, 0).unwrap().name,
        "Consumer heartbeat time",
        "sub 0 names the array"
    );
    assert_eq!(od.get(0x1016, 3).unwrap().name, "Heartbeat of node 4");
    assert_eq!(
        od.get(0x1016, 0).unwrap().def.object_type,
        ObjectType::Array
    );
    assert_eq!(od.get_value::<u8>(0x2000, 3), Ok(7));
}

#[test]
fn compact_pdo_implies_the_pdos_the_file_does_not_describe() {
    let d = clean("compact_pdo.eds");
    assert_eq!(d.device_info.compact_pdo, 0x13);
    // RPDO1's communication object is in the file; its mapping, RPDO2 and TPDO1 are implied.
    assert!(!d.object_at(0x1400).unwrap().implicit);
    assert_eq!(
        d.object_at(0x1400).unwrap().subs.len(),
        3,
        "the file's own, not completed"
    );
    for i in [0x1600, 0x1401, 0x1601, 0x1800, 0x1A00] {
        assert!(
            d.object_at(i).unwrap_or_else(|| panic!("{i:#x}")).implicit,
            "{i:#x}"
        );
    }
    assert!(d.object_at(0x1402).is_none() && d.object_at(0x1801).is_none());
    let rpdo2 = d.object_at(0x1401).unwrap();
    // 0x13: COB-ID, transmission type, event timer.
    assert_eq!(rpdo2.subs.keys().copied().collect::<Vec<_>>(), [0, 1, 2, 5]);
    assert_eq!(
        rpdo2.subs[&0].default,
        Some(Value::Unsigned(5)),
        "highest sub-index"
    );
    assert_eq!(rpdo2.subs[&1].default, Some(Value::NodeIdPlus(0x300)));
    assert_eq!(rpdo2.subs[&1].name, "COB-ID used by RPDO");
    let map = d.object_at(0x1A00).unwrap();
    assert_eq!(map.subs.len(), 65);
    assert_eq!(map.subs[&64].name, "Application object 64");
    let od = d.dictionary(3);
    assert_eq!(od.get_value::<u32>(0x1401, 1), Ok(0x303));
    assert_eq!(od.get_value::<u32>(0x1800, 1), Ok(0x183));
    assert_eq!(od.get_value::<u32>(0x1400, 1), Ok(0x203));
}

#[test]
fn dummy_usage() {
    let d = clean("dummy_usage.eds");
    assert!(!d.dummy_allowed(DataType::Boolean));
    assert!(d.dummy_allowed(DataType::Integer8));
    assert!(!d.dummy_allowed(DataType::Integer32));
    assert!(d.dummy_allowed(DataType::Unsigned32));
    assert_eq!(d.dummy_usage, 0b1110_1100);
}

#[test]
fn object_links() {
    let d = clean("object_links.eds");
    assert_eq!(d.object_at(0x6000).unwrap().links, [0x6200, 0x6401]);
    assert!(d.object_at(0x6200).unwrap().links.is_empty());
    assert_eq!(d.entry_at(0x6200, 0).unwrap().access, AccessType::Rww);
}

#[test]
fn comments() {
    let d = clean("comments.eds");
    assert_eq!(
        d.comments,
        [
            "Written for the duocan tests.",
            "Indented text is trimmed like any value.",
            "The third line; with a semicolon."
        ]
    );
}

#[test]
fn device_and_file_info() {
    let d = clean("device_info.eds");
    let i = &d.device_info;
    assert_eq!(i.baud_rates, [10, 50, 125, 500, 1000]);
    assert_eq!((i.nr_of_rx_pdo, i.nr_of_tx_pdo), (4, 2));
    assert_eq!(i.granularity, 1);
    assert!(
        i.lss_supported && i.simple_boot_up_master && i.simple_boot_up_slave && i.group_messaging
    );
    assert_eq!(i.dynamic_channels_supported, 3);
    assert_eq!(
        (i.vendor_number, i.product_number, i.revision_number),
        (Some(0xD0CA), Some(1), Some(0x10001))
    );
    assert_eq!(
        (
            i.vendor_name.as_str(),
            i.product_name.as_str(),
            i.order_code.as_str()
        ),
        ("duocan tests", "Test device", "T-1")
    );
    let f = &d.file_info;
    assert_eq!(f.file_name, "device_info.eds");
    assert_eq!(
        (f.file_version, f.file_revision, f.eds_version.as_str()),
        (1, 0, "4.0")
    );
    assert_eq!(
        (f.creation_date.as_str(), f.creation_time.as_str()),
        ("01-15-2026", "09:00AM")
    );
    assert_eq!(
        (
            f.modification_date.as_str(),
            f.modification_time.as_str(),
            f.modified_by.as_str()
        ),
        ("02-01-2026", "10:30PM", "a tester")
    );
    assert_eq!(d.kind, FileKind::Eds);
    assert!(d.commissioning.is_none());
}

#[test]
fn dcf_values_denotations_and_commissioning() {
    let d = clean("commissioning.dcf");
    assert_eq!(d.kind, FileKind::Dcf);
    assert_eq!(d.file_info.last_eds, "turnout.eds");
    let c = d.commissioning.as_ref().unwrap();
    assert_eq!(c.node_id, Some(0x12));
    assert_eq!(c.node_name, "Left turnout");
    assert_eq!(c.baud_rate, Some(500));
    assert_eq!(c.net_number, Some(1));
    assert_eq!(c.network_name, "Station A");
    assert!(!c.canopen_manager);
    assert_eq!(c.lss_serial_number, Some(0x1234));
    let hb = d.entry_at(0x1017, 0).unwrap();
    assert_eq!(hb.value, Some(Value::Unsigned(250)));
    assert_eq!(hb.default, Some(Value::Unsigned(0)));
    assert_eq!(
        hb.denotation.as_deref(),
        Some("Heartbeat of the left turnout")
    );
    assert_eq!(
        d.entry_at(0x1800, 1).unwrap().value,
        Some(Value::NodeIdPlus(0x190))
    );
    // [2000Value] and [2000Denotation] of the compact array.
    let arr = d.object_at(0x2000).unwrap();
    assert_eq!(arr.subs[&1].value, Some(Value::Unsigned(5)));
    assert_eq!(arr.subs[&2].value, None);
    assert_eq!(arr.subs[&3].value, Some(Value::Unsigned(7)));
    assert_eq!(arr.subs[&2].denotation.as_deref(), Some("Spare"));
    // What the DCF configures, and the node built from it.
    let configured: Vec<(u16, u8)> = d.parameter_values().map(|s| (s.index, s.sub)).collect();
    assert_eq!(
        configured,
        [(0x1017, 0), (0x1800, 1), (0x2000, 1), (0x2000, 3)]
    );
    let od = d.dictionary(0x12);
    assert_eq!(od.get_value::<u16>(0x1017, 0), Ok(250));
    assert_eq!(od.get_value::<u32>(0x1800, 1), Ok(0x1A2));
    assert_eq!(od.get_value::<u8>(0x2000, 3), Ok(7));
    assert_eq!(
        d.entry("heartbeat of the left turnout").unwrap().index,
        0x1017,
        "by denotation"
    );
}

#[test]
fn domains_with_upload_and_download_files() {
    let d = clean("domain_files.eds");
    let prog = d.entry_at(0x1F50, 1).unwrap();
    assert_eq!(prog.download_file.as_deref(), Some("firmware.bin"));
    assert_eq!(
        (prog.data_type, prog.access),
        (DataType::Domain, AccessType::Wo)
    );
    let log = d.object_at(0x2000).unwrap();
    assert_eq!(log.code, ObjectCode::Domain);
    let e = &log.subs[&0];
    assert_eq!(
        e.data_type,
        DataType::Domain,
        "a DOMAIN object needs no DataType"
    );
    assert_eq!(e.upload_file.as_deref(), Some("log.bin"));
    let cal = d.entry_at(0x2001, 0).unwrap();
    assert_eq!(cal.default, Some(Value::Bytes(vec![1, 2, 0x0A, 0xFF])));
    let od = d.dictionary(1);
    assert_eq!(od.read(0x2001, 0), Ok(&[1u8, 2, 0x0A, 0xFF][..]));
    assert_eq!(
        od.get(0x2001, 0).unwrap().def.capacity,
        duocan::eds::DOMAIN_CAPACITY
    );
    assert_eq!(od.get(0x2000, 0).unwrap().def.object_type, ObjectType::Var);
}

#[test]
fn limits_are_checked_by_the_dictionary() {
    let d = clean("limits.eds");
    let e = d.entry_at(0x2000, 0).unwrap();
    assert_eq!(
        (e.low.clone(), e.high.clone()),
        (Some(Value::Unsigned(10)), Some(Value::Unsigned(1000)))
    );
    let mut od = d.dictionary(1);
    assert_eq!(
        od.write(0x2000, 0, &9u16.to_le_bytes()),
        Err(AbortCode::VALUE_TOO_LOW)
    );
    assert_eq!(
        od.write(0x2000, 0, &1001u16.to_le_bytes()),
        Err(AbortCode::VALUE_TOO_HIGH)
    );
    assert_eq!(od.write(0x2000, 0, &1000u16.to_le_bytes()), Ok(()));
    assert_eq!(
        od.write(0x2001, 0, &(-101i8).to_le_bytes()),
        Err(AbortCode::VALUE_TOO_LOW)
    );
    assert_eq!(
        od.write(0x2001, 0, &101i8.to_le_bytes()),
        Err(AbortCode::VALUE_TOO_HIGH)
    );
    assert_eq!(
        od.get(0x2002, 0).unwrap().def.high(),
        Some(Limit::Real(1.5))
    );
    assert_eq!(
        od.write(0x2002, 0, &1.75f32.to_le_bytes()),
        Err(AbortCode::VALUE_TOO_HIGH)
    );
    assert_eq!(od.get_value::<f32>(0x2002, 0), Ok(1.0));
}

#[test]
fn every_access_type_and_pdo_mapping() {
    let d = clean("access_types.eds");
    let expect = [
        (AccessType::Ro, Access::Ro, true),
        (AccessType::Wo, Access::Wo, false),
        (AccessType::Rw, Access::Rw, false),
        (AccessType::Rwr, Access::Rw, true),
        (AccessType::Rww, Access::Rw, true),
        (AccessType::Const, Access::Const, false),
    ];
    let od = d.dictionary(1);
    for (i, (a, access, mapped)) in expect.into_iter().enumerate() {
        let index = 0x2000 + i as u16;
        let e = d.entry_at(index, 0).unwrap();
        assert_eq!((e.access, e.pdo_mapping), (a, mapped), "{index:#x}");
        let def = od.get(index, 0).unwrap().def;
        assert_eq!(
            (def.access, def.pdo_mappable),
            (access, mapped),
            "{index:#x}"
        );
    }
}

#[test]
fn every_cia_301_data_type() {
    let d = clean("data_types.eds");
    let od = d.dictionary(1);
    for t in DataType::ALL {
        let index = 0x2000 + t as u16;
        let e = d.entry_at(index, 0).unwrap_or_else(|| panic!("{t:?}"));
        assert_eq!(e.data_type, t);
        assert_eq!(e.name, duocan::eds::type_name(t));
        let expect: Vec<u8> = match t {
            DataType::Boolean => vec![1],
            DataType::Real32 => 0.5f32.to_le_bytes().to_vec(),
            DataType::Real64 => (-0.25f64).to_le_bytes().to_vec(),
            DataType::VisibleString => b"visible".to_vec(),
            DataType::OctetString => vec![1, 2],
            DataType::Domain => vec![0x0A, 0x0B],
            DataType::UnicodeString => "Grüße".encode_utf16().flat_map(u16::to_le_bytes).collect(),
            DataType::TimeOfDay => 0x10_0000_0001u64.to_le_bytes()[..6].to_vec(),
            DataType::TimeDifference => 0x20_0000_0002u64.to_le_bytes()[..6].to_vec(),
            t => {
                let size = t.fixed_size().unwrap();
                // Signed: minus the size in bits; unsigned: the size in bits, written in hex.
                let bits = size as i64 * 8;
                let v = if t.is_signed() {
                    -bits
                } else {
                    i64::from_str_radix(&bits.to_string(), 16).unwrap()
                };
                v.to_le_bytes()[..size].to_vec()
            }
        };
        assert_eq!(od.read(index, 0).unwrap(), expect, "{t:?}");
    }
}
