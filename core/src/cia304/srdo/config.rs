//! The SRDO parameters in the dictionary and the checks a configuration must pass before the
//! node may enter operational.
//!
//! **The objects.** SRDO `n` (1–64) has its communication parameters at 0x1301 + n − 1 and its
//! mapping at 0x1381 + n − 1; 0x13FE holds the one "configuration valid" byte for all of them and
//! 0x13FF sub `n` the checksum of SRDO `n`.
//!
//! | 0x1301 + n − 1 | Meaning |
//! | --- | --- |
//! | sub 1 | direction: 0 unused, 1 transmit (producer), 2 receive (consumer) |
//! | sub 2 | refresh time (producer) or safety cycle time, SCT (consumer), in ms |
//! | sub 3 | safety-related validation time, SRVT, in ms (normal → inverted) |
//! | sub 4 | transmission type: 254 is the only one CiA 304 allows |
//! | sub 5, 6 | COB-IDs of the normal and the inverted frame, 0x101–0x180, odd then even |
//!
//! The mapping has an even count of entries (at most 16): odd sub-indices map the objects the
//! normal frame carries, even ones the objects holding their bitwise inverse, in pairs.
//!
//! **The rule.** A configuration counts only if 0x13FE holds 0xA5 and, for every SRDO in use,
//! the parameters are in range and the checksum in 0x13FF matches the one computed here. Any
//! write to the parameters, the mapping or the checksums clears 0x13FE (the node does it), so a
//! configuration tool writes everything, then the checksums, then 0xA5 last.
//!
//! **The checksum.** CRC-16 CCITT (polynomial 0x1021, initial value 0, no reflection) over, in
//! this order: direction (1 byte), SCT (2 bytes, little-endian), SRVT (1 byte), the two COB-IDs
//! (4 bytes each, little-endian), the mapping count (1 byte), then for each entry its sub-index
//! (1 byte) and its value (4 bytes, little-endian). The transmission type is not part of it. This
//! is the layout CiA 304 gives and CANopenNode's `CO_SRDO.c` computes, so a checksum a tool made
//! for one passes the other.

use crate::cia301::pdo::{check_entry, Dir, MapEntry};
use crate::frame::cob_id::NodeId;
use crate::frame::instant::Duration;
use crate::od::abort::AbortCode;
use crate::od::ObjectDictionary;
use core::fmt;

/// GFC parameter (0x1300): 1 when the global fail-safe command is in use.
pub const GFC_PARAMETER: u16 = 0x1300;
/// Communication parameters of SRDO 1 (SRDO n: `COMM + n − 1`).
pub const COMM: u16 = 0x1301;
/// Mapping of SRDO 1 (SRDO n: `MAPPING + n − 1`).
pub const MAPPING: u16 = 0x1381;
/// Configuration valid: [`VALID`] when the whole SRDO configuration was checked.
pub const CONFIG_VALID: u16 = 0x13FE;
/// Safety configuration checksums: sub n for SRDO n.
pub const CHECKSUMS: u16 = 0x13FF;
/// The value of 0x13FE that says "valid".
pub const VALID: u8 = 0xA5;
/// SRDOs CiA 304 numbers.
pub const MAX_SRDOS: u16 = 64;
/// Mapping entries an SRDO can have (eight normal, eight inverted).
pub const MAX_MAPPED: u8 = 16;
/// The transmission type CiA 304 allows.
pub const TRANSMISSION_TYPE: u8 = 254;

/// Sub-indices of the communication parameters.
pub mod sub {
    /// Direction.
    pub const DIRECTION: u8 = 1;
    /// Refresh time / SCT.
    pub const SCT: u8 = 2;
    /// SRVT.
    pub const SRVT: u8 = 3;
    /// Transmission type.
    pub const TRANSMISSION_TYPE: u8 = 4;
    /// COB-ID of the normal frame.
    pub const COB_NORMAL: u8 = 5;
    /// COB-ID of the inverted frame.
    pub const COB_INVERTED: u8 = 6;
}

