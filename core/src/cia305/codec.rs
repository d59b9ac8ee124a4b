//! The LSS frames (CiA 305): every request of the master and every answer of a slave, decoded
//! from and encoded to the 8-byte frames on 0x7E5 and 0x7E4.
//!
//! Byte 0 is the command specifier; a 32-bit value (an identity part, a fastscan number) is
//! little-endian in bytes 1–4; unused bytes are zero when sent and ignored when read. A frame on
//! the LSS identifiers that is not 8 bytes long, is a remote frame or carries a command
//! specifier this stack does not know decodes to an [`LssFrameError`] naming what was wrong,
//! never a panic.

use crate::frame::{Frame, Id};
use core::fmt;

/// Identifier of the master's requests.
pub const MASTER_TO_SLAVE: Id = Id::Standard(0x7E5);
/// Identifier of the slaves' answers.
pub const SLAVE_TO_MASTER: Id = Id::Standard(0x7E4);
/// The node-ID of a slave that has none ("non-configured").
pub const UNCONFIGURED: u8 = 0xFF;
/// The fastscan `bit_checked` value that resets every non-configured slave's scan position.
pub const FASTSCAN_RESET: u8 = 0x80;

/// The LSS address of a slave: the four parts of its identity object (0x1018 sub 1–4).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct LssAddress {
    /// Vendor-ID (0x1018 sub 1).
    pub vendor: u32,
    /// Product code (0x1018 sub 2).
    pub product: u32,
    /// Revision number (0x1018 sub 3).
    pub revision: u32,
    /// Serial number (0x1018 sub 4).
    pub serial: u32,
}

impl LssAddress {
    /// The address made of its four parts, in fastscan order.
    #[must_use]
    pub const fn from_parts(p: [u32; 4]) -> LssAddress {
        LssAddress {
            vendor: p[0],
            product: p[1],
            revision: p[2],
            serial: p[3],
        }
    }
    /// The four parts in fastscan order (the `lss_sub` index): vendor, product, revision, serial.
    #[must_use]
    pub const fn parts(&self) -> [u32; 4] {
        [self.vendor, self.product, self.revision, self.serial]
    }
}

impl fmt::Display for LssAddress {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "vendor {:#010x} product {:#010x} revision {:#010x} serial {:#010x}",
            self.vendor, self.product, self.revision, self.serial
        )
    }
}

/// The LSS state of a slave.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum LssMode {
    /// Only switching, identification and fastscan are served.
    Waiting = 0,
    /// The configuration and inquiry services are served too.
    Configuration = 1,
}

/// A part of the identity, or the node-ID, as the inquire services name them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Inquiry {
    /// Vendor-ID (0x5A).
    Vendor,
    /// Product code (0x5B).
    Product,
    /// Revision number (0x5C).
    Revision,
    /// Serial number (0x5D).
    Serial,
    /// The active node-ID (0x5E).
    NodeId,
}

impl Inquiry {
    /// The command specifier of the request and its answer.
    #[must_use]
    pub const fn cs(self) -> u8 {
        match self {
            Inquiry::Vendor => 0x5A,
            Inquiry::Product => 0x5B,
            Inquiry::Revision => 0x5C,
            Inquiry::Serial => 0x5D,
            Inquiry::NodeId => 0x5E,
        }
    }
    const fn from_cs(cs: u8) -> Option<Inquiry> {
        Some(match cs {
            0x5A => Inquiry::Vendor,
            0x5B => Inquiry::Product,
            0x5C => Inquiry::Revision,
            0x5D => Inquiry::Serial,
            0x5E => Inquiry::NodeId,
            _ => return None,
        })
    }
}

/// A bit timing as configure bit timing names it: a table and an index into it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct BitTiming {
    /// Table selector: 0 is the CiA 301 table, 1–127 reserved, 128–255 the manufacturer's.
    pub table: u8,
    /// Index into the table.
    pub index: u8,
}

impl BitTiming {
    /// An index of the CiA 301 table (table 0).
    #[must_use]
    pub const fn standard(index: u8) -> BitTiming {
        BitTiming { table: 0, index }
    }
    /// The bit rate in kbit/s of a CiA 301 table entry (`None` for index 5, which the table
    /// reserves, index 9, automatic detection, other tables and indices beyond the table).
    #[must_use]
    pub const fn kbit(self) -> Option<u16> {
        if self.table != 0 {
            return None;
        }
        match self.index {
            0 => Some(1000),
            1 => Some(800),
            2 => Some(500),
            3 => Some(250),
            4 => Some(125),
            6 => Some(50),
            7 => Some(20),
            8 => Some(10),
            _ => None,
        }
    }
}

