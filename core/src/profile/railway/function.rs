//! The 9-bit function codes of the railway scheme.

use core::fmt;

/// What a railway frame is, from the top 9 bits of its identifier. Lower codes win arbitration.
///
/// The published railway design fixes fault report, heartbeat, command (answer), state change, node guarding and
/// state query. The rest are duocan's choices, documented here:
///
/// - **State answer 0x044**: the published design's source gives 0x040 for both node guarding and state
///   answer; 0x044 is the next free code of the same priority class.
/// - **NMT 0x000** (address 0): the published design has no NMT identifier; module control must beat
///   everything, as CiA 301 gives it 0x000.
/// - **SYNC 0x002** (address 0): the interlocking cycle; above fault reports, as CiA 301 puts
///   SYNC (0x080) above EMCY (0x081+).
/// - **SDO 0x080 / 0x082** (server's address, port 0): configuration traffic, below every
///   process and error-control code; answer below request as the published design orders command answer
///   (0x010) before command (0x012).
/// - **Unmapped 0x1FF**: the lowest priority; what a node missing from the profile's table
///   sends its error control on, so that the mistake is visible on the bus and nobody acts on
///   it (never decoded as a service).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[repr(u16)]
pub enum RailFunction {
    /// NMT module control (duocan's choice; address 0).
    Nmt = 0x000,
    /// SYNC, the interlocking cycle (duocan's choice; address 0).
    Sync = 0x002,
    /// Fault report: the node's EMCY (CiA 301 EMCY payload).
    FaultReport = 0x004,
    /// Heartbeat and boot-up (CiA 301 error-control payload).
    Heartbeat = 0x008,
    /// Answer of a board to a command (railway payload with CRC).
    CommandAnswer = 0x010,
    /// Command of the interlocking to a board's I/O port (railway payload with CRC).
    Command = 0x012,
    /// Spontaneous state change of a field device (railway payload with CRC).
    StateChange = 0x020,
    /// Node guarding: remote request of the master, answer of the node.
    NodeGuarding = 0x040,
    /// State query of the interlocking (railway payload with CRC, no data).
    StateQuery = 0x042,
    /// State answer (0x044: the published design's source gives 0x040 twice).
    StateAnswer = 0x044,
    /// SDO server → client (duocan's choice).
    SdoResponse = 0x080,
    /// SDO client → server (duocan's choice).
    SdoRequest = 0x082,
    /// Error control of a node missing from the table (never decoded as a service).
    Unmapped = 0x1FF,
}

impl RailFunction {
    /// Every code, in priority order.
    pub const ALL: [RailFunction; 13] = [
        RailFunction::Nmt,
        RailFunction::Sync,
        RailFunction::FaultReport,
        RailFunction::Heartbeat,
        RailFunction::CommandAnswer,
        RailFunction::Command,
        RailFunction::StateChange,
        RailFunction::NodeGuarding,
        RailFunction::StateQuery,
        RailFunction::StateAnswer,
        RailFunction::SdoResponse,
        RailFunction::SdoRequest,
        RailFunction::Unmapped,
    ];

    /// The 9-bit code.
    pub const fn code(self) -> u16 {
        self as u16
    }
    /// The function with this code; `None` for codes the scheme does not use (free for the
    /// application).
    pub const fn from_code(code: u16) -> Option<RailFunction> {
        Some(match code {
            0x000 => RailFunction::Nmt,
            0x002 => RailFunction::Sync,
            0x004 => RailFunction::FaultReport,
            0x008 => RailFunction::Heartbeat,
            0x010 => RailFunction::CommandAnswer,
            0x012 => RailFunction::Command,
            0x020 => RailFunction::StateChange,
            0x040 => RailFunction::NodeGuarding,
            0x042 => RailFunction::StateQuery,
            0x044 => RailFunction::StateAnswer,
            0x080 => RailFunction::SdoResponse,
            0x082 => RailFunction::SdoRequest,
            0x1FF => RailFunction::Unmapped,
            _ => return None,
        })
    }
    /// True when the addressed device sends frames of this function (they tell who spoke);
    /// false when the interlocking sends them to the address.
    pub const fn from_device(self) -> bool {
        matches!(
            self,
            RailFunction::FaultReport
                | RailFunction::Heartbeat
                | RailFunction::CommandAnswer
                | RailFunction::StateChange
                | RailFunction::NodeGuarding
                | RailFunction::StateAnswer
                | RailFunction::SdoResponse
        )
    }
    /// True for functions of the board as a whole: their address has port 0.
    pub const fn node_level(self) -> bool {
        !matches!(
            self,
            RailFunction::CommandAnswer
                | RailFunction::Command
                | RailFunction::StateChange
                | RailFunction::StateQuery
                | RailFunction::StateAnswer
        )
    }
    /// True for functions whose payload is index + sub-index + data + CRC
    /// ([`super::payload`]).
    pub const fn has_crc_payload(self) -> bool {
        !self.node_level()
    }
}

impl fmt::Display for RailFunction {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            RailFunction::Nmt => "NMT",
            RailFunction::Sync => "SYNC",
            RailFunction::FaultReport => "fault report",
            RailFunction::Heartbeat => "heartbeat",
            RailFunction::CommandAnswer => "command answer",
            RailFunction::Command => "command",
            RailFunction::StateChange => "state change",
            RailFunction::NodeGuarding => "node guarding",
            RailFunction::StateQuery => "state query",
            RailFunction::StateAnswer => "state answer",
            RailFunction::SdoResponse => "SDO response",
            RailFunction::SdoRequest => "SDO request",
            RailFunction::Unmapped => "unmapped node",
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_round_trip_and_are_distinct_and_in_priority_order() {
        for (i, f) in RailFunction::ALL.iter().enumerate() {
            assert_eq!(RailFunction::from_code(f.code()), Some(*f));
            assert!(f.code() <= super::super::address::FUNCTION_MAX);
            if i > 0 {
                assert!(RailFunction::ALL[i - 1].code() < f.code());
            }
        }
        let known = (0..=0x1FF).filter_map(RailFunction::from_code).count();
        assert_eq!(known, RailFunction::ALL.len());
    }

    #[test]
    fn the_seed_codes_are_kept() {
        assert_eq!(RailFunction::FaultReport.code(), 0x004);
        assert_eq!(RailFunction::Heartbeat.code(), 0x008);
        assert_eq!(RailFunction::CommandAnswer.code(), 0x010);
        assert_eq!(RailFunction::Command.code(), 0x012);
        assert_eq!(RailFunction::StateChange.code(), 0x020);
        assert_eq!(RailFunction::NodeGuarding.code(), 0x040);
        assert_eq!(RailFunction::StateQuery.code(), 0x042);
        assert_eq!(RailFunction::StateAnswer.code(), 0x044);
    }
}
