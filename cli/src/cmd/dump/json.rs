//! A decoded frame as one JSON object: where and when, the frame, and what it is, with the
//! fields of its kind (the library's types have public fields; the tool names them).

use duocan::capture::decode::{
    DecodedFrame, FieldValue, PdoInfo, RailPayload, SdoInfo, SdoSide, SdoStep,
};
use duocan::emcy::EmcyMessage;
use duocan::{FdFrame, Frame, Id, NmtCommand, NmtState, NmtTarget};
use serde_json::{json, Map, Value};

/// `0a0b0c`: bytes as JSON carries them.
pub fn hex(d: &[u8]) -> String {
    d.iter().map(|b| format!("{b:02x}")).collect()
}

/// `{"time": "1700000000.000200", "timestamp_us": …, "interface": "can0", "id": 1541, …}`.
pub fn line(timestamp_us: u64, interface: &str, frame: &Frame, d: &DecodedFrame) -> Value {
    any_line(timestamp_us, interface, frame.id(), frame.data(), d, |m| {
        m.insert("remote".into(), json!(frame.is_remote()));
        m.insert("dlc".into(), json!(frame.dlc()));
    })
}

/// [`line`] of a CAN FD frame the decoder read (a PDO of up to 64 bytes): `"fd": true`, its
/// `brs` flag, no `remote`.
pub fn line_fd(timestamp_us: u64, interface: &str, frame: &FdFrame, d: &DecodedFrame) -> Value {
    any_line(timestamp_us, interface, frame.id(), frame.data(), d, |m| {
        m.insert("fd".into(), json!(true));
        m.insert("brs".into(), json!(frame.brs()));
    })
}

/// What a classic and a CAN FD frame's lines share, with `own` adding the kind's fields.
fn any_line(
    timestamp_us: u64,
    interface: &str,
    id: Id,
    data: &[u8],
    d: &DecodedFrame,
    own: impl FnOnce(&mut Map<String, Value>),
) -> Value {
    let mut m = Map::new();
    m.insert("time".into(), json!(time_text(timestamp_us)));
    m.insert("timestamp_us".into(), json!(timestamp_us));
    m.insert("interface".into(), json!(interface));
    m.insert("id".into(), json!(id.raw()));
    m.insert("extended".into(), json!(id.is_extended()));
    own(&mut m);
    m.insert("data".into(), json!(hex(data)));
    m.insert("kind".into(), json!(d.kind().name()));
    m.insert("node".into(), json!(d.node().map(|n| n.raw())));
    m.insert("text".into(), json!(d.to_string()));
    fields(&mut m, d);
    Value::Object(m)
}

fn nmt(m: &mut Map<String, Value>, command: NmtCommand, target: NmtTarget) {
    m.insert("command".into(), json!(command.to_string()));
    let t = match target {
        NmtTarget::All => json!("all"),
        NmtTarget::Node(n) => json!(n.raw()),
    };
    m.insert("target".into(), t);
}

fn emcy(m: &mut Map<String, Value>, e: &EmcyMessage) {
    m.insert("code".into(), json!(e.code));
    m.insert("code_text".into(), json!(e.text()));
    m.insert("register".into(), json!(e.register));
    m.insert("manufacturer".into(), json!(hex(&e.data)));
}

fn state(m: &mut Map<String, Value>, s: NmtState, toggle: bool) {
    m.insert("state".into(), json!(s.to_string()));
    m.insert(
        "boot_up".into(),
        json!(s == NmtState::Initialising && !toggle),
    );
    m.insert("toggle".into(), json!(toggle));
}

fn value(v: FieldValue) -> Value {
    match v {
        FieldValue::Bool(b) => json!(b),
        FieldValue::Unsigned(u) => json!(u),
        FieldValue::Signed(i) => json!(i),
        FieldValue::Real(r) => json!(r),
    }
}

fn pdo(m: &mut Map<String, Value>, p: &PdoInfo) {
    m.insert("pdo".into(), json!(p.label()));
    let values: Vec<Value> = p
        .fields
        .iter()
        .map(|f| json!({"name": f.name, "index": f.index, "sub": f.sub, "value": value(f.value)}))
        .collect();
    m.insert("values".into(), Value::Array(values));
}

