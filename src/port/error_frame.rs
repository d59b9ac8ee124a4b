//! Decoding of Linux SocketCAN error frames (`linux/can/error.h`) into port status.
//!
//! Pure functions on the error class bits of the identifier word and the 8 data bytes, so the
//! decoding is tested on any host, and shared by the SocketCAN port and the capture readers.

use crate::machine::{ErrorCause, PortStatus};

/// Error frame flag in the SocketCAN identifier word.
pub const CAN_ERR_FLAG: u32 = 0x2000_0000;
/// Remote frame flag in the SocketCAN identifier word.
pub const CAN_RTR_FLAG: u32 = 0x4000_0000;
/// Extended frame flag in the SocketCAN identifier word.
pub const CAN_EFF_FLAG: u32 = 0x8000_0000;
/// Error class bits of an error frame identifier.
pub const CAN_ERR_MASK: u32 = 0x1FFF_FFFF;

mod class {
    pub const TX_TIMEOUT: u32 = 0x001;
    pub const LOSTARB: u32 = 0x002;
    pub const CRTL: u32 = 0x004;
    pub const PROT: u32 = 0x008;
    pub const TRX: u32 = 0x010;
    pub const ACK: u32 = 0x020;
    pub const BUSOFF: u32 = 0x040;
    pub const BUSERROR: u32 = 0x080;
    pub const RESTARTED: u32 = 0x100;
}

mod ctrl {
    pub const RX_OVERFLOW: u8 = 0x01;
    pub const TX_OVERFLOW: u8 = 0x02;
    pub const RX_WARNING: u8 = 0x04;
    pub const TX_WARNING: u8 = 0x08;
    pub const RX_PASSIVE: u8 = 0x10;
    pub const TX_PASSIVE: u8 = 0x20;
    pub const ACTIVE: u8 = 0x40;
}

mod prot {
    pub const BIT: u8 = 0x01;
    pub const FORM: u8 = 0x02;
    pub const STUFF: u8 = 0x04;
    pub const BIT0: u8 = 0x08;
    pub const BIT1: u8 = 0x10;
    pub const LOC_CRC_SEQ: u8 = 0x08;
    pub const LOC_CRC_DEL: u8 = 0x18;
}

/// Statuses one error frame reports (at most one per error class).
pub type ErrorStatuses = heapless::Vec<PortStatus, 9>;

