//! The conversions and the interface checks, without an interface.

mod classic {
    use super::super::*;
    use proptest::prelude::*;
    use socketcan::{CanAnyFrame, CanErrorFrame};

    proptest! {
        #[test]
        fn socketcan_round_trip_is_lossless(f in crate::frame::arbitrary::any_frame()) {
            let sc = socketcan_frame(&f);
            prop_assert_eq!(frame_from_socketcan(sc).unwrap(), f);
            let any = CanAnyFrame::from(socketcan_frame(&f));
            prop_assert_eq!(frame_from_socketcan(any).unwrap(), f);
        }
    }

    #[test]
    fn error_frames_are_not_frames() {
        let ef = CanErrorFrame::new_error(0x40, &[0; 8]).unwrap();
        assert_eq!(
            frame_from_socketcan(CanFrame::Error(ef)),
            Err(FrameError::NotClassic)
        );
        assert_eq!(
            decode_error_frame(&ef).as_slice(),
            &[crate::machine::PortStatus::Down(
                crate::machine::ErrorCause::BusOff
            )]
        );
    }

    #[test]
    fn missing_interface_is_a_clear_error() {
        assert_eq!(link_state("duocan-nope0"), LinkState::Missing);
        assert_eq!(link_state("../etc"), LinkState::Missing);
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .unwrap();
        let err = rt
            .block_on(async { SocketCanPort::open("duocan-nope0") })
            .unwrap_err();
        assert_eq!(err.kind, PortErrorKind::NoSuchInterface);
        assert!(err
            .to_string()
            .contains("ip link add dev duocan-nope0 type vcan"));
    }
}

mod fd {
    use super::super::convert::CANFD_FDF;
    use super::super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn canfd_frame_bytes_round_trip(f in crate::frame::arbitrary::any_fd_frame()) {
            let raw = canfd_bytes(&f);
            prop_assert_eq!(raw[5] & CANFD_FDF, CANFD_FDF);
            prop_assert_eq!(fd_from_kernel(&raw).unwrap(), f);
        }
    }

    #[test]
    fn a_kernel_fd_frame_of_a_length_between_the_steps_is_refused() {
        let mut raw = canfd_bytes(&FdFrame::new(Id::Standard(0x123), &[1; 12]).unwrap());
        raw[4] = 10;
        assert!(fd_from_kernel(&raw).is_err());
    }

    #[test]
    fn a_missing_interface_has_no_mtu_and_open_fd_says_so() {
        assert_eq!(interface_mtu("duocan-nope0"), None);
        let e = not_fd("vcan9", Some(16));
        assert_eq!(e.kind, PortErrorKind::Config);
        let msg = e.to_string();
        assert!(
            msg.contains("vcan9 has MTU 16, not the CAN FD MTU 72"),
            "{msg}"
        );
        assert!(msg.contains("ip link set vcan9 mtu 72"), "{msg}");
    }
}
