//! CiA 301 SDO abort codes.
//!
//! The dictionary returns them for bad accesses, the SDO server sends them, the SDO client reports
//! them. A newtype rather than an enum: a remote device may send a code this table does not know,
//! and that must still be represented (and printed) faithfully.

use core::fmt;

/// A CiA 301 SDO abort code.
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
pub struct AbortCode(pub u32);

macro_rules! abort_codes {
    ($( $(#[$doc:meta])* $name:ident = $value:literal, $text:literal; )*) => {
        impl AbortCode {
            $( $(#[$doc])* pub const $name: AbortCode = AbortCode($value); )*

            /// Every code this stack knows, in CiA 301 order.
            pub const ALL: &'static [AbortCode] = &[$(AbortCode::$name),*];

            /// The CiA 301 meaning of the code, or `None` for a code the standard does not define.
            pub const fn description(self) -> Option<&'static str> {
                match self.0 {
                    $( $value => Some($text), )*
                    _ => None,
                }
            }
        }
    };
}

abort_codes! {
    /// 0x05030000: toggle bit not alternated.
    TOGGLE_BIT = 0x0503_0000, "toggle bit not alternated";
    /// 0x05040000: SDO protocol timed out.
    TIMEOUT = 0x0504_0000, "SDO protocol timed out";
    /// 0x05040001: client/server command specifier not valid or unknown.
    COMMAND_SPECIFIER = 0x0504_0001, "client/server command specifier not valid or unknown";
    /// 0x05040002: invalid block size (block mode only).
    INVALID_BLOCK_SIZE = 0x0504_0002, "invalid block size";
    /// 0x05040003: invalid sequence number (block mode only).
    INVALID_SEQUENCE = 0x0504_0003, "invalid sequence number";
    /// 0x05040004: CRC error (block mode only).
    CRC_ERROR = 0x0504_0004, "CRC error";
    /// 0x05040005: out of memory.
    OUT_OF_MEMORY = 0x0504_0005, "out of memory";
    /// 0x06010000: unsupported access to an object.
    UNSUPPORTED_ACCESS = 0x0601_0000, "unsupported access to an object";
    /// 0x06010001: attempt to read a write-only object.
    WRITE_ONLY = 0x0601_0001, "attempt to read a write only object";
    /// 0x06010002: attempt to write a read-only object.
    READ_ONLY = 0x0601_0002, "attempt to write a read only object";
    /// 0x06020000: object does not exist in the object dictionary.
    NO_OBJECT = 0x0602_0000, "object does not exist in the object dictionary";
    /// 0x06040041: object cannot be mapped to the PDO.
    NOT_MAPPABLE = 0x0604_0041, "object cannot be mapped to the PDO";
    /// 0x06040042: the number and length of the objects to be mapped would exceed the PDO length.
    PDO_LENGTH = 0x0604_0042, "number and length of mapped objects would exceed the PDO length";
    /// 0x06040043: general parameter incompatibility.
    PARAMETER_INCOMPATIBLE = 0x0604_0043, "general parameter incompatibility";
    /// 0x06040047: general internal incompatibility in the device.
    INTERNAL_INCOMPATIBLE = 0x0604_0047, "general internal incompatibility in the device";
    /// 0x06060000: access failed due to a hardware error.
    HARDWARE_ERROR = 0x0606_0000, "access failed due to a hardware error";
    /// 0x06070010: data type does not match, length of service parameter does not match.
    TYPE_MISMATCH = 0x0607_0010, "data type does not match, length of service parameter does not match";
    /// 0x06070012: data type does not match, length of service parameter too high.
    LENGTH_TOO_HIGH = 0x0607_0012, "data type does not match, length of service parameter too high";
    /// 0x06070013: data type does not match, length of service parameter too low.
    LENGTH_TOO_LOW = 0x0607_0013, "data type does not match, length of service parameter too low";
    /// 0x06090011: sub-index does not exist.
    NO_SUB_INDEX = 0x0609_0011, "sub-index does not exist";
    /// 0x06090030: invalid value for parameter (download only).
    VALUE_RANGE = 0x0609_0030, "invalid value for parameter";
    /// 0x06090031: value of parameter written too high.
    VALUE_TOO_HIGH = 0x0609_0031, "value of parameter written too high";
    /// 0x06090032: value of parameter written too low.
    VALUE_TOO_LOW = 0x0609_0032, "value of parameter written too low";
    /// 0x06090036: maximum value is less than minimum value.
    MAX_LESS_THAN_MIN = 0x0609_0036, "maximum value is less than minimum value";
    /// 0x060A0023: resource not available: SDO connection.
    NO_RESOURCE = 0x060A_0023, "resource not available: SDO connection";
    /// 0x08000000: general error.
    GENERAL = 0x0800_0000, "general error";
    /// 0x08000020: data cannot be transferred or stored to the application.
    CANNOT_STORE = 0x0800_0020, "data cannot be transferred or stored to the application";
    /// 0x08000021: ... because of local control.
    LOCAL_CONTROL = 0x0800_0021, "data cannot be transferred or stored to the application because of local control";
    /// 0x08000022: ... because of the present device state.
    DEVICE_STATE = 0x0800_0022, "data cannot be transferred or stored to the application because of the present device state";
    /// 0x08000023: object dictionary dynamic generation fails or no object dictionary is present.
    NO_OD = 0x0800_0023, "object dictionary dynamic generation fails or no object dictionary is present";
    /// 0x08000024: no data available.
    NO_DATA = 0x0800_0024, "no data available";
}

impl fmt::Display for AbortCode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.description() {
            Some(text) => write!(f, "{:#010x} ({text})", self.0),
            None => write!(f, "{:#010x} (not a CiA 301 abort code)", self.0),
        }
    }
}

impl core::error::Error for AbortCode {}
impl fmt::Debug for AbortCode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(self, f)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_known_code_has_a_distinct_description() {
        for (i, a) in AbortCode::ALL.iter().enumerate() {
            assert!(a.description().is_some());
            for b in &AbortCode::ALL[i + 1..] {
                assert_ne!(a.0, b.0);
            }
        }
        assert_eq!(AbortCode(0x1234).description(), None);
        assert_eq!(
            format!("{}", AbortCode::READ_ONLY),
            "0x06010002 (attempt to write a read only object)"
        );
    }
}