fn sdo(m: &mut Map<String, Value>, s: &SdoInfo) {
    let side = match s.side {
        SdoSide::Client => "client",
        SdoSide::Server => "server",
    };
    m.insert("side".into(), json!(side));
    m.insert("service".into(), json!(s.service.map(|v| v.to_string())));
    m.insert("index".into(), json!(s.object.map(|o| o.0)));
    m.insert("sub".into(), json!(s.object.map(|o| o.1)));
    let (step, extra) = match s.step {
        SdoStep::Request => ("request", json!({})),
        SdoStep::Value { data, len } => {
            let n = len.map_or(4, |l| usize::from(l).clamp(1, 4));
            let v = data[..n]
                .iter()
                .rev()
                .fold(0u64, |a, b| a << 8 | u64::from(*b));
            ("value", json!({"value": v, "bytes": hex(&data[..n])}))
        }
        SdoStep::Segmented { size } => ("segmented", json!({"size": size})),
        SdoStep::Accepted => ("accepted", json!({})),
        SdoStep::Segment {
            number,
            len,
            last,
            total,
        } => (
            "segment",
            json!({"segment": number, "bytes": len, "last": last, "total": total}),
        ),
        SdoStep::SegmentAck { number, toggle } => {
            ("segment_ack", json!({"segment": number, "toggle": toggle}))
        }
        SdoStep::BlockInit { size, blksize, crc } => (
            "block_init",
            json!({"size": size, "block_size": blksize, "crc": crc}),
        ),
        SdoStep::BlockStart => ("block_start", json!({})),
        SdoStep::BlockSegment {
            seqno,
            number,
            last,
        } => (
            "block_segment",
            json!({"sequence": seqno, "segment": number, "last": last}),
        ),
        SdoStep::BlockAck { ackseq, blksize } => (
            "block_ack",
            json!({"ack_sequence": ackseq, "block_size": blksize}),
        ),
        SdoStep::BlockEnd { unused, crc, total } => (
            "block_end",
            json!({"unused": unused, "crc": crc, "total": total}),
        ),
        SdoStep::BlockEndConfirmed => ("block_end_confirmed", json!({})),
        SdoStep::Abort { code } => (
            "abort",
            json!({"abort_code": code.0, "abort_text": code.description()}),
        ),
        SdoStep::BadCommand { byte } => ("bad_command", json!({"command_byte": byte})),
        // SdoStep may grow: its text still says what it is.
        _ => ("other", json!({})),
    };
    m.insert("step".into(), json!(step));
    if let Value::Object(e) = extra {
        m.extend(e);
    }
}

fn fields(m: &mut Map<String, Value>, d: &DecodedFrame) {
    match d {
        DecodedFrame::Nmt { command, target } => nmt(m, *command, *target),
        DecodedFrame::Sync { counter } => {
            m.insert("counter".into(), json!(counter));
        }
        DecodedFrame::Time { days, millis } => {
            m.insert("days".into(), json!(days));
            m.insert("millis".into(), json!(millis));
        }
        DecodedFrame::Emcy { emcy: e, .. } => emcy(m, e),
        DecodedFrame::Heartbeat {
            state: s, toggle, ..
        } => state(m, *s, *toggle),
        DecodedFrame::Sdo { sdo: s, .. } => sdo(m, s),
        DecodedFrame::Pdo(p) => pdo(m, p),
        DecodedFrame::Lss { request, cs, data } => {
            m.insert("request".into(), json!(request));
            m.insert("cs".into(), json!(cs));
            m.insert("lss_data".into(), json!(hex(data)));
        }
        DecodedFrame::FlyingMaster { frame, rank } => {
            m.insert("frame".into(), json!(frame.to_string()));
            m.insert("priority".into(), json!(rank.map(|r| r.0)));
            m.insert("master".into(), json!(rank.map(|r| r.1.raw())));
        }
        DecodedFrame::Railway {
            function,
            address,
            payload,
            ..
        } => {
            m.insert("function".into(), json!(function.to_string()));
            m.insert("function_code".into(), json!(function.code()));
            m.insert("address".into(), json!(address.to_string()));
            m.insert("port".into(), json!(address.port()));
            railway(m, payload);
        }
        DecodedFrame::Malformed { problem, .. } => {
            m.insert("problem".into(), json!(problem));
        }
        _ => {}
    }
}

fn railway(m: &mut Map<String, Value>, p: &RailPayload) {
    match p {
        RailPayload::Nmt { command, target } => nmt(m, *command, *target),
        RailPayload::Emcy(e) => emcy(m, e),
        RailPayload::State { state: s, toggle } => state(m, *s, *toggle),
        RailPayload::Sdo(s) => sdo(m, s),
        RailPayload::Process(p) => {
            m.insert("index".into(), json!(p.index()));
            m.insert("sub".into(), json!(p.sub()));
            m.insert("value".into(), json!(hex(p.data())));
        }
        RailPayload::Unmapped(d) => {
            m.insert("value".into(), json!(hex(d)));
        }
        _ => {}
    }
}

/// `1700000000.000200`: seconds and microseconds since the Unix epoch, as candump writes them.
pub fn time_text(timestamp_us: u64) -> String {
    format!(
        "{}.{:06}",
        timestamp_us / 1_000_000,
        timestamp_us % 1_000_000
    )
}

/// The identifier as candump writes it: three hex digits, or eight for 29 bits.
pub fn id_text(id: Id) -> String {
    match id {
        Id::Standard(r) => format!("{r:03X}"),
        Id::Extended(r) => format!("{r:08X}"),
    }
}