/// The six parts of an identify-remote-slave request: a slave answers when its vendor and
/// product equal these and its revision and serial lie in the ranges (both ends included).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct IdentifyRange {
    /// Vendor-ID, exact.
    pub vendor: u32,
    /// Product code, exact.
    pub product: u32,
    /// Lowest revision number.
    pub revision_low: u32,
    /// Highest revision number.
    pub revision_high: u32,
    /// Lowest serial number.
    pub serial_low: u32,
    /// Highest serial number.
    pub serial_high: u32,
}

impl IdentifyRange {
    /// The six values in the order they go on the wire (0x46 to 0x4B).
    #[must_use]
    pub const fn values(&self) -> [u32; 6] {
        [
            self.vendor,
            self.product,
            self.revision_low,
            self.revision_high,
            self.serial_low,
            self.serial_high,
        ]
    }
    /// True when `a` lies in the range.
    #[must_use]
    pub const fn contains(&self, a: &LssAddress) -> bool {
        a.vendor == self.vendor
            && a.product == self.product
            && self.revision_low <= a.revision
            && a.revision <= self.revision_high
            && self.serial_low <= a.serial
            && a.serial <= self.serial_high
    }
}

/// One fastscan request.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Fastscan {
    /// The value compared with the slave's identity part `sub`.
    pub id_number: u32,
    /// The lowest bit compared (bits 31 to `bit_checked`); [`FASTSCAN_RESET`] resets the scan.
    pub bit_checked: u8,
    /// The identity part compared (0 vendor … 3 serial).
    pub sub: u8,
    /// The part a matching slave compares next.
    pub next: u8,
}

/// A request of the LSS master (on [`MASTER_TO_SLAVE`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum LssRequest {
    /// Switch state global (0x04): every slave changes to the mode; no answer.
    SwitchGlobal(LssMode),
    /// Switch state selective (0x40–0x43): part `0..4` of the address of the one slave that is to
    /// switch to configuration; the slave answers the fourth (0x44).
    SwitchSelective {
        /// 0 vendor, 1 product, 2 revision, 3 serial.
        part: u8,
        /// The value of that part.
        value: u32,
    },
    /// Configure node-ID (0x11): 1–127, or 0xFF for none.
    ConfigureNodeId(u8),
    /// Configure bit timing (0x13).
    ConfigureBitTiming(BitTiming),
    /// Activate bit timing (0x15): switch after the delay (ms), wait the delay again; no answer.
    ActivateBitTiming {
        /// The switch delay in milliseconds.
        delay_ms: u16,
    },
    /// Store configuration (0x17).
    Store,
    /// Inquire a part of the identity or the node-ID (0x5A–0x5E).
    Inquire(Inquiry),
    /// Identify remote slave (0x46–0x4B): value `part` (0 vendor … 5 serial high) of an
    /// [`IdentifyRange`]; slaves in the range answer the last (0x4F).
    IdentifyRemote {
        /// 0 vendor, 1 product, 2 revision low, 3 revision high, 4 serial low, 5 serial high.
        part: u8,
        /// The value.
        value: u32,
    },
    /// Identify non-configured remote slave (0x4C): non-configured slaves answer (0x50).
    IdentifyNonConfigured,
    /// A fastscan step (0x51): matching slaves answer (0x4F).
    Fastscan(Fastscan),
}

/// An answer of an LSS slave (on [`SLAVE_TO_MASTER`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum LssResponse {
    /// The selected slave is in configuration mode (0x44).
    SelectiveSwitched,
    /// Configure node-ID answered (0x11): error code 0 done, 1 out of range, 0xFF the
    /// manufacturer's `spec` code.
    NodeIdConfigured {
        /// The error code.
        error: u8,
        /// The manufacturer-specific error when `error` is 0xFF.
        spec: u8,
    },
    /// Configure bit timing answered (0x13): 0 done, 1 not supported, 0xFF the manufacturer's.
    BitTimingConfigured {
        /// The error code.
        error: u8,
        /// The manufacturer-specific error.
        spec: u8,
    },
    /// Store configuration answered (0x17): 0 done, 1 not supported, 2 medium failed, 0xFF the
    /// manufacturer's.
    Stored {
        /// The error code.
        error: u8,
        /// The manufacturer-specific error.
        spec: u8,
    },
    /// An identity part (0x5A–0x5D) or the node-ID (0x5E, in the low byte).
    Inquired(Inquiry, u32),
    /// A slave matches an identify-remote-slave request or a fastscan step (0x4F).
    IdentifySlave,
    /// A non-configured slave is there (0x50).
    NonConfigured,
}

