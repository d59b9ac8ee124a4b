use super::*;

#[test]
fn railway_frames_by_the_29_bit_layout() {
    let turnout = NodeId::must(10);
    let board = DeviceAddress::board_at(1, 2, 3, 4);
    let profile = rw::RailwayProfile::with(&[(turnout, board)]).unwrap();
    let mut dec = Decoder::new().with_railway(profile);
    let hb = Frame::new(rw::id(RailFunction::Heartbeat, board), &[0x05]).unwrap();
    assert_eq!(
        dec.decode(&hb).to_string(),
        "railway R1 C2 L3 B4 P0 node 10 heartbeat operational"
    );
    assert_eq!(dec.decode(&hb).node(), Some(turnout));
    let port2 = board.with_port(2);
    let id = rw::id(RailFunction::StateChange, port2);
    let state = Payload::byte(0x6000, 2, 0x5A).encode(id);
    assert_eq!(
        dec.decode(&state).to_string(),
        "railway R1 C2 L3 B4 P2 node 10 state change 0x6000:02 = 5A"
    );
    let mut bytes = state.data().to_vec();
    bytes[3] ^= 1;
    let corrupted = dec.decode(&Frame::new(id, &bytes).unwrap());
    assert_eq!(corrupted.kind(), Kind::Railway);
    assert!(
        corrupted
            .to_string()
            .starts_with("node 10 railway: state change at R1 C2 L3 B4 P2: CRC "),
        "{corrupted}"
    );
    // Not in the table: no node, no SDO context, still decoded.
    let other = DeviceAddress::board_at(9, 9, 9, 9);
    let sdo = Frame::new(
        rw::id(RailFunction::SdoResponse, other),
        &[0x43, 0x18, 0x10, 0x01, 0x23, 0x01, 0, 0],
    )
    .unwrap();
    assert_eq!(
        dec.decode(&sdo).to_string(),
        "railway R9 C9 L9 B9 P0 SDO upload 0x1018:01 = 0x00000123"
    );
    let nmt = Frame::new(rw::RailwayProfile::NMT, &[0x01, 0]).unwrap();
    let d = dec.decode(&nmt);
    assert_eq!(d.to_string(), "railway R0 C0 L0 B0 P0 NMT start all");
    assert_eq!((d.service(), d.concerns(turnout)), (Kind::Nmt, true));
    // A 29-bit identifier whose function code is no railway one.
    assert_eq!(
        dec.decode(&Frame::new(Id::Extended(0x0030_0000), &[1]).unwrap())
            .to_string(),
        "unknown 0x00300000x [1] 01"
    );
}