/// The default COB-IDs of a node's SRDO (normal, inverted): 0xFF + 2 × node-ID and
/// 0x100 + 2 × node-ID, for node-IDs 1–64 (0x101/0x102 for node 1 … 0x17F/0x180 for node 64).
/// `None` above 64: such a node has no default and must be given its identifiers.
#[must_use]
pub const fn default_cob_ids(node: NodeId) -> Option<(u16, u16)> {
    let n = node.raw() as u16;
    if n > 64 {
        return None;
    }
    Some((0xFF + 2 * n, 0x100 + 2 * n))
}

/// What an SRDO does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SrdoDirection {
    /// Not used (0).
    Unused,
    /// Producer (1).
    Transmit,
    /// Consumer (2).
    Receive,
}

/// The communication parameters of one SRDO as the dictionary holds them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SrdoParams {
    /// Sub 1.
    pub direction: SrdoDirection,
    /// Sub 2: refresh time (producer) or SCT (consumer), ms.
    pub sct_ms: u16,
    /// Sub 3: SRVT, ms.
    pub srvt_ms: u8,
    /// Sub 4.
    pub transmission_type: u8,
    /// Sub 5: COB-ID of the normal frame.
    pub cob_normal: u32,
    /// Sub 6: COB-ID of the inverted frame.
    pub cob_inverted: u32,
}

impl SrdoParams {
    /// The refresh time or SCT.
    #[must_use]
    pub const fn sct(&self) -> Duration {
        Duration::from_millis(self.sct_ms as u64)
    }
    /// The SRVT.
    #[must_use]
    pub const fn srvt(&self) -> Duration {
        Duration::from_millis(self.srvt_ms as u64)
    }
    /// The direction byte (sub 1).
    #[must_use]
    pub const fn direction_code(&self) -> u8 {
        match self.direction {
            SrdoDirection::Unused => 0,
            SrdoDirection::Transmit => 1,
            SrdoDirection::Receive => 2,
        }
    }
}

/// The mapping of one SRDO: entries 1..=count, odd ones normal, even ones inverted.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SrdoMapping {
    count: u8,
    entries: [MapEntry; MAX_MAPPED as usize],
}

impl SrdoMapping {
    /// No entries.
    pub const EMPTY: SrdoMapping = SrdoMapping {
        count: 0,
        entries: [MapEntry::new(0, 0, 0); MAX_MAPPED as usize],
    };

    /// A mapping of `(normal, inverted)` pairs (at most eight; more are cut).
    #[must_use]
    pub fn pairs(pairs: &[(MapEntry, MapEntry)]) -> SrdoMapping {
        let mut m = SrdoMapping::EMPTY;
        for (k, (n, i)) in pairs.iter().take(MAX_MAPPED as usize / 2).enumerate() {
            m.entries[2 * k] = *n;
            m.entries[2 * k + 1] = *i;
            m.count += 2;
        }
        m
    }
    /// Number of entries (sub 0).
    #[must_use]
    pub const fn count(&self) -> u8 {
        self.count
    }
    /// All entries in sub-index order.
    pub fn entries(&self) -> &[MapEntry] {
        &self.entries[..self.count as usize]
    }
    /// The entries the normal frame carries (odd sub-indices).
    pub fn normal(&self) -> impl Iterator<Item = MapEntry> + '_ {
        self.entries().iter().copied().step_by(2)
    }
    /// The entries the inverted frame carries (even sub-indices).
    pub fn inverted(&self) -> impl Iterator<Item = MapEntry> + '_ {
        self.entries().iter().copied().skip(1).step_by(2)
    }
    /// Bytes each of the two frames carries.
    #[must_use]
    pub fn bytes(&self) -> u8 {
        (self.normal().map(|e| e.bits as u32).sum::<u32>() / 8) as u8
    }
}

/// One SRDO's checked configuration.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SrdoConfig {
    /// Communication parameters.
    pub params: SrdoParams,
    /// Mapping.
    pub mapping: SrdoMapping,
}