/// Decodes an error frame: `bits` are the error class bits (identifier word without the flag),
/// `data` its payload. Unknown or empty classes give [`ErrorCause::Other`]; never panics.
pub fn decode(bits: u32, data: &[u8]) -> ErrorStatuses {
    let byte = |i: usize| data.get(i).copied().unwrap_or(0);
    let mut out = ErrorStatuses::new();
    macro_rules! push {
        ($s:expr) => {{
            let _ = out.push($s);
        }};
    }
    if bits & class::TX_TIMEOUT != 0 {
        push!(PortStatus::TxFailed(ErrorCause::TxTimeout));
    }
    if bits & class::ACK != 0 {
        push!(PortStatus::TxFailed(ErrorCause::NoAck));
    }
    if bits & class::BUSOFF != 0 {
        push!(PortStatus::Down(ErrorCause::BusOff));
    }
    if bits & class::CRTL != 0 {
        let c = byte(1);
        let cause = if c & (ctrl::RX_PASSIVE | ctrl::TX_PASSIVE) != 0 {
            Some(ErrorCause::ErrorPassive)
        } else if c & (ctrl::RX_WARNING | ctrl::TX_WARNING) != 0 {
            Some(ErrorCause::ErrorWarning)
        } else if c & (ctrl::RX_OVERFLOW | ctrl::TX_OVERFLOW) != 0 {
            Some(ErrorCause::RxOverflow)
        } else if c & ctrl::ACTIVE != 0 {
            None // back to error active: nothing wrong any more
        } else {
            Some(ErrorCause::Other)
        };
        push!(match cause {
            Some(c) => PortStatus::Error(c),
            None => PortStatus::Up,
        });
    }
    if bits & class::PROT != 0 {
        let t = byte(2);
        let loc = byte(3);
        let cause = if t & (prot::BIT | prot::BIT0 | prot::BIT1) != 0 {
            ErrorCause::Bit
        } else if t & prot::STUFF != 0 {
            ErrorCause::Stuff
        } else if t & prot::FORM != 0 {
            ErrorCause::Form
        } else if loc == prot::LOC_CRC_SEQ || loc == prot::LOC_CRC_DEL {
            ErrorCause::Crc
        } else {
            ErrorCause::Other
        };
        push!(PortStatus::Error(cause));
    }
    if bits & class::TRX != 0 {
        push!(PortStatus::Error(ErrorCause::Transceiver));
    }
    if bits & class::RESTARTED != 0 {
        push!(PortStatus::Up);
    }
    let known = class::TX_TIMEOUT
        | class::ACK
        | class::BUSOFF
        | class::CRTL
        | class::PROT
        | class::TRX
        | class::RESTARTED;
    // Lost arbitration is normal bus life; a bare bus-error bit says no more than PROT does.
    let silent = class::LOSTARB | class::BUSERROR;
    if out.is_empty() && bits & !(known | silent) != 0 || bits == 0 {
        push!(PortStatus::Error(ErrorCause::Other));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn bus_off_takes_the_port_down() {
        assert_eq!(
            decode(class::BUSOFF, &[0; 8]).as_slice(),
            &[PortStatus::Down(ErrorCause::BusOff)]
        );
    }

    #[test]
    fn controller_states() {
        let passive = decode(class::CRTL, &[0, ctrl::TX_PASSIVE, 0, 0, 0, 0, 0, 0]);
        assert_eq!(
            passive.as_slice(),
            &[PortStatus::Error(ErrorCause::ErrorPassive)]
        );
        let warn = decode(class::CRTL, &[0, ctrl::RX_WARNING, 0, 0, 0, 0, 0, 0]);
        assert_eq!(
            warn.as_slice(),
            &[PortStatus::Error(ErrorCause::ErrorWarning)]
        );
        let ovf = decode(class::CRTL, &[0, ctrl::RX_OVERFLOW, 0, 0, 0, 0, 0, 0]);
        assert_eq!(ovf.as_slice(), &[PortStatus::Error(ErrorCause::RxOverflow)]);
        let active = decode(class::CRTL, &[0, ctrl::ACTIVE, 0, 0, 0, 0, 0, 0]);
        assert_eq!(active.as_slice(), &[PortStatus::Up]);
    }

    #[test]
    fn no_ack_and_protocol_errors() {
        let s = decode(
            class::ACK | class::PROT | class::BUSERROR,
            &[0, 0, prot::STUFF, 0, 0, 0, 0, 0],
        );
        assert_eq!(
            s.as_slice(),
            &[
                PortStatus::TxFailed(ErrorCause::NoAck),
                PortStatus::Error(ErrorCause::Stuff)
            ]
        );
        let crc = decode(class::PROT, &[0, 0, 0, prot::LOC_CRC_SEQ, 0, 0, 0, 0]);
        assert_eq!(crc.as_slice(), &[PortStatus::Error(ErrorCause::Crc)]);
    }

    #[test]
    fn restart_brings_it_up_and_unknown_is_other() {
        assert_eq!(decode(class::RESTARTED, &[]).as_slice(), &[PortStatus::Up]);
        assert_eq!(
            decode(0x1000_0000, &[]).as_slice(),
            &[PortStatus::Error(ErrorCause::Other)]
        );
        assert_eq!(
            decode(0, &[]).as_slice(),
            &[PortStatus::Error(ErrorCause::Other)]
        );
        assert!(decode(class::LOSTARB, &[0; 8]).is_empty());
    }

    proptest! {
        #[test]
        fn any_error_frame_decodes_without_panic(bits in any::<u32>(), data in proptest::collection::vec(any::<u8>(), 0..12)) {
            let s = decode(bits & CAN_ERR_MASK, &data);
            prop_assert!(s.len() <= 9);
        }
    }
}
