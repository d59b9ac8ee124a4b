//! The kinds of frame a filter names, and the flying-master frames.

use core::fmt;

/// The kinds of frame, for filtering (`--kind sdo,nmt`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[non_exhaustive]
pub enum Kind {
    /// NMT module control.
    Nmt,
    /// SYNC.
    Sync,
    /// TIME.
    Time,
    /// EMCY.
    Emcy,
    /// Heartbeat, boot-up and node guarding.
    Heartbeat,
    /// SDO.
    Sdo,
    /// PDO.
    Pdo,
    /// LSS.
    Lss,
    /// Flying master (CiA 302-2).
    FlyingMaster,
    /// A railway 29-bit frame.
    Railway,
    /// Nothing known.
    Unknown,
}

impl Kind {
    /// Every kind.
    pub const ALL: [Kind; 11] = [
        Kind::Nmt,
        Kind::Sync,
        Kind::Time,
        Kind::Emcy,
        Kind::Heartbeat,
        Kind::Sdo,
        Kind::Pdo,
        Kind::Lss,
        Kind::FlyingMaster,
        Kind::Railway,
        Kind::Unknown,
    ];
    /// Its name in filters and JSON: `nmt`, `sync`, `time`, `emcy`, `heartbeat`, `sdo`, `pdo`,
    /// `lss`, `flying-master`, `railway`, `unknown`.
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            Kind::Nmt => "nmt",
            Kind::Sync => "sync",
            Kind::Time => "time",
            Kind::Emcy => "emcy",
            Kind::Heartbeat => "heartbeat",
            Kind::Sdo => "sdo",
            Kind::Pdo => "pdo",
            Kind::Lss => "lss",
            Kind::FlyingMaster => "flying-master",
            Kind::Railway => "railway",
            Kind::Unknown => "unknown",
        }
    }
    /// The kind named `name` (case-insensitive).
    #[must_use]
    pub fn from_name(name: &str) -> Option<Kind> {
        Kind::ALL
            .into_iter()
            .find(|k| k.name().eq_ignore_ascii_case(name))
    }
    /// What a line says for a frame of this kind: `heartbeat`, `SDO`, `EMCY`.
    pub(super) const fn label(self) -> &'static str {
        match self {
            Kind::Nmt => "NMT",
            Kind::Sync => "SYNC",
            Kind::Time => "TIME",
            Kind::Emcy => "EMCY",
            Kind::Heartbeat => "heartbeat",
            Kind::Sdo => "SDO",
            Kind::Pdo => "PDO",
            Kind::Lss => "LSS",
            Kind::FlyingMaster => "flying master",
            Kind::Railway => "railway",
            Kind::Unknown => "unknown",
        }
    }
}

impl fmt::Display for Kind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The six flying-master frames of CiA 302-2 (11-bit COB-IDs 0x71–0x76).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum FlyingMasterFrame {
    /// 0x71: an active master announces itself (priority, node-ID).
    ActiveMasterResponse,
    /// 0x72: start a negotiation.
    NegotiationRequest,
    /// 0x73: who is the active master?
    ActiveMasterRequest,
    /// 0x74: a master-capable device answers (priority, node-ID).
    MasterCapableResponse,
    /// 0x75: which devices are master-capable?
    MasterCapableRequest,
    /// 0x76: force a negotiation; an active master's multiple-master detection (priority,
    /// node-ID).
    ForceNegotiation,
}

impl FlyingMasterFrame {
    /// The COB-ID.
    #[must_use]
    pub const fn cob_id(self) -> u16 {
        match self {
            FlyingMasterFrame::ActiveMasterResponse => 0x71,
            FlyingMasterFrame::NegotiationRequest => 0x72,
            FlyingMasterFrame::ActiveMasterRequest => 0x73,
            FlyingMasterFrame::MasterCapableResponse => 0x74,
            FlyingMasterFrame::MasterCapableRequest => 0x75,
            FlyingMasterFrame::ForceNegotiation => 0x76,
        }
    }
    /// The frame on 11-bit identifier `raw`.
    #[must_use]
    pub const fn from_cob_id(raw: u16) -> Option<FlyingMasterFrame> {
        Some(match raw {
            0x71 => FlyingMasterFrame::ActiveMasterResponse,
            0x72 => FlyingMasterFrame::NegotiationRequest,
            0x73 => FlyingMasterFrame::ActiveMasterRequest,
            0x74 => FlyingMasterFrame::MasterCapableResponse,
            0x75 => FlyingMasterFrame::MasterCapableRequest,
            0x76 => FlyingMasterFrame::ForceNegotiation,
            _ => return None,
        })
    }
    /// True for the three that carry (priority, node-ID).
    #[must_use]
    pub const fn carries_rank(self) -> bool {
        matches!(
            self,
            FlyingMasterFrame::ActiveMasterResponse
                | FlyingMasterFrame::MasterCapableResponse
                | FlyingMasterFrame::ForceNegotiation
        )
    }
}

impl fmt::Display for FlyingMasterFrame {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            FlyingMasterFrame::ActiveMasterResponse => "active-master response",
            FlyingMasterFrame::NegotiationRequest => "negotiation request",
            FlyingMasterFrame::ActiveMasterRequest => "active-master request",
            FlyingMasterFrame::MasterCapableResponse => "master-capable response",
            FlyingMasterFrame::MasterCapableRequest => "master-capable request",
            FlyingMasterFrame::ForceNegotiation => "force negotiation",
        })
    }
}