impl SrdoConfig {
    /// The 11-bit identifier of the normal frame.
    #[must_use]
    pub fn normal_id(&self) -> u16 {
        (self.params.cob_normal & 0x7FF) as u16
    }
    /// The 11-bit identifier of the inverted frame.
    #[must_use]
    pub fn inverted_id(&self) -> u16 {
        (self.params.cob_inverted & 0x7FF) as u16
    }
}

/// What is wrong with an SRDO configuration.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum SrdoProblem {
    /// 0x13FE does not hold 0xA5 (it holds this).
    NotValid(u8),
    /// An object the configuration needs cannot be read.
    Missing(AbortCode),
    /// Direction other than 0, 1 or 2.
    Direction,
    /// Refresh time / SCT of 0.
    CycleTime,
    /// SRVT of 0.
    ValidationTime,
    /// Transmission type other than 254.
    TransmissionType,
    /// COB-IDs outside 0x101–0x180, or not an odd normal and the even one after it.
    CobId,
    /// Mapping count odd or above 16, or no entries.
    MappingCount,
    /// A mapping entry the dictionary cannot serve (abort code as an SDO write would give), or
    /// not whole bytes.
    Mapping(AbortCode),
    /// Normal and inverted entries differ in length, or together exceed eight bytes.
    Length,
    /// The checksum in 0x13FF differs from the configuration's.
    Checksum {
        /// What 0x13FF holds.
        stored: u16,
        /// What the configuration gives.
        computed: u16,
    },
}

/// Why a node's SRDO configuration is refused: which SRDO, which entry, what.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SrdoConfigError {
    /// SRDO number (1-based); 0 for 0x13FE itself.
    pub srdo: u16,
    /// The object at fault.
    pub index: u16,
    /// Its sub-index.
    pub sub: u8,
    /// What is wrong.
    pub problem: SrdoProblem,
}

impl SrdoProblem {
    /// A number for the problem, as the refusal's EMCY carries it: 1 not valid, 2 missing,
    /// 3 direction, 4 refresh time / SCT, 5 SRVT, 6 transmission type, 7 COB-IDs, 8 mapping
    /// count, 9 mapping entry, 10 length, 11 checksum.
    #[must_use]
    pub const fn number(self) -> u8 {
        match self {
            SrdoProblem::NotValid(_) => 1,
            SrdoProblem::Missing(_) => 2,
            SrdoProblem::Direction => 3,
            SrdoProblem::CycleTime => 4,
            SrdoProblem::ValidationTime => 5,
            SrdoProblem::TransmissionType => 6,
            SrdoProblem::CobId => 7,
            SrdoProblem::MappingCount => 8,
            SrdoProblem::Mapping(_) => 9,
            SrdoProblem::Length => 10,
            SrdoProblem::Checksum { .. } => 11,
        }
    }
}

impl SrdoConfigError {
    /// The five manufacturer bytes of the EMCY a node sends when it refuses operational for
    /// this: SRDO number (0 for 0x13FE; low byte), the object's index (little-endian), its
    /// sub-index, and the problem's [`SrdoProblem::number`].
    #[must_use]
    pub const fn emcy_data(&self) -> [u8; 5] {
        let [lo, hi] = self.index.to_le_bytes();
        [self.srdo as u8, lo, hi, self.sub, self.problem.number()]
    }
}

impl fmt::Display for SrdoConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "SRDO {} configuration, {:04X}sub{}: ",
            self.srdo, self.index, self.sub
        )?;
        match self.problem {
            SrdoProblem::NotValid(v) => {
                write!(f, "not marked valid (0x13FE = 0x{v:02X}, not 0xA5)")
            }
            SrdoProblem::Missing(code) => write!(f, "cannot be read ({code})"),
            SrdoProblem::Direction => f.write_str("direction is not 0, 1 or 2"),
            SrdoProblem::CycleTime => f.write_str("refresh time / SCT is 0"),
            SrdoProblem::ValidationTime => f.write_str("SRVT is 0"),
            SrdoProblem::TransmissionType => f.write_str("transmission type is not 254"),
            SrdoProblem::CobId => f.write_str("COB-IDs are not an odd/even pair in 0x101-0x180"),
            SrdoProblem::MappingCount => f.write_str("mapping count is not even in 2-16"),
            SrdoProblem::Mapping(code) => write!(f, "mapping entry refused ({code})"),
            SrdoProblem::Length => {
                f.write_str("normal and inverted data differ in length or exceed 8 bytes")
            }
            SrdoProblem::Checksum { stored, computed } => write!(
                f,
                "checksum 0x{stored:04X} does not match the configuration's 0x{computed:04X}"
            ),
        }
    }
}

