//! The frames: every request and answer round-trips through its 8 bytes; bad frames say why.

use duocan::cia305::codec::{MASTER_TO_SLAVE, SLAVE_TO_MASTER};
use duocan::cia305::{
    BitTiming, Fastscan, Inquiry, LssFrameError, LssMode, LssRequest, LssResponse,
};
use duocan::Frame;
#[test]
fn requests_round_trip_through_their_frames() {
    let reqs = [
        LssRequest::SwitchGlobal(LssMode::Configuration),
        LssRequest::SwitchSelective {
            part: 3,
            value: 0xDEAD_BEEF,
        },
        LssRequest::ConfigureNodeId(0x7F),
        LssRequest::ConfigureBitTiming(BitTiming::standard(4)),
        LssRequest::ActivateBitTiming { delay_ms: 0x1234 },
        LssRequest::Store,
        LssRequest::Inquire(Inquiry::Serial),
        LssRequest::IdentifyRemote { part: 5, value: 9 },
        LssRequest::IdentifyNonConfigured,
        LssRequest::Fastscan(Fastscan {
            id_number: 0x8000_0001,
            bit_checked: 31,
            sub: 2,
            next: 3,
        }),
    ];
    for r in reqs {
        assert_eq!(LssRequest::decode(&r.encode()), Ok(r), "{r:?}");
    }
    let f = LssRequest::Fastscan(Fastscan {
        id_number: 0x0403_0201,
        bit_checked: 0x80,
        sub: 0,
        next: 0,
    });
    assert_eq!(f.encode().data(), [0x51, 1, 2, 3, 4, 0x80, 0, 0]);
}

#[test]
fn answers_round_trip_and_bad_frames_say_why() {
    let resps = [
        LssResponse::SelectiveSwitched,
        LssResponse::NodeIdConfigured { error: 1, spec: 0 },
        LssResponse::Stored {
            error: 0xFF,
            spec: 7,
        },
        LssResponse::Inquired(Inquiry::Vendor, 0x1234_5678),
        LssResponse::Inquired(Inquiry::NodeId, 5),
        LssResponse::IdentifySlave,
        LssResponse::NonConfigured,
    ];
    for r in resps {
        assert_eq!(LssResponse::decode(&r.encode()), Ok(r), "{r:?}");
    }
    let short = Frame::new(SLAVE_TO_MASTER, &[0x44]).unwrap();
    assert_eq!(LssResponse::decode(&short), Err(LssFrameError::Length(1)));
    let odd = Frame::from_array(SLAVE_TO_MASTER, [0x99, 0, 0, 0, 0, 0, 0, 0]);
    assert_eq!(
        LssResponse::decode(&odd),
        Err(LssFrameError::UnknownCommand(0x99))
    );
    let scan = Frame::from_array(MASTER_TO_SLAVE, [0x51, 0, 0, 0, 0, 32, 0, 0]);
    assert_eq!(
        LssRequest::decode(&scan),
        Err(LssFrameError::BadValue {
            cs: 0x51,
            byte: 5,
            value: 32
        })
    );
    assert_eq!(LssRequest::decode(&odd), Err(LssFrameError::NotLss));
}