/// Why a frame on an LSS identifier is not an LSS message this stack reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum LssFrameError {
    /// Not on the identifier of this direction (or extended, or remote).
    NotLss,
    /// LSS frames have 8 bytes.
    Length(u8),
    /// The command specifier is not one of this direction's.
    UnknownCommand(u8),
    /// A value out of its range (a switch mode above 1, a fastscan part above 3).
    BadValue {
        /// The command specifier.
        cs: u8,
        /// The byte at fault.
        byte: u8,
        /// Its value.
        value: u8,
    },
}

impl fmt::Display for LssFrameError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LssFrameError::NotLss => f.write_str("not an LSS frame"),
            LssFrameError::Length(n) => write!(f, "an LSS frame has 8 bytes, this one {n}"),
            LssFrameError::UnknownCommand(cs) => write!(f, "unknown LSS command {cs:#04x}"),
            LssFrameError::BadValue { cs, byte, value } => write!(
                f,
                "LSS command {cs:#04x}: byte {byte} holds {value:#04x}, out of range"
            ),
        }
    }
}

impl core::error::Error for LssFrameError {}

fn u32_at(d: &[u8; 8]) -> u32 {
    u32::from_le_bytes([d[1], d[2], d[3], d[4]])
}

/// The 8 data bytes of an LSS frame on `id`, or why it is not one.
fn payload(frame: &Frame, id: Id) -> Result<[u8; 8], LssFrameError> {
    if frame.id() != id || frame.is_remote() {
        return Err(LssFrameError::NotLss);
    }
    <[u8; 8]>::try_from(frame.data()).map_err(|_| LssFrameError::Length(frame.dlc()))
}

fn frame(id: Id, cs: u8, rest: [u8; 7]) -> Frame {
    let mut d = [0u8; 8];
    d[0] = cs;
    d[1..].copy_from_slice(&rest);
    Frame::from_array(id, d)
}

fn with_u32(v: u32) -> [u8; 7] {
    let b = v.to_le_bytes();
    [b[0], b[1], b[2], b[3], 0, 0, 0]
}

impl LssRequest {
    /// Reads a frame of the master.
    pub fn decode(f: &Frame) -> Result<LssRequest, LssFrameError> {
        let d = payload(f, MASTER_TO_SLAVE)?;
        let bad = |byte: u8| LssFrameError::BadValue {
            cs: d[0],
            byte,
            value: d[byte as usize],
        };
        Ok(match d[0] {
            0x04 => LssRequest::SwitchGlobal(match d[1] {
                0 => LssMode::Waiting,
                1 => LssMode::Configuration,
                _ => return Err(bad(1)),
            }),
            cs @ 0x40..=0x43 => LssRequest::SwitchSelective {
                part: cs - 0x40,
                value: u32_at(&d),
            },
            0x11 => LssRequest::ConfigureNodeId(d[1]),
            0x13 => LssRequest::ConfigureBitTiming(BitTiming {
                table: d[1],
                index: d[2],
            }),
            0x15 => LssRequest::ActivateBitTiming {
                delay_ms: u16::from_le_bytes([d[1], d[2]]),
            },
            0x17 => LssRequest::Store,
            cs @ 0x46..=0x4B => LssRequest::IdentifyRemote {
                part: cs - 0x46,
                value: u32_at(&d),
            },
            0x4C => LssRequest::IdentifyNonConfigured,
            0x51 => {
                if d[5] > 31 && d[5] != FASTSCAN_RESET {
                    return Err(bad(5));
                }
                if d[6] > 3 {
                    return Err(bad(6));
                }
                if d[7] > 3 {
                    return Err(bad(7));
                }
                LssRequest::Fastscan(Fastscan {
                    id_number: u32_at(&d),
                    bit_checked: d[5],
                    sub: d[6],
                    next: d[7],
                })
            }
            cs => match Inquiry::from_cs(cs) {
                Some(q) => LssRequest::Inquire(q),
                None => return Err(LssFrameError::UnknownCommand(cs)),
            },
        })
    }