impl core::error::Error for SrdoConfigError {}

/// CRC-16 CCITT (polynomial 0x1021, no reflection) continuing from a CRC over more bytes: the
/// same CRC as the SDO block transfer's, so one table serves both.
pub use crate::cia301::sdo::crc::update as crc16_ccitt;

/// The checksum CiA 304 defines over one SRDO's parameters and mapping (module doc).
#[must_use]
pub fn signature(params: &SrdoParams, mapping: &SrdoMapping) -> u16 {
    let mut crc = crc16_ccitt(0, &[params.direction_code()]);
    crc = crc16_ccitt(crc, &params.sct_ms.to_le_bytes());
    crc = crc16_ccitt(crc, &[params.srvt_ms]);
    crc = crc16_ccitt(crc, &params.cob_normal.to_le_bytes());
    crc = crc16_ccitt(crc, &params.cob_inverted.to_le_bytes());
    crc = crc16_ccitt(crc, &[mapping.count]);
    for (k, e) in mapping.entries().iter().enumerate() {
        crc = crc16_ccitt(crc, &[k as u8 + 1]);
        crc = crc16_ccitt(crc, &e.raw().to_le_bytes());
    }
    crc
}

fn read_u32<D: ObjectDictionary + ?Sized>(
    od: &D,
    srdo: u16,
    index: u16,
    sub: u8,
) -> Result<u32, SrdoConfigError> {
    let data = od.read(index, sub).map_err(|code| SrdoConfigError {
        srdo,
        index,
        sub,
        problem: SrdoProblem::Missing(code),
    })?;
    let mut b = [0u8; 4];
    let n = data.len().min(4);
    b[..n].copy_from_slice(&data[..n]);
    Ok(u32::from_le_bytes(b))
}

/// Reads SRDO `n`'s parameters and mapping as stored, without judging them. `None` when the
/// dictionary has no 0x1301 + n − 1.
pub fn read<D: ObjectDictionary + ?Sized>(
    od: &D,
    n: u16,
) -> Result<Option<(SrdoParams, SrdoMapping)>, SrdoConfigError> {
    let comm = COMM + n - 1;
    if od.get(comm, 0).is_err() {
        return Ok(None);
    }
    let dir = read_u32(od, n, comm, sub::DIRECTION)?;
    let direction = match dir {
        0 => SrdoDirection::Unused,
        1 => SrdoDirection::Transmit,
        2 => SrdoDirection::Receive,
        _ => return Err(fault(n, comm, sub::DIRECTION, SrdoProblem::Direction)),
    };
    let params = SrdoParams {
        direction,
        sct_ms: read_u32(od, n, comm, sub::SCT)? as u16,
        srvt_ms: read_u32(od, n, comm, sub::SRVT)? as u8,
        transmission_type: read_u32(od, n, comm, sub::TRANSMISSION_TYPE)? as u8,
        cob_normal: read_u32(od, n, comm, sub::COB_NORMAL)?,
        cob_inverted: read_u32(od, n, comm, sub::COB_INVERTED)?,
    };
    let map = MAPPING + n - 1;
    let count = read_u32(od, n, map, 0)?;
    if count > MAX_MAPPED as u32 || !count.is_multiple_of(2) {
        return Err(fault(n, map, 0, SrdoProblem::MappingCount));
    }
    let mut mapping = SrdoMapping {
        count: count as u8,
        ..SrdoMapping::EMPTY
    };
    for s in 1..=count as u8 {
        mapping.entries[s as usize - 1] = MapEntry::from_raw(read_u32(od, n, map, s)?);
    }
    Ok(Some((params, mapping)))
}

