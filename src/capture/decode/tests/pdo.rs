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

/// A CANopen FD network's 64-byte TPDO: by its layout (values at odd bit offsets over the whole
/// frame, the padding not read), raw on its predefined COB-ID without one, a frame shorter than
/// its mapping said so; a CAN FD frame that is no PDO is left to the caller.
#[test]
fn a_64_byte_pdo_in_a_can_fd_frame() {
    use crate::cia301::pdo::write_bits_wide;
    let mut dec = Decoder::new();
    // 3 + 13 + 7 × 64 bits + a 16-bit dummy = 480 bits: 60 bytes, in a 64-byte frame.
    let mut fields = vec![
        PdoFieldDef::new(MapEntry::new(0x6000, 1, 3)).with_name("Mode", DataType::Unsigned8),
        PdoFieldDef::new(MapEntry::new(0x6000, 2, 13)).with_name("Offset", DataType::Integer16),
    ];
    fields.extend((0..7).map(|k| PdoFieldDef::new(MapEntry::new(0x6100 + k, 0, 64))));
    fields.push(PdoFieldDef::new(MapEntry::new(0x0006, 0, 16)));
    let layout = PdoLayout {
        node: Some(NodeId::must(5)),
        dir: crate::cia301::pdo::Dir::Transmit,
        number: 1,
        fields,
    };
    dec.add_pdo(Id::Standard(0x185), layout);
    let mut data = [0xCCu8; 64];
    write_bits_wide(&mut data, 0, 3, 5);
    write_bits_wide(&mut data, 3, 13, 0x1FFE); // -2
    for k in 0..7u32 {
        write_bits_wide(&mut data, 16 + 64 * k, 64, u64::MAX - u64::from(k));
    }
    let f = crate::FdFrame::new(Id::Standard(0x185), &data).unwrap();
    let d = dec.decode_fd(&f).unwrap();
    let DecodedFrame::Pdo(p) = &d else {
        panic!("{d:?}")
    };
    assert_eq!((p.data.len(), p.fields.len()), (64, 9));
    assert_eq!(p.fields[0].value, FieldValue::Unsigned(5));
    assert_eq!(p.fields[1].value, FieldValue::Signed(-2));
    assert_eq!(p.fields[8].value, FieldValue::Unsigned(u64::MAX - 6));
    assert_eq!((p.fields[8].index, p.fields[8].sub), (0x6106, 0));
    assert!(d
        .to_string()
        .starts_with("node 5 TPDO1 Mode = 5, Offset = -2, 0x6100:00 = 18446744073709551615"));
    // 48 bytes: shorter than the 60 mapped.
    let short = crate::FdFrame::new(Id::Standard(0x185), &data[..48]).unwrap();
    assert_eq!(
        dec.decode_fd(&short).unwrap().to_string(),
        "node 5 PDO: TPDO1: CAN FD frame of 48 bytes, its mapping has 60"
    );
    // Without a layout: the bytes of node 6's RPDO2, all 64.
    let raw = crate::FdFrame::new(Id::Standard(0x306), &[0xAB; 64]).unwrap();
    let d = dec.decode_fd(&raw).unwrap();
    assert_eq!(d.kind(), Kind::Pdo);
    assert!(d.to_string().starts_with("node 6 RPDO2 AB AB"), "{d}");
    assert_eq!(d.to_string().matches("AB").count(), 64);
    // A USDO request is no PDO.
    let usdo = crate::FdFrame::new(Id::Standard(0x67F), &[0x01; 12]).unwrap();
    assert!(dec.decode_fd(&usdo).is_none());
}
