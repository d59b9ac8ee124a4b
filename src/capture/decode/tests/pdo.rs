use super::*;

/// TPDO1 of node 5 maps "Input 1" (UNSIGNED8) and "Input 2" (INTEGER16).
pub(super) const EDS: &str = include_str!("io.eds");

#[test]
fn pdo_raw_by_default_and_by_name_with_a_description() {
    assert_eq!(
        line(std(0x185, &[0x11, 0xFD, 0xFF])),
        "node 5 TPDO1 11 FD FF"
    );
    assert_eq!(line(std(0x305, &[])), "node 5 RPDO2 (no data)");
    assert_eq!(
        line(Frame::remote(Id::Standard(0x285), 3).unwrap()),
        "node 5 TPDO2 remote request"
    );
    let desc = Description::parse(EDS.as_bytes(), "io.eds", &ImportOptions::lenient()).unwrap();
    let mut dec = Decoder::new();
    assert_eq!(dec.describe(NodeId::must(5), &desc), 1);
    let layout = dec.pdo(Id::Standard(0x185)).unwrap();
    assert_eq!(
        (layout.dir, layout.number, layout.fields.len()),
        (crate::cia301::pdo::Dir::Transmit, 1, 2)
    );
    let d = dec.decode(&std(0x185, &[0x11, 0xFD, 0xFF]));
    assert_eq!(d.to_string(), "node 5 TPDO1 Input 1 = 17, Input 2 = -3");
    let DecodedFrame::Pdo(p) = &d else {
        panic!("{d:?}")
    };
    assert_eq!(p.fields[1].value, FieldValue::Signed(-3));
    assert_eq!((p.fields[1].index, p.fields[1].sub), (0x2001, 0));
    // Node 6 has no description: raw bytes still.
    assert_eq!(dec.decode(&std(0x186, &[1])).to_string(), "node 6 TPDO1 01");
    assert_eq!(
        dec.decode(&std(0x185, &[0x11])).to_string(),
        "node 5 PDO: TPDO1: 1 byte, its mapping has 3 (11)"
    );
}

#[test]
fn pdo_values_by_type() {
    let mut dec = Decoder::new();
    let fields = vec![
        PdoFieldDef::new(MapEntry::new(0x2000, 1, 1)).with_name("On", DataType::Boolean),
        PdoFieldDef::new(MapEntry::new(0x0005, 0, 7)),
        PdoFieldDef::new(MapEntry::new(0x2000, 2, 32)).with_name("Temp", DataType::Real32),
        PdoFieldDef::new(MapEntry::new(0x2000, 3, 8)),
    ];
    let layout = PdoLayout {
        node: None,
        dir: crate::cia301::pdo::Dir::Receive,
        number: 9,
        fields,
    };
    dec.add_pdo(Id::Extended(0x1234), layout);
    let t = 21.5f32.to_le_bytes();
    let d = dec
        .decode(&Frame::new(Id::Extended(0x1234), &[0x01, t[0], t[1], t[2], t[3], 200]).unwrap());
    assert_eq!(
        d.to_string(),
        "RPDO9 On = true, Temp = 21.5, 0x2000:03 = 200"
    );
}