fn fault(srdo: u16, index: u16, sub: u8, problem: SrdoProblem) -> SrdoConfigError {
    SrdoConfigError {
        srdo,
        index,
        sub,
        problem,
    }
}

/// Judges SRDO `n`'s parameters and mapping against CiA 304 and the dictionary (everything but
/// 0x13FE and the checksum).
pub fn check<D: ObjectDictionary + ?Sized>(
    od: &D,
    n: u16,
    params: &SrdoParams,
    mapping: &SrdoMapping,
) -> Result<(), SrdoConfigError> {
    let (comm, map) = (COMM + n - 1, MAPPING + n - 1);
    let p = params;
    if p.sct_ms == 0 {
        return Err(fault(n, comm, sub::SCT, SrdoProblem::CycleTime));
    }
    if p.srvt_ms == 0 {
        return Err(fault(n, comm, sub::SRVT, SrdoProblem::ValidationTime));
    }
    if p.transmission_type != TRANSMISSION_TYPE {
        return Err(fault(
            n,
            comm,
            sub::TRANSMISSION_TYPE,
            SrdoProblem::TransmissionType,
        ));
    }
    if !(0x101..=0x17F).contains(&p.cob_normal) || p.cob_normal.is_multiple_of(2) {
        return Err(fault(n, comm, sub::COB_NORMAL, SrdoProblem::CobId));
    }
    if p.cob_inverted != p.cob_normal + 1 {
        return Err(fault(n, comm, sub::COB_INVERTED, SrdoProblem::CobId));
    }
    if mapping.count == 0 {
        return Err(fault(n, map, 0, SrdoProblem::MappingCount));
    }
    let mut bits = [0u32; 2];
    for (k, e) in mapping.entries().iter().enumerate() {
        let dir = match p.direction {
            SrdoDirection::Receive => Dir::Receive,
            _ => Dir::Transmit,
        };
        let s = k as u8 + 1;
        check_entry(od, dir, *e).map_err(|c| fault(n, map, s, SrdoProblem::Mapping(c)))?;
        // The inverse is checked byte by byte: entries in whole bytes only.
        if !e.bits.is_multiple_of(8) {
            let c = AbortCode::NOT_MAPPABLE;
            return Err(fault(n, map, s, SrdoProblem::Mapping(c)));
        }
        bits[k % 2] += e.bits as u32;
    }
    if bits[0] != bits[1] || bits[0] > 64 {
        return Err(fault(n, map, 0, SrdoProblem::Length));
    }
    Ok(())
}

/// SRDO `n` as the node runs it: `Ok(None)` when the dictionary has no such SRDO or it is
/// unused, the checked configuration otherwise. The checksum in 0x13FF sub `n` must match.
/// 0x13FE is the caller's ([`check_valid`]).
pub fn load<D: ObjectDictionary + ?Sized>(
    od: &D,
    n: u16,
) -> Result<Option<SrdoConfig>, SrdoConfigError> {
    let Some((params, mapping)) = read(od, n)? else {
        return Ok(None);
    };
    if params.direction == SrdoDirection::Unused {
        return Ok(None);
    }
    check(od, n, &params, &mapping)?;
    let stored = read_u32(od, n, CHECKSUMS, n as u8)? as u16;
    let computed = signature(&params, &mapping);
    if stored != computed {
        let problem = SrdoProblem::Checksum { stored, computed };
        return Err(fault(n, CHECKSUMS, n as u8, problem));
    }
    Ok(Some(SrdoConfig { params, mapping }))
}

/// 0x13FE: `Ok(false)` when the dictionary has no SRDO objects at all, `Ok(true)` when it holds
/// 0xA5, the refusal otherwise.
pub fn check_valid<D: ObjectDictionary + ?Sized>(od: &D) -> Result<bool, SrdoConfigError> {
    let Ok(data) = od.read(CONFIG_VALID, 0) else {
        return Ok(false);
    };
    match data.first() {
        Some(&VALID) => Ok(true),
        v => Err(fault(
            0,
            CONFIG_VALID,
            0,
            SrdoProblem::NotValid(v.copied().unwrap_or(0)),
        )),
    }
}