    /// The frame of this request. Out-of-range fields (a part above its last) are sent as
    /// given, masked to their byte: the slave refuses them.
    #[must_use]
    pub fn encode(&self) -> Frame {
        let id = MASTER_TO_SLAVE;
        match *self {
            LssRequest::SwitchGlobal(m) => frame(id, 0x04, [m as u8, 0, 0, 0, 0, 0, 0]),
            LssRequest::SwitchSelective { part, value } => {
                frame(id, 0x40 + (part & 3), with_u32(value))
            }
            LssRequest::ConfigureNodeId(n) => frame(id, 0x11, [n, 0, 0, 0, 0, 0, 0]),
            LssRequest::ConfigureBitTiming(t) => frame(id, 0x13, [t.table, t.index, 0, 0, 0, 0, 0]),
            LssRequest::ActivateBitTiming { delay_ms } => {
                let b = delay_ms.to_le_bytes();
                frame(id, 0x15, [b[0], b[1], 0, 0, 0, 0, 0])
            }
            LssRequest::Store => frame(id, 0x17, [0; 7]),
            LssRequest::Inquire(q) => frame(id, q.cs(), [0; 7]),
            LssRequest::IdentifyRemote { part, value } => {
                frame(id, 0x46 + part.min(5), with_u32(value))
            }
            LssRequest::IdentifyNonConfigured => frame(id, 0x4C, [0; 7]),
            LssRequest::Fastscan(s) => {
                let b = s.id_number.to_le_bytes();
                frame(
                    id,
                    0x51,
                    [b[0], b[1], b[2], b[3], s.bit_checked, s.sub, s.next],
                )
            }
        }
    }
}

impl LssResponse {
    /// Reads a frame of a slave.
    pub fn decode(f: &Frame) -> Result<LssResponse, LssFrameError> {
        let d = payload(f, SLAVE_TO_MASTER)?;
        Ok(match d[0] {
            0x44 => LssResponse::SelectiveSwitched,
            0x11 => LssResponse::NodeIdConfigured {
                error: d[1],
                spec: d[2],
            },
            0x13 => LssResponse::BitTimingConfigured {
                error: d[1],
                spec: d[2],
            },
            0x17 => LssResponse::Stored {
                error: d[1],
                spec: d[2],
            },
            0x4F => LssResponse::IdentifySlave,
            0x50 => LssResponse::NonConfigured,
            cs => match Inquiry::from_cs(cs) {
                Some(Inquiry::NodeId) => LssResponse::Inquired(Inquiry::NodeId, u32::from(d[1])),
                Some(q) => LssResponse::Inquired(q, u32_at(&d)),
                None => return Err(LssFrameError::UnknownCommand(cs)),
            },
        })
    }

    /// The command specifier of this answer.
    #[must_use]
    pub const fn cs(&self) -> u8 {
        match self {
            LssResponse::SelectiveSwitched => 0x44,
            LssResponse::NodeIdConfigured { .. } => 0x11,
            LssResponse::BitTimingConfigured { .. } => 0x13,
            LssResponse::Stored { .. } => 0x17,
            LssResponse::Inquired(q, _) => q.cs(),
            LssResponse::IdentifySlave => 0x4F,
            LssResponse::NonConfigured => 0x50,
        }
    }

    /// The frame of this answer.
    #[must_use]
    pub fn encode(&self) -> Frame {
        let id = SLAVE_TO_MASTER;
        let cs = self.cs();
        match *self {
            LssResponse::NodeIdConfigured { error, spec }
            | LssResponse::BitTimingConfigured { error, spec }
            | LssResponse::Stored { error, spec } => frame(id, cs, [error, spec, 0, 0, 0, 0, 0]),
            LssResponse::Inquired(Inquiry::NodeId, v) => frame(id, cs, [v as u8, 0, 0, 0, 0, 0, 0]),
            LssResponse::Inquired(_, v) => frame(id, cs, with_u32(v)),
            _ => frame(id, cs, [0; 7]),
        }
    }
}
