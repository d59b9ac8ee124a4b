//! The railway scheme's 29-bit identifier: a 9-bit function code above a 20-bit device address.
//!
//! ```text
//!  28        20 19   16 15   12 11    8 7     4 3     0
//! ┌────────────┬───────┬───────┬───────┬───────┬───────┐
//! │  function  │  row  │cabinet│ layer │ board │ port  │
//! └────────────┴───────┴───────┴───────┴───────┴───────┘
//! ```
//!
//! Lower function codes win arbitration, so the code is also the frame's priority class.

use crate::frame::Id;
use core::fmt;

/// Largest value of one address field (4 bits).
pub const FIELD_MAX: u8 = 0xF;
/// Largest 20-bit device address.
pub const ADDRESS_MAX: u32 = 0xF_FFFF;
/// Largest 9-bit function code.
pub const FUNCTION_MAX: u16 = 0x1FF;

/// Where a device sits in the station: row · cabinet · layer · board · port, 4 bits each.
///
/// `port` is the board's **I/O port** (the connector or channel a field device hangs on: point
/// machine 2, track circuit 5), not the CAN bus: the frames on bus 1 and bus 2 must be
/// identical so that the dual-bus merger can pair the two copies. Port 0 stands for the board
/// itself: node-level services (heartbeat, guarding, fault report, NMT, SDO) use it, and a
/// node's entry in [`super::RailwayProfile`] is its board address with port 0.
#[derive(Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Default)]
pub struct DeviceAddress(u32);

/// A field of a [`DeviceAddress`] did not fit its 4 bits, or a raw address its 20.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AddressError {
    /// A field above 15.
    Field {
        /// Which field ("row", "cabinet", "layer", "board", "port").
        field: &'static str,
        /// The value given.
        value: u8,
    },
    /// A raw address above 0xFFFFF.
    Raw(u32),
}

impl fmt::Display for AddressError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            AddressError::Field { field, value } => write!(
                f,
                "device address {field} {value} does not fit 4 bits (0-15)"
            ),
            AddressError::Raw(raw) => {
                write!(f, "device address {raw:#x} does not fit 20 bits")
            }
        }
    }
}

impl core::error::Error for AddressError {}

impl DeviceAddress {
    /// An address from its five fields, each 0–15.
    pub const fn new(
        row: u8,
        cabinet: u8,
        layer: u8,
        board: u8,
        port: u8,
    ) -> Result<DeviceAddress, AddressError> {
        let fields = [
            ("row", row),
            ("cabinet", cabinet),
            ("layer", layer),
            ("board", board),
            ("port", port),
        ];
        let mut raw = 0u32;
        let mut i = 0;
        while i < fields.len() {
            let (field, value) = fields[i];
            if value > FIELD_MAX {
                return Err(AddressError::Field { field, value });
            }
            raw = (raw << 4) | value as u32;
            i += 1;
        }
        Ok(DeviceAddress(raw))
    }
    /// A board address (port 0); panics (at compile time in a const context) on a field above
    /// 15. For literals.
    #[must_use]
    pub const fn board_at(row: u8, cabinet: u8, layer: u8, board: u8) -> DeviceAddress {
        match DeviceAddress::new(row, cabinet, layer, board, 0) {
            Ok(a) => a,
            Err(_) => panic!("device address fields must be 0..=15"),
        }
    }
    /// The address from its 20-bit form.
    pub const fn from_raw(raw: u32) -> Result<DeviceAddress, AddressError> {
        if raw > ADDRESS_MAX {
            Err(AddressError::Raw(raw))
        } else {
            Ok(DeviceAddress(raw))
        }
    }
    /// The 20-bit form.
    pub const fn raw(self) -> u32 {
        self.0
    }
    /// Row.
    pub const fn row(self) -> u8 {
        (self.0 >> 16) as u8 & FIELD_MAX
    }
    /// Cabinet.
    pub const fn cabinet(self) -> u8 {
        (self.0 >> 12) as u8 & FIELD_MAX
    }
    /// Layer.
    pub const fn layer(self) -> u8 {
        (self.0 >> 8) as u8 & FIELD_MAX
    }
    /// Board.
    pub const fn board(self) -> u8 {
        (self.0 >> 4) as u8 & FIELD_MAX
    }
    /// I/O port of the board (0: the board itself).
    pub const fn port(self) -> u8 {
        self.0 as u8 & FIELD_MAX
    }
    /// The same board, I/O port `port` (masked to 4 bits).
    #[must_use]
    pub const fn with_port(self, port: u8) -> DeviceAddress {
        DeviceAddress((self.0 & !0xF) | (port & FIELD_MAX) as u32)
    }
    /// The board this address belongs to (port 0).
    #[must_use]
    pub const fn board_address(self) -> DeviceAddress {
        self.with_port(0)
    }
}

