//! USDO (CANopen FD): the decoder, a server and a client fed arbitrary frames and time steps.
//! The decoder answers any bytes with a message or an error; a message it returns encodes and
//! decodes to itself. The server (two sessions, a small dictionary with a value, a read-only
//! entry and a domain) and the client (a segmented read and a segmented write started while
//! the input lasts) never panic, never hold more than their limits, never queue without
//! bound, and every client transfer ends (result or abort) once its timeout has passed.
#![no_main]

use duocan::cia1301::usdo::codec::Usdo;
use duocan::cia1301::usdo::{UsdoClient, UsdoServer};
use duocan::od::abort::AbortCode;
use duocan::od::{Access, DataType, DynamicDictionary, Entry, ObjectAccess, ObjectDef, ObjectDictionary};
use duocan::{Duration, FdFrame, Id, Instant, NodeId};
use libfuzzer_sys::fuzz_target;

const LIMIT: usize = 2048;

struct Od(DynamicDictionary);

impl ObjectAccess for Od {
    fn entry(&self, index: u16, sub: u8) -> Result<Entry<'_>, AbortCode> {
        self.0.get(index, sub)
    }
    fn read(&self, index: u16, sub: u8) -> Result<&[u8], AbortCode> {
        Ok(self.0.get(index, sub)?.data)
    }
    fn write(&mut self, _: Instant, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        if !self.0.get(index, sub)?.def.access.writable() {
            return Err(AbortCode::READ_ONLY);
        }
        self.0.store(index, sub, data)
    }
}

fuzz_target!(|data: &[u8]| {
    // The decoder alone, on the whole input.
    if let Ok(u) = Usdo::decode(data) {
        let f = u.encode(Id::Standard(0x601));
        assert_eq!(Usdo::decode(f.data()), Ok(u));
    }

    let mut d = DynamicDictionary::new(5);
    d.insert_all(&[
        ObjectDef::u32(0x2000, 0, Access::Rw, 7),
        ObjectDef::u32(0x2002, 0, Access::Ro, 9),
        ObjectDef::bytes(0x2001, 0, DataType::Domain, 1024),
    ])
    .unwrap();
    let mut od = Od(d);
    let timeout = Duration::from_millis(100);
    let mut server: UsdoServer<duocan::sdo::HeapBuffer, 2> =
        UsdoServer::new(NodeId::must(5), timeout, LIMIT);
    let mut client: UsdoClient = UsdoClient::new(NodeId::must(1), LIMIT);
    let mut now = Instant::ZERO;
    let mut started_at = None;
    // Input, one record at a time: a control byte (bit 7: to the client, else to the server;
    // bit 6: a time step of the low bits in ms first; bits 0-2 pick the identifier), a length
    // byte, then the frame's data.
    let mut rest = data;
    let mut k = 0u32;
    while let [ctl, len, tail @ ..] = rest {
        k += 1;
        let n = usize::from(*len).min(64).min(tail.len());
        let (bytes, next) = tail.split_at(n);
        rest = next;
        if ctl & 0x40 != 0 {
            now += Duration::from_millis(u64::from(ctl & 0x3F) * 7);
        }
        let _ = client.poll_event();
        if !client.is_busy() {
            let r = if k % 2 == 0 {
                client.upload(now, NodeId::must(5), 0x2001, 0, timeout)
            } else {
                client.download(now, NodeId::must(5), 0x2001, 0, 0, &[k as u8; 700], timeout)
            };
            if r.is_ok() {
                started_at = Some(now);
            }
        }
        let Ok(frame) = FdFrame::padded(Id::Standard(if ctl & 0x80 != 0 { 0x580 } else { 0x600 } + u16::from(ctl & 7)), bytes, 0xCC) else {
            continue;
        };
        if ctl & 0x80 != 0 {
            client.handle_frame(now, &frame);
        } else {
            let _ = server.handle_frame(now, &frame, &mut od);
        }
        // The two also talk to each other, so that deep states are reached.
        while let Some(f) = client.poll_transmit() {
            let _ = server.handle_frame(now, &f, &mut od);
        }
        while let Some(f) = server.poll_transmit() {
            client.handle_frame(now, &f);
        }
        server.handle_timeout(now);
        client.handle_timeout(now);
        assert!(server.active() <= 2);
    }
    // The end of time: every transfer ends.
    let end = now + Duration::from_secs(3600);
    client.handle_timeout(end);
    server.handle_timeout(end);
    assert!(!client.is_busy());
    assert_eq!(server.active(), 0);
    assert!(server.poll_timeout().is_none() && client.poll_timeout().is_none());
    let _ = started_at;
});
