//! Export → import gives the same dictionary: duocan's standard tables, application entries
//! of every kind, a static dictionary, a DCF with changed values; what cannot be written is an
//! error naming the entry.

use duocan::eds::{
    difference, export_dcf, export_eds, Description, ExportError, ExportOptions, FileKind,
    ImportOptions, Value,
};
use duocan::od::{
    comm, Access, DataType, DefaultValue, DynamicDictionary, Limit, ObjectDef, ObjectDictionary,
    ObjectType, StaticDictionary,
};

/// The standard communication objects and application entries of every kind.
pub fn sample(node: u8) -> DynamicDictionary {
    let mut od = comm::standard_dictionary(
        node,
        comm::Identity {
            device_type: 0x0002_0191,
            vendor: 0xD0CA,
            product: 7,
            revision: 0x0001_0002,
            serial: 42,
        },
    );
    let defs = [
        ObjectDef::u16(0x2000, 0, Access::Rw, 100)
            .limits(Limit::Unsigned(10), Limit::Unsigned(1000))
            .mappable()
            .named("Speed"),
        ObjectDef::new(0x2001, 0, DataType::Integer24)
            .default(DefaultValue::Signed(-5))
            .limits(Limit::Signed(-1000), Limit::Signed(1000))
            .named("Offset"),
        ObjectDef::new(0x2002, 0, DataType::Real32)
            .default(DefaultValue::Real(0.1))
            .limits(Limit::Real(-1.5), Limit::Real(1.5))
            .named("Gain"),
        ObjectDef::bytes(0x2003, 0, DataType::VisibleString, 40)
            .default(DefaultValue::Bytes(b"left turnout"))
            .named("Location"),
        ObjectDef::bytes(0x2004, 0, DataType::Domain, 1000).named("Log"),
        ObjectDef::u32(0x2005, 0, Access::Ro, 0)
            .default(DefaultValue::NodeIdPlus(0x4000))
            .named("Node-relative"),
        ObjectDef::new(0x2006, 0, DataType::Unsigned48)
            .access(Access::Wo)
            .default(DefaultValue::Unsigned(0x1234_5678_9ABC))
            .named("Wide"),
        ObjectDef::u8(0x2100, 0, Access::Const, 2)
            .object_type(ObjectType::Record)
            .named("Channel"),
        ObjectDef::new(0x2100, 1, DataType::Boolean)
            .object_type(ObjectType::Record)
            .mappable()
            .named("Enabled"),
        ObjectDef::bytes(0x2100, 2, DataType::UnicodeString, 16)
            .object_type(ObjectType::Record)
            .named("Label"),
    ];
    od.insert_all(&defs).unwrap();
    od
}

fn import(text: &str, opts: &ImportOptions) -> Description {
    Description::parse(text.as_bytes(), "exported", opts).unwrap_or_else(|e| panic!("{e}\n{text}"))
}

#[test]
fn an_exported_eds_imports_strictly_as_the_same_dictionary() {
    let od = sample(5);
    let text = export_eds(&od, &ExportOptions::default().with_vendor_name("duocan")).unwrap();
    let d = import(&text, &ImportOptions::strict());
    assert!(d.warnings.is_empty());
    assert_eq!(d.kind, FileKind::Eds);
    assert_eq!(d.len(), od.len());
    assert_eq!(difference(&od, &d.dictionary(5)), None);
    // What the header says comes from the dictionary.
    assert_eq!(d.device_info.vendor_number, Some(0xD0CA));
    assert_eq!(d.device_info.product_number, Some(7));
    assert_eq!(d.device_info.revision_number, Some(0x0001_0002));
    assert_eq!(d.device_info.product_name, "duocan", "0x1008's default");
    assert_eq!(
        d.entry_at(0x2005, 0).unwrap().default,
        Some(Value::NodeIdPlus(0x4000))
    );
    assert_eq!(d.entry_at(0x2003, 0).unwrap().max_length, Some(40));
    // Another node from the same file: node-relative defaults follow.
    assert_eq!(d.dictionary(9).get_value::<u32>(0x2005, 0), Ok(0x4009));
}

#[test]
fn export_is_a_fixed_point() {
    let od = sample(5);
    let opts = ExportOptions::default();
    let once = export_eds(&od, &opts).unwrap();
    let twice = export_eds(
        &import(&once, &ImportOptions::strict()).dictionary(5),
        &opts,
    )
    .unwrap();
    assert_eq!(once, twice);
}