impl fmt::Display for DeviceAddress {
    /// `R1 C2 L3 B4 P5`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "R{} C{} L{} B{} P{}",
            self.row(),
            self.cabinet(),
            self.layer(),
            self.board(),
            self.port()
        )
    }
}

impl fmt::Debug for DeviceAddress {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "DeviceAddress({self})")
    }
}

/// The 29-bit identifier of `function` (any 9-bit code; masked) at `address`.
pub const fn compose(function: u16, address: DeviceAddress) -> Id {
    Id::Extended(((function & FUNCTION_MAX) as u32) << 20 | address.raw())
}

/// (function code, address) of a 29-bit identifier; `None` for an 11-bit one.
pub const fn split(id: Id) -> Option<(u16, DeviceAddress)> {
    match id {
        Id::Extended(raw) => Some((
            ((raw >> 20) & FUNCTION_MAX as u32) as u16,
            DeviceAddress(raw & ADDRESS_MAX),
        )),
        Id::Standard(_) => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn fields_land_where_the_seed_puts_them() {
        let a = DeviceAddress::new(1, 2, 3, 4, 5).unwrap();
        assert_eq!(a.raw(), 0x12345);
        assert_eq!(
            (a.row(), a.cabinet(), a.layer(), a.board(), a.port()),
            (1, 2, 3, 4, 5)
        );
        assert_eq!(compose(0x020, a), Id::Extended(0x0201_2345));
        assert_eq!(split(Id::Extended(0x0201_2345)), Some((0x020, a)));
        assert_eq!(split(Id::Standard(0x123)), None);
        assert_eq!(a.board_address().raw(), 0x12340);
        assert_eq!(a.with_port(0xF).raw(), 0x1234F);
        assert_eq!(a.to_string(), "R1 C2 L3 B4 P5");
    }

    #[test]
    fn out_of_range_fields_are_errors_naming_the_field() {
        assert_eq!(
            DeviceAddress::new(0, 16, 0, 0, 0),
            Err(AddressError::Field {
                field: "cabinet",
                value: 16
            })
        );
        assert_eq!(
            DeviceAddress::from_raw(0x10_0000),
            Err(AddressError::Raw(0x10_0000))
        );
        assert!(DeviceAddress::new(0, 0, 0, 0, 200)
            .unwrap_err()
            .to_string()
            .contains("port 200"));
    }

    proptest! {
        #[test]
        fn compose_and_split_round_trip(f in 0u16..=FUNCTION_MAX, raw in 0u32..=ADDRESS_MAX) {
            let a = DeviceAddress::from_raw(raw).unwrap();
            let id = compose(f, a);
            prop_assert!(id.raw() <= crate::frame::EXTENDED_ID_MAX);
            prop_assert_eq!(split(id), Some((f, a)));
            let b = DeviceAddress::new(a.row(), a.cabinet(), a.layer(), a.board(), a.port());
            prop_assert_eq!(b, Ok(a));
        }
    }
}
