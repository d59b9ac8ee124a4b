//! What the machine-level fuzz targets share: a clock that also goes backwards and jumps,
//! SDO answers shaped after the request they answer (so the fuzzer gets past the first
//! multiplexer check), and drain/expire loops that assert bounded output and no livelock.
#![allow(dead_code)]

use duocan::machine::{Device, ErrorCause, PortStatus};
use duocan::{Duration, Frame, Id, Instant};

/// Most frames, requests or events one input step may cause.
pub const MAX_PER_STEP: usize = 4096;

/// Moves `now` by what `step` says: small and medium steps forward, a jump of a minute or an
/// hour, back in time, or to the end of time (the clock contract: time may misbehave).
pub fn advance(now: Instant, step: u8) -> Instant {
    let k = u64::from(step & 0x3F);
    match step >> 6 {
        0 => now + Duration::from_micros(k * 100),
        1 => now + Duration::from_millis(k * 10),
        2 if k == 63 => now + Duration::from_secs(3600),
        2 => now + Duration::from_millis(k * 1000),
        _ if k == 63 => Instant::MAX,
        _ => now.saturating_sub(Duration::from_millis(k * 10)),
    }
}

/// The next time for `b` if it stands for a misbehaving clock (a step back, an hour ahead, the
/// end of time); any other byte is left to the target's own time step.
pub fn misbehave(now: Instant, b: u8) -> Option<Instant> {
    match b {
        0xFF => Some(Instant::MAX),
        0xFE => Some(now + Duration::from_secs(3600)),
        0xF0..=0xFD => Some(now - Duration::from_millis(u64::from(b & 0x0F) * 100)),
        _ => None,
    }
}

/// A time well inside the clock's range, for the checks a target makes at its end ("long after
/// every timeout"): from the end of time the clock comes back.
pub fn sane(now: Instant) -> Instant {
    now.min(Instant::from_secs(1_000_000))
}

const CAUSES: [ErrorCause; 6] = [
    ErrorCause::BusOff,
    ErrorCause::ErrorPassive,
    ErrorCause::NoAck,
    ErrorCause::InterfaceDown,
    ErrorCause::TxTimeout,
    ErrorCause::Restarted,
];

/// A port status a driver could report.
pub fn port_status(kind: u8, cause: u8) -> PortStatus {
    let cause = CAUSES[usize::from(cause) % CAUSES.len()];
    match kind % 5 {
        0 => PortStatus::TxOk,
        1 => PortStatus::TxFailed(cause),
        2 => PortStatus::Error(cause),
        3 => PortStatus::Down(cause),
        _ => PortStatus::Up,
    }
}

/// An SDO server's answer to `request` (the client's last frame to it, if any): `kind` picks the
/// command specifier, `d` the value. The multiplexer is the request's, so the answer reaches the
/// code behind the multiplexer check; a third of the kinds give the answer the request expects
/// (with the value from `d`), so a boot process gets past its first steps.
pub fn sdo_answer(request: Option<[u8; 8]>, kind: u8, d: [u8; 8]) -> [u8; 8] {
    let req = request.unwrap_or([0; 8]);
    let mut a = d;
    let mux = |a: &mut [u8; 8]| a[1..4].copy_from_slice(&req[1..4]);
    match kind % 16 {
        // Expedited upload with 1–4 bytes (size indicated), or without size.
        k @ 0..=3 => {
            a[0] = 0x43 | ((3 - k) << 2);
            mux(&mut a);
        }
        4 => {
            a[0] = 0x42;
            mux(&mut a);
        }
        // Download acknowledged.
        5 => {
            a = [0x60, 0, 0, 0, 0, 0, 0, 0];
            mux(&mut a);
        }
        // Abort with the value's code.
        6 => {
            a[0] = 0x80;
            mux(&mut a);
        }
        // Segmented upload initiate with a size.
        7 => {
            a[0] = 0x41;
            mux(&mut a);
        }
        // A segment with the request's toggle, or a block answer.
        8 => a[0] = (d[0] & 0x0F) | (req[0] & 0x10),
        9 => {
            a[0] = 0xC0 | (d[0] & 0x07);
            mux(&mut a);
        }
        10 => {}
        // What the request expects.
        _ => match req[0] >> 5 {
            // Initiate download: acknowledged.
            1 => {
                a = [0x60, 0, 0, 0, 0, 0, 0, 0];
                mux(&mut a);
            }
            // Initiate upload: four bytes, expedited.
            2 => {
                a[0] = 0x43;
                mux(&mut a);
            }
            // Download segment: acknowledged with its toggle.
            0 => a = [0x20 | (req[0] & 0x10), 0, 0, 0, 0, 0, 0, 0],
            // Upload segment: the last one, with its toggle.
            3 => a[0] = (req[0] & 0x10) | 0x01,
            _ => {}
        },
    }
    a
}

/// SDO requests a client sent, by node: the last one to each of 0x601–0x67F.
pub struct Requests([Option<[u8; 8]>; 128]);

impl Requests {
    pub fn new() -> Self {
        Requests([None; 128])
    }
    /// Notes `f` if it is an SDO request on the predefined channel.
    pub fn note(&mut self, f: &Frame) {
        if let Id::Standard(id @ 0x601..=0x67F) = f.id() {
            if f.data().len() == 8 && !f.is_remote() {
                let mut b = [0u8; 8];
                b.copy_from_slice(f.data());
                self.0[usize::from(id - 0x600)] = Some(b);
            }
        }
    }
    pub fn last(&self, node: u8) -> Option<[u8; 8]> {
        self.0[usize::from(node & 0x7F)]
    }
}

/// Takes everything a device has queued, noting its SDO requests; panics past the bound.
pub fn drain<D: Device>(d: &mut D, req: &mut Requests) {
    let mut k = 0;
    while let Some((_, f)) = d.poll_transmit() {
        req.note(&f);
        k += 1;
        assert!(k <= MAX_PER_STEP, "unbounded transmit queue");
    }
    let mut k = 0;
    while d.poll_port_request().is_some() {
        k += 1;
        assert!(k <= MAX_PER_STEP, "unbounded port requests");
    }
    let mut k = 0;
    while d.poll_event().is_some() {
        k += 1;
        assert!(k <= MAX_PER_STEP, "unbounded event queue");
    }
}

/// Handles every deadline due at `now`; a device whose deadline stays due is livelocked.
pub fn expire<D: Device>(d: &mut D, now: Instant, req: &mut Requests) {
    for _ in 0..64 {
        match d.poll_timeout() {
            Some(t) if t <= now => d.handle_timeout(now),
            _ => return,
        }
        drain(d, req);
    }
    panic!(
        "deadline {:?} still due at {now:?} after 64 rounds",
        d.poll_timeout()
    );
}

/// A data frame on a standard identifier with the first `dlc % 9` bytes of `d`.
pub fn std_frame(id: u16, dlc: u8, d: &[u8; 8]) -> Frame {
    Frame::new(Id::Standard(id & 0x7FF), &d[..usize::from(dlc % 9)])
        .unwrap_or_else(|_| Frame::from_array(Id::Standard(id & 0x7FF), [0; 0]))
}