#[test]
fn a_dcf_carries_the_current_values() {
    let mut od = sample(0x21);
    od.write(0x1017, 0, &250u16.to_le_bytes()).unwrap();
    od.write(0x2003, 0, b"right turnout").unwrap();
    od.write(0x2004, 0, &[1, 2, 3, 0xFF]).unwrap();
    od.write(0x2002, 0, &(-1.25f32).to_le_bytes()).unwrap();
    od.write_local(0x2005, 0, &7u32.to_le_bytes()).unwrap();
    let text = export_dcf(
        &od,
        &ExportOptions::default()
            .with_node_name("Right turnout")
            .with_baud_rate(250),
    )
    .unwrap();
    let d = import(&text, &ImportOptions::strict());
    assert_eq!(d.kind, FileKind::Dcf);
    let c = d.commissioning.as_ref().unwrap();
    assert_eq!(
        (c.node_id, c.node_name.as_str(), c.baud_rate),
        (Some(0x21), "Right turnout", Some(250))
    );
    assert_eq!(
        d.entry_at(0x1017, 0).unwrap().value,
        Some(Value::Unsigned(250))
    );
    let back = d.dictionary(0x21);
    assert_eq!(difference(&od, &back), None);
    assert_eq!(back.read(0x2003, 0), Ok(&b"right turnout"[..]));
    // The defaults are still the defaults: a reset brings them back.
    let mut back = back;
    back.reset_range(0x2000..=0x2FFF);
    assert_eq!(back.read(0x2003, 0), Ok(&b"left turnout"[..]));
    assert_eq!(back.get_value::<u32>(0x2005, 0), Ok(0x4021));
}

#[test]
fn a_static_dictionary_round_trips_too() {
    static COMM: [ObjectDef; comm::COMM_LEN] = comm::communication();
    static ID: [ObjectDef; 6] = comm::identity(0x191, 1, 2, 3, 4);
    static HB: [ObjectDef; 5] = comm::heartbeat_consumers();
    static HIST: [ObjectDef; 9] = comm::error_history();
    let mut od = StaticDictionary::<64, 512>::new();
    od.load(3, &[&COMM, &ID, &HB, &HIST]).unwrap();
    let text = export_eds(&od, &ExportOptions::default()).unwrap();
    let d = import(&text, &ImportOptions::strict());
    assert_eq!(difference(&od, &d.dictionary(3)), None);
    assert!(text.contains(
        "[1016]\nParameterName=Consumer heartbeat time\nObjectType=0x8\nSubNumber=0x5\n"
    ));
    assert!(text.contains("[1200sub1]\nParameterName=COB-ID client to server\nObjectType=0x7\nDataType=0x0007\nAccessType=ro\nDefaultValue=$NODEID+0x600\n"));
}

#[test]
fn a_difference_is_found_and_named() {
    let a = sample(5);
    let mut b = sample(5);
    assert_eq!(difference(&a, &b), None);
    b.write(0x2000, 0, &11u16.to_le_bytes()).unwrap();
    let d = difference(&a, &b).unwrap();
    assert_eq!((d.index, d.sub, d.what), (0x2000, 0, "value"));
    let mut c = sample(5);
    c.upsert(ObjectDef::u32(0x2005, 0, Access::Ro, 0x4005).named("Node-relative"));
    let d = difference(&a, &c).unwrap();
    assert_eq!(
        (d.index, d.what),
        (0x2005, "default"),
        "node-relative or not: {d}"
    );
    let mut e = sample(5);
    e.remove(0x2100, 2);
    assert_eq!(difference(&a, &e).unwrap().what, "entry");
}

#[test]
fn what_a_file_cannot_carry_is_an_error_naming_the_entry() {
    let mut od = DynamicDictionary::new(1);
    od.insert(
        ObjectDef::bytes(0x2000, 0, DataType::VisibleString, 8)
            .default(DefaultValue::Bytes(b" padded")),
    )
    .unwrap();
    assert_eq!(
        export_eds(&od, &ExportOptions::default()),
        Err(ExportError::Unrepresentable {
            index: 0x2000,
            sub: 0,
            why: "the string starts or ends with white space"
        })
    );
    let mut od = DynamicDictionary::new(1);
    od.insert(ObjectDef::bytes(0x2000, 0, DataType::VisibleString, 8))
        .unwrap();
    od.write(0x2000, 0, b"a\nb").unwrap();
    assert!(
        export_eds(&od, &ExportOptions::default()).is_ok(),
        "an EDS has no values"
    );
    let e = export_dcf(&od, &ExportOptions::default()).unwrap_err();
    assert_eq!(
        e.to_string(),
        "entry 0x2000sub0 cannot be written: the string holds a control character"
    );
}
