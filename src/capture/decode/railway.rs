//! The railway profile's 29-bit frames: function and address from the identifier, CiA 301
//! payloads for the node-level services, the railway payload (CRC checked) for process frames.

use super::frames::{emcy_text, nmt_text, state_text, DecodedFrame, Hex, RailPayload, N};
use super::kind::Kind;
use super::sdo::{self, SdoSide, Tracks};
use super::services::{bad, emcy_payload, nmt_payload, state_payload, wrong_length};
use crate::frame::cob_id::NodeId;
use crate::frame::Frame;
use crate::profile::railway::{split, DeviceAddress, Payload, RailFunction, RailwayProfile};
use core::fmt;

pub(super) fn decode(profile: &RailwayProfile, sdo: &mut Tracks, frame: &Frame) -> DecodedFrame {
    let Some((code, address)) = split(frame.id()) else {
        return DecodedFrame::Unknown(*frame);
    };
    let Some(function) = RailFunction::from_code(code) else {
        return DecodedFrame::Unknown(*frame);
    };
    // Node-level services name the board (port 0); process frames a port of it.
    let node = profile.node_at(address);
    match payload(function, node, sdo, frame) {
        Ok(payload) => DecodedFrame::Railway {
            function,
            address,
            node,
            payload,
        },
        Err(why) => bad(
            Kind::Railway,
            node,
            format!("{function} at {address}: {why}"),
        ),
    }
}

fn payload(
    function: RailFunction,
    node: Option<NodeId>,
    sdo: &mut Tracks,
    frame: &Frame,
) -> Result<RailPayload, String> {
    use RailFunction as F;
    if frame.is_remote() && function != F::NodeGuarding {
        return Err(wrong_length(frame, "this function", "data"));
    }
    Ok(match function {
        F::Nmt => {
            if frame.data().len() != 2 {
                return Err(wrong_length(frame, "an NMT command", "2"));
            }
            let (command, target) = nmt_payload(frame.data())?;
            RailPayload::Nmt { command, target }
        }
        F::Sync if frame.data().is_empty() => RailPayload::Sync,
        F::Sync => return Err(wrong_length(frame, "a railway SYNC", "0")),
        F::FaultReport => RailPayload::Emcy(emcy_payload(frame)?),
        F::NodeGuarding if frame.is_remote() => RailPayload::GuardingRequest,
        F::Heartbeat | F::NodeGuarding => {
            let (state, toggle) = state_payload(frame)?;
            RailPayload::State { state, toggle }
        }
        F::SdoRequest | F::SdoResponse => {
            let side = match function {
                F::SdoRequest => SdoSide::Client,
                _ => SdoSide::Server,
            };
            RailPayload::Sdo(match node {
                Some(n) => sdo.info(n, side, frame)?,
                None => sdo::without_context(side, frame)?,
            })
        }
        F::Unmapped => RailPayload::Unmapped(frame.data().to_vec()),
        F::Command | F::CommandAnswer | F::StateChange | F::StateQuery | F::StateAnswer => {
            RailPayload::Process(Payload::decode(frame).map_err(|e| match e {
                crate::profile::railway::PayloadError::Crc {
                    computed, carried, ..
                } => format!(
                    "CRC {carried:#06x} does not match {computed:#06x} ({}): corrupted or misrouted",
                    Hex(frame.data())
                ),
                _ => wrong_length(frame, "a railway payload", "5-8"),
            })?)
        }
    })
}

/// `railway R1 C2 L3 B4 P0 node 10 heartbeat operational`.
pub(super) fn text(
    f: &mut fmt::Formatter<'_>,
    function: RailFunction,
    address: DeviceAddress,
    node: Option<NodeId>,
    payload: &RailPayload,
) -> fmt::Result {
    write!(f, "railway {address}")?;
    if let Some(n) = node {
        write!(f, " {}", N(n))?;
    }
    f.write_str(" ")?;
    match payload {
        RailPayload::Nmt { command, target } => nmt_text(f, *command, *target),
        RailPayload::Sync => f.write_str("SYNC"),
        RailPayload::Emcy(e) => emcy_text(f, e),
        RailPayload::State { state, toggle } => state_text(f, *state, *toggle),
        RailPayload::GuardingRequest => f.write_str("guarding request"),
        RailPayload::Sdo(s) => write!(f, "{s}"),
        RailPayload::Process(p) => {
            write!(f, "{function} {:#06x}:{:02x}", p.index(), p.sub())?;
            if !p.data().is_empty() {
                write!(f, " = {}", Hex(p.data()))?;
            }
            Ok(())
        }
        RailPayload::Unmapped(d) if d.is_empty() => write!(f, "{function}"),
        RailPayload::Unmapped(d) => write!(f, "{function} {}", Hex(d)),
    }
}
