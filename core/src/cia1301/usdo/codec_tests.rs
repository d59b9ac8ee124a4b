use super::*;
use proptest::prelude::*;

fn bytes(u: &Usdo) -> std::vec::Vec<u8> {
    let mut out = [0; 64];
    let n = u.write(&mut out);
    out[..n].to_vec()
}

#[test]
fn known_frames_byte_for_byte() {
    let write = Usdo {
        dest: 5,
        session: 9,
        msg: Msg::DownloadExpedited {
            index: 0x2000,
            sub: 1,
            data_type: 7,
            data: UsdoPayload::new(&[1, 2, 3, 4]).unwrap(),
        },
    };
    assert_eq!(bytes(&write), [5, 0x01, 9, 0x00, 0x20, 1, 7, 4, 1, 2, 3, 4]);
    let f = write.encode(Id::Standard(0x601));
    assert_eq!((f.len(), f.brs()), (12, true));
    let seg = Usdo {
        dest: 1,
        session: 9,
        msg: Msg::UploadSegmentData {
            toggle: true,
            last: true,
            data: UsdoPayload::new(&[0xAA; 9]).unwrap(),
        },
    };
    let f = seg.encode(Id::Standard(0x585));
    assert_eq!(&f.data()[..4], [1, 0x45, 9, 0x80 | 0x40 | 9]);
    assert_eq!(
        (f.len(), f.data()[13], f.data()[15]),
        (16, PADDING, PADDING)
    );
    let abort = Usdo {
        dest: 1,
        session: 2,
        msg: Msg::Abort {
            index: 0x1018,
            sub: 4,
            code: UsdoAbort::from_code(AbortCode::NO_OBJECT),
        },
    };
    assert_eq!(bytes(&abort), [1, 0x80, 2, 0x18, 0x10, 4, 11, 0]);
    let init = Usdo {
        dest: 5,
        session: 3,
        msg: Msg::DownloadInitiate {
            index: 0x2001,
            sub: 0,
            data_type: 0x0F,
            size: 1024,
        },
    };
    assert_eq!(bytes(&init), [5, 0x02, 3, 1, 0x20, 0, 0x0F, 0, 0, 4, 0, 0]);
}

#[test]
fn bad_bytes_name_their_abort() {
    assert_eq!(Usdo::decode(&[5, 1]), Err(UsdoDecodeError::NoHeader));
    let bad = |code| UsdoDecodeError::Bad {
        dest: 5,
        session: 1,
        code,
    };
    assert_eq!(
        Usdo::decode(&[5, 0x77, 1]),
        Err(bad(AbortCode::COMMAND_SPECIFIER))
    );
    // Expedited: more than 56 bytes announced, or more than the frame holds.
    let mut d = [0u8; 64];
    d[..8].copy_from_slice(&[5, 0x01, 1, 0, 0x20, 0, 0, 57]);
    assert_eq!(Usdo::decode(&d), Err(bad(AbortCode::LENGTH_TOO_HIGH)));
    d[7] = 8;
    assert_eq!(Usdo::decode(&d[..16]).map(|u| u.session), Ok(1));
    assert_eq!(Usdo::decode(&d[..12]), Err(bad(AbortCode::TYPE_MISMATCH)));
    // A segment request with flag bits it does not use.
    assert_eq!(
        Usdo::decode(&[5, 0x05, 1, 0x81]),
        Err(bad(AbortCode::COMMAND_SPECIFIER))
    );
    assert_eq!(
        Usdo::decode(&[5, 0x04, 1, 0, 0x20]),
        Err(bad(AbortCode::TYPE_MISMATCH))
    );
}

fn any_payload(max: usize) -> impl Strategy<Value = UsdoPayload> {
    proptest::collection::vec(any::<u8>(), 0..=max).prop_map(|v| UsdoPayload::new(&v).unwrap())
}

fn any_msg() -> impl Strategy<Value = Msg> {
    let mux = (any::<u16>(), any::<u8>());
    prop_oneof![
        (mux, any::<u8>(), any_payload(EXPEDITED_MAX)).prop_map(
            |((index, sub), data_type, data)| Msg::DownloadExpedited {
                index,
                sub,
                data_type,
                data
            }
        ),
        (mux, any::<u8>(), any_payload(EXPEDITED_MAX)).prop_map(
            |((index, sub), data_type, data)| Msg::UploadExpedited {
                index,
                sub,
                data_type,
                data
            }
        ),
        (mux, any::<u8>(), any::<u32>()).prop_map(|((index, sub), data_type, size)| {
            Msg::DownloadInitiate {
                index,
                sub,
                data_type,
                size,
            }
        }),
        (mux, any::<u8>(), any::<u32>()).prop_map(|((index, sub), data_type, size)| {
            Msg::UploadSegmented {
                index,
                sub,
                data_type,
                size,
            }
        }),
        (any::<bool>(), any::<bool>(), any_payload(SEGMENT_MAX))
            .prop_map(|(toggle, last, data)| Msg::DownloadSegment { toggle, last, data }),
        (any::<bool>(), any::<bool>(), any_payload(SEGMENT_MAX))
            .prop_map(|(toggle, last, data)| Msg::UploadSegmentData { toggle, last, data }),
        mux.prop_map(|(index, sub)| Msg::UploadInitiate { index, sub }),
        mux.prop_map(|(index, sub)| Msg::DownloadAck { index, sub }),
        (mux, any::<u8>()).prop_map(|((index, sub), c)| Msg::Abort {
            index,
            sub,
            code: UsdoAbort(c)
        }),
        any::<bool>().prop_map(|toggle| Msg::UploadSegment { toggle }),
        any::<bool>().prop_map(|toggle| Msg::DownloadSegmentAck { toggle }),
    ]
}

proptest! {
    #[test]
    fn every_message_round_trips_through_a_padded_fd_frame(
        dest in any::<u8>(), session in any::<u8>(), msg in any_msg()
    ) {
        let u = Usdo { dest, session, msg };
        let f = u.encode(Id::Standard(0x600 + u16::from(dest & 0x7F)));
        prop_assert!(crate::frame::fd::dlc_for_len(f.len()).is_some());
        prop_assert_eq!(Usdo::decode(f.data()), Ok(u));
    }

    #[test]
    fn any_bytes_decode_without_panic_and_re_encode_stably(
        d in proptest::collection::vec(any::<u8>(), 0..=64)
    ) {
        if let Ok(u) = Usdo::decode(&d) {
            // Reserved bytes are written as zero, so the bytes may differ; the message may not.
            prop_assert_eq!(Usdo::decode(&bytes(&u)), Ok(u));
        }
    }
}