/// True for the objects whose change invalidates the configuration (0x13FE is cleared).
#[must_use]
pub const fn invalidates(index: u16) -> bool {
    matches!(index, 0x1301..=0x1340 | 0x1381..=0x13C0 | CHECKSUMS)
}

/// True for the objects that may change only outside operational (CiA 304: SRDO parameters,
/// mapping, 0x13FE and 0x13FF are configured in pre-operational).
#[must_use]
pub const fn locked_in_operational(index: u16) -> bool {
    invalidates(index) || index == CONFIG_VALID
}

/// One write of an SRDO configuration: `data()` into `index`/`sub`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SrdoWrite {
    /// Object.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    bytes: [u8; 4],
    size: u8,
}

impl SrdoWrite {
    const fn new(index: u16, sub: u8, value: u32, size: u8) -> SrdoWrite {
        SrdoWrite {
            index,
            sub,
            bytes: value.to_le_bytes(),
            size,
        }
    }
    /// The little-endian bytes to write (1, 2 or 4).
    pub fn data(&self) -> &[u8] {
        &self.bytes[..self.size as usize]
    }
}

/// Writes that give SRDO `n` this configuration, in the order a configuration tool makes
/// them: the communication parameters, the mapping (count 0, the entries, the count), then the
/// checksum computed here. 0x13FE is written once after all SRDOs ([`mark_valid`]).
pub fn writes(n: u16, cfg: &SrdoConfig) -> impl Iterator<Item = SrdoWrite> + '_ {
    let (comm, map) = (COMM + n - 1, MAPPING + n - 1);
    let p = &cfg.params;
    let m = &cfg.mapping;
    let params = [
        SrdoWrite::new(comm, sub::DIRECTION, p.direction_code() as u32, 1),
        SrdoWrite::new(comm, sub::SCT, p.sct_ms as u32, 2),
        SrdoWrite::new(comm, sub::SRVT, p.srvt_ms as u32, 1),
        SrdoWrite::new(comm, sub::TRANSMISSION_TYPE, p.transmission_type as u32, 1),
        SrdoWrite::new(comm, sub::COB_NORMAL, p.cob_normal, 4),
        SrdoWrite::new(comm, sub::COB_INVERTED, p.cob_inverted, 4),
        SrdoWrite::new(map, 0, 0, 1),
    ];
    let entries = (m.entries().iter().enumerate())
        .map(move |(k, e)| SrdoWrite::new(map, k as u8 + 1, e.raw(), 4));
    let tail = [
        SrdoWrite::new(map, 0, m.count() as u32, 1),
        SrdoWrite::new(CHECKSUMS, n as u8, signature(p, m) as u32, 2),
    ];
    params.into_iter().chain(entries).chain(tail)
}

/// The write that marks the whole SRDO configuration valid (0x13FE = 0xA5), last.
#[must_use]
pub const fn mark_valid() -> SrdoWrite {
    SrdoWrite::new(CONFIG_VALID, 0, VALID as u32, 1)
}

impl SrdoConfig {
    /// A configuration on the COB-IDs `normal` and `normal + 1` with transmission type 254:
    /// a producer (`transmit`) refreshing every `sct_ms`, or a consumer with that SCT.
    #[must_use]
    pub const fn new(
        transmit: bool,
        sct_ms: u16,
        srvt_ms: u8,
        normal: u16,
        mapping: SrdoMapping,
    ) -> Self {
        SrdoConfig {
            params: SrdoParams {
                direction: if transmit {
                    SrdoDirection::Transmit
                } else {
                    SrdoDirection::Receive
                },
                sct_ms,
                srvt_ms,
                transmission_type: TRANSMISSION_TYPE,
                cob_normal: normal as u32,
                cob_inverted: normal as u32 + 1,
            },
            mapping,
        }
    }
}
