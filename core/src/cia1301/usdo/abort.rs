//! USDO abort codes: one byte on the wire, a CiA 301 [`AbortCode`] in the API.
//!
//! CiA 1301 carries the reason of a USDO abort in one byte instead of SDO's four. Its code table
//! was not at hand, so the byte values here are duocan's: the CiA 301 codes in the order CiA 301
//! lists them (the order of [`AbortCode::ALL`] when this table was written), numbered from 1.
//! The table is spelled out below rather than derived from [`AbortCode::ALL`], so that a code
//! added to that list later cannot shift the bytes on the wire. A four-byte code without a byte
//! here goes out as "general error"; a byte without a code here is kept as it came
//! ([`UsdoAbort::code`] is then `None`).

use crate::od::abort::AbortCode;
use core::fmt;

/// The wire byte `i + 1` stands for `TABLE[i]`.
const TABLE: [AbortCode; 31] = [
    AbortCode::TOGGLE_BIT,
    AbortCode::TIMEOUT,
    AbortCode::COMMAND_SPECIFIER,
    AbortCode::INVALID_BLOCK_SIZE,
    AbortCode::INVALID_SEQUENCE,
    AbortCode::CRC_ERROR,
    AbortCode::OUT_OF_MEMORY,
    AbortCode::UNSUPPORTED_ACCESS,
    AbortCode::WRITE_ONLY,
    AbortCode::READ_ONLY,
    AbortCode::NO_OBJECT,
    AbortCode::NOT_MAPPABLE,
    AbortCode::PDO_LENGTH,
    AbortCode::PARAMETER_INCOMPATIBLE,
    AbortCode::INTERNAL_INCOMPATIBLE,
    AbortCode::HARDWARE_ERROR,
    AbortCode::TYPE_MISMATCH,
    AbortCode::LENGTH_TOO_HIGH,
    AbortCode::LENGTH_TOO_LOW,
    AbortCode::NO_SUB_INDEX,
    AbortCode::VALUE_RANGE,
    AbortCode::VALUE_TOO_HIGH,
    AbortCode::VALUE_TOO_LOW,
    AbortCode::MAX_LESS_THAN_MIN,
    AbortCode::NO_RESOURCE,
    AbortCode::GENERAL,
    AbortCode::CANNOT_STORE,
    AbortCode::LOCAL_CONTROL,
    AbortCode::DEVICE_STATE,
    AbortCode::NO_OD,
    AbortCode::NO_DATA,
];

/// A USDO abort code as the wire carries it: one byte.
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
pub struct UsdoAbort(pub u8);

impl UsdoAbort {
    /// The byte for a CiA 301 code; "general error" for a code without one.
    pub fn from_code(code: AbortCode) -> UsdoAbort {
        let i = TABLE.iter().position(|&c| c == code).unwrap_or(25);
        UsdoAbort(i as u8 + 1)
    }

    /// The CiA 301 code this byte stands for; `None` for a byte duocan gives no meaning.
    pub fn code(self) -> Option<AbortCode> {
        TABLE.get(usize::from(self.0).checked_sub(1)?).copied()
    }
}

impl From<AbortCode> for UsdoAbort {
    fn from(code: AbortCode) -> UsdoAbort {
        UsdoAbort::from_code(code)
    }
}

impl fmt::Debug for UsdoAbort {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(self, f)
    }
}

/// `0x12 (0x06070012 (…))`, or the byte alone for one without a meaning.
impl fmt::Display for UsdoAbort {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.code() {
            Some(c) => write!(f, "{:#04x} ({c})", self.0),
            None => write!(f, "{:#04x} (no USDO abort code)", self.0),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_known_code_has_a_byte_and_back() {
        for &c in AbortCode::ALL {
            assert_eq!(UsdoAbort::from_code(c).code(), Some(c));
        }
        assert_eq!(TABLE.len(), AbortCode::ALL.len());
    }

    #[test]
    fn pinned_bytes_and_the_rest() {
        assert_eq!(UsdoAbort::from_code(AbortCode::TOGGLE_BIT), UsdoAbort(1));
        assert_eq!(UsdoAbort::from_code(AbortCode::NO_OBJECT), UsdoAbort(11));
        assert_eq!(UsdoAbort::from_code(AbortCode::NO_RESOURCE), UsdoAbort(25));
        assert_eq!(UsdoAbort::from_code(AbortCode(0x1234_5678)), UsdoAbort(26));
        assert_eq!(UsdoAbort(0).code(), None);
        assert_eq!(UsdoAbort(32).code(), None);
        assert!(UsdoAbort(200).to_string().contains("0xc8"));
    }
}
