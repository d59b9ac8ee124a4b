//! A USDO client and server exchanging frames in memory, one millisecond a frame, with every
//! deadline exact.

use super::codec::{Msg, Usdo, UsdoPayload, BROADCAST};
use super::*;
use crate::frame::fd::FdFrame;
use crate::frame::instant::{Duration, Instant};
use crate::od::abort::AbortCode;
use crate::od::{
    Access, DataType, DynamicDictionary, Entry, ObjectAccess, ObjectDef, ObjectDictionary,
};
use proptest::prelude::*;
use std::vec::Vec;

const VALUE: u16 = 0x2000;
const DOMAIN: u16 = 0x2001;
const RO: u16 = 0x2002;
const CLIENT: NodeId = NodeId::must(1);
const SERVER: NodeId = NodeId::must(5);
const T: Duration = Duration::from_millis(100);
const MS: Duration = Duration::from_millis(1);

/// A dictionary as a bus client reaches it: access rights checked.
struct Od(DynamicDictionary);

impl ObjectAccess for Od {
    fn entry(&self, index: u16, sub: u8) -> Result<Entry<'_>, AbortCode> {
        self.0.get(index, sub)
    }
    fn read(&self, index: u16, sub: u8) -> Result<&[u8], AbortCode> {
        let e = self.0.get(index, sub)?;
        if !e.def.access.readable() {
            return Err(AbortCode::WRITE_ONLY);
        }
        Ok(e.data)
    }
    fn write(&mut self, _: Instant, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        if !self.0.get(index, sub)?.def.access.writable() {
            return Err(AbortCode::READ_ONLY);
        }
        self.0.store(index, sub, data)
    }
}

fn od() -> Od {
    let mut d = DynamicDictionary::new(SERVER.raw());
    d.insert_all(&[
        ObjectDef::u32(VALUE, 0, Access::Rw, 7),
        ObjectDef::bytes(DOMAIN, 0, DataType::Domain, 4096),
        ObjectDef::u32(RO, 0, Access::Ro, 9),
    ])
    .unwrap();
    Od(d)
}

struct Net {
    now: Instant,
    client: UsdoClient,
    server: UsdoServer,
    od: Od,
    /// Frames the bus loses: given each frame and whether the client sent it.
    lose: fn(&FdFrame, bool, usize) -> bool,
    /// Frames put on the bus: (when it arrived, sent by the client, the frame).
    log: Vec<(Instant, bool, FdFrame)>,
}

impl Net {
    fn new() -> Net {
        Net {
            now: Instant::ZERO,
            client: UsdoClient::new(CLIENT, 4096),
            server: UsdoServer::new(SERVER, T, 4096),
            od: od(),
            lose: |_, _, _| false,
            log: Vec::new(),
        }
    }

    /// Runs until the client's transfer ends: each frame takes a millisecond; with none on
    /// the bus, time jumps to the next deadline.
    fn run(&mut self) -> UsdoEvent<crate::cia301::sdo::DefaultBuffer> {
        loop {
            if let Some(e) = self.client.poll_event() {
                return e;
            }
            let mut moved = false;
            while let Some(f) = self.client.poll_transmit() {
                moved = true;
                self.now += MS;
                self.log.push((self.now, true, f));
                if !(self.lose)(&f, true, self.log.len()) {
                    let _ = self.server.handle_frame(self.now, &f, &mut self.od);
                }
            }
            while let Some(f) = self.server.poll_transmit() {
                moved = true;
                self.now += MS;
                self.log.push((self.now, false, f));
                if !(self.lose)(&f, false, self.log.len()) {
                    self.client.handle_frame(self.now, &f);
                }
            }
            if !moved {
                let next = [self.client.poll_timeout(), self.server.poll_timeout()]
                    .into_iter()
                    .flatten()
                    .min()
                    .expect("a transfer that waits has a deadline");
                self.now = self.now.max(next);
                self.client.handle_timeout(self.now);
                self.server.handle_timeout(self.now);
            }
        }
    }

    fn write(
        &mut self,
        index: u16,
        ty: u8,
        data: &[u8],
    ) -> UsdoEvent<crate::cia301::sdo::DefaultBuffer> {
        self.client
            .download(self.now, SERVER, index, 0, ty, data, T)
            .unwrap();
        self.run()
    }

    fn read(&mut self, index: u16) -> UsdoEvent<crate::cia301::sdo::DefaultBuffer> {
        self.client.upload(self.now, SERVER, index, 0, T).unwrap();
        self.run()
    }
}

fn pattern(len: usize) -> Vec<u8> {
    (0..len).map(|i| (i * 31 % 251) as u8).collect()
}

fn code(e: &UsdoEvent<crate::cia301::sdo::DefaultBuffer>) -> Option<AbortCode> {
    e.result.as_ref().err().and_then(|e| e.code())
}

#[test]
fn fifty_six_bytes_go_in_one_frame_each_way() {
    let mut net = Net::new();
    let data = pattern(56);
    let e = net.write(DOMAIN, DataType::Domain as u8, &data);
    assert!(e.result.is_ok());
    assert_eq!((e.at, net.log.len()), (Instant::from_millis(2), 2));
    assert_eq!(net.log[0].2.len(), 64);
    let e = net.read(DOMAIN);
    assert_eq!(e.data(), Some(&data[..]));
    assert_eq!((e.at, net.log.len()), (Instant::from_millis(4), 4));
}

#[test]
fn a_kibibyte_goes_in_eighteen_segments_each_way() {
    let mut net = Net::new();
    let data = pattern(1024);
    let e = net.write(DOMAIN, 0, &data);
    assert!(e.result.is_ok(), "{:?}", e.result);
    // Initiate and 18 segments (17 of 60 bytes, one of 4), each answered.
    assert_eq!((e.at, net.log.len()), (Instant::from_millis(38), 38));
    assert_eq!(net.od.read(DOMAIN, 0).unwrap(), &data[..]);
    let e = net.read(DOMAIN);
    assert_eq!(e.data(), Some(&data[..]));
    assert_eq!(e.at, Instant::from_millis(76));
    let s = net.server.stats();
    assert_eq!((s.completed, s.aborted, net.server.active()), (2, 0, 0));
}

#[test]
fn no_such_object_wrong_length_and_read_only_are_the_servers_aborts() {
    let mut net = Net::new();
    let e = net.read(0x3000);
    assert_eq!(code(&e), Some(AbortCode::NO_OBJECT));
    assert!(matches!(
        e.result.unwrap_err().kind,
        UsdoErrorKind::Server(_)
    ));
    // A segmented write of 100 bytes to a 4-byte entry is refused at its start.
    let e = net.write(VALUE, 0, &pattern(100));
    assert_eq!(code(&e), Some(AbortCode::LENGTH_TOO_HIGH));
    // The data type announced is not the entry's.
    let e = net.write(VALUE, DataType::Unsigned16 as u8, &[1, 2]);
    assert_eq!(code(&e), Some(AbortCode::TYPE_MISMATCH));
    let e = net.write(RO, 0, &[1, 2, 3, 4]);
    assert_eq!(code(&e), Some(AbortCode::READ_ONLY));
    assert_eq!(net.od.read(VALUE, 0).unwrap(), 7u32.to_le_bytes());
}

#[test]
fn a_silent_server_times_out_on_both_sides_at_exact_deadlines() {
    let mut net = Net::new();
    // The answer to the third segment (the 8th frame on the bus) is lost.
    net.lose = |_, client, n| !client && n == 8;
    let e = net.write(DOMAIN, 0, &pattern(600));
    // The client sent segment 3 at 7 ms, its answer went at 8 ms: the client waited since the
    // answer to segment 2 at 6 ms; the server since segment 3 at 7 ms.
    assert_eq!(code(&e), Some(AbortCode::TIMEOUT));
    assert_eq!(e.at, Instant::from_millis(106));
    // The client's abort reaches the server at 107 ms, before its own deadline is handled: it
    // drops its side without an answer.
    let abort = net.client.poll_transmit().unwrap();
    assert_eq!(abort.data()[1], 0x80);
    assert_eq!(net.server.poll_timeout(), Some(Instant::from_millis(107)));
    net.server
        .handle_frame(Instant::from_millis(107), &abort, &mut net.od)
        .unwrap();
    net.server.handle_timeout(Instant::from_millis(107));
    assert!(net.server.poll_transmit().is_none());
    assert_eq!(
        (net.server.active(), net.server.stats().client_aborts),
        (0, 1)
    );
    assert_eq!(net.od.read(DOMAIN, 0).unwrap(), &[] as &[u8]);

    // The server's own timeout: a client that falls silent after the initiate.
    let mut net = Net::new();
    net.client
        .download(Instant::ZERO, SERVER, DOMAIN, 0, 0, &pattern(200), T)
        .unwrap();
    let init = net.client.poll_transmit().unwrap();
    net.server
        .handle_frame(Instant::from_millis(1), &init, &mut net.od)
        .unwrap();
    let _ack = net.server.poll_transmit().unwrap();
    assert_eq!(net.server.poll_timeout(), Some(Instant::from_millis(101)));
    net.server.handle_timeout(Instant::from_millis(101));
    let abort = Usdo::decode(net.server.poll_transmit().unwrap().data()).unwrap();
    assert_eq!(
        abort.msg,
        Msg::Abort {
            index: DOMAIN,
            sub: 0,
            code: UsdoAbort::from_code(AbortCode::TIMEOUT)
        }
    );
    assert_eq!((abort.dest, abort.session), (CLIENT.raw(), 1));
}

fn from_client(session: u8, msg: Msg) -> FdFrame {
    Usdo {
        dest: SERVER.raw(),
        session,
        msg,
    }
    .encode(request_id(CLIENT))
}

#[test]
fn a_segment_with_the_wrong_toggle_is_aborted() {
    let mut net = Net::new();
    net.client
        .download(Instant::ZERO, SERVER, DOMAIN, 0, 0, &pattern(200), T)
        .unwrap();
    let init = net.client.poll_transmit().unwrap();
    net.server
        .handle_frame(Instant::from_millis(1), &init, &mut net.od)
        .unwrap();
    let _ack = net.server.poll_transmit().unwrap();
    let data = UsdoPayload::new(&[0; 60]).unwrap();
    let bad = from_client(
        1,
        Msg::DownloadSegment {
            toggle: true,
            last: false,
            data,
        },
    );
    net.server
        .handle_frame(Instant::from_millis(2), &bad, &mut net.od)
        .unwrap();
    let answer = net.server.poll_transmit().unwrap();
    net.client.handle_frame(Instant::from_millis(3), &answer);
    let e = net.client.poll_event().unwrap();
    assert_eq!(code(&e), Some(AbortCode::TOGGLE_BIT));
    assert_eq!(net.server.active(), 0);
}

#[test]
fn a_second_session_of_the_same_client_is_busy_and_the_first_goes_on() {
    let mut net = Net::new();
    net.client
        .download(Instant::ZERO, SERVER, DOMAIN, 0, 0, &pattern(200), T)
        .unwrap();
    let init = net.client.poll_transmit().unwrap();
    net.server
        .handle_frame(Instant::from_millis(1), &init, &mut net.od)
        .unwrap();
    let ack = net.server.poll_transmit().unwrap();
    let other = from_client(
        42,
        Msg::UploadInitiate {
            index: VALUE,
            sub: 0,
        },
    );
    net.server
        .handle_frame(Instant::from_millis(2), &other, &mut net.od)
        .unwrap();
    let busy = Usdo::decode(net.server.poll_transmit().unwrap().data()).unwrap();
    assert_eq!(busy.session, 42);
    assert_eq!(
        busy.msg,
        Msg::Abort {
            index: VALUE,
            sub: 0,
            code: UsdoAbort::from_code(AbortCode::NO_RESOURCE)
        }
    );
    // The busy abort (session 42) is not the client's: it ignores it and goes on.
    net.client
        .handle_frame(Instant::from_millis(3), &net_frame(&busy));
    net.client.handle_frame(Instant::from_millis(3), &ack);
    net.now = Instant::from_millis(3);
    let e = net.run();
    assert!(e.result.is_ok());
    assert_eq!(net.client.stats().ignored, 1);
    assert_eq!(net.server.stats().busy, 1);
}

#[test]
fn a_second_copy_of_a_segment_is_ignored_on_both_sides() {
    let mut net = Net::new();
    net.client
        .download(Instant::ZERO, SERVER, DOMAIN, 0, 0, &pattern(200), T)
        .unwrap();
    let init = net.client.poll_transmit().unwrap();
    net.server
        .handle_frame(Instant::from_millis(1), &init, &mut net.od)
        .unwrap();
    net.client.handle_frame(
        Instant::from_millis(2),
        &net.server.poll_transmit().unwrap(),
    );
    let seg = net.client.poll_transmit().unwrap();
    for at in [3, 4] {
        net.server
            .handle_frame(Instant::from_millis(at), &seg, &mut net.od)
            .unwrap();
    }
    let ack = net.server.poll_transmit().unwrap();
    assert!(net.server.poll_transmit().is_none());
    for at in [5, 6] {
        net.client.handle_frame(Instant::from_millis(at), &ack);
    }
    net.now = Instant::from_millis(6);
    let e = net.run();
    assert!(e.result.is_ok(), "{:?}", e.result);
    assert_eq!(net.od.read(DOMAIN, 0).unwrap(), &pattern(200)[..]);
    assert_eq!(
        (net.server.stats().repeats, net.client.stats().repeats),
        (1, 1)
    );
}

fn net_frame(u: &Usdo) -> FdFrame {
    u.encode(answer_id(SERVER))
}

#[test]
fn a_broadcast_write_is_answered_by_every_server_a_broadcast_segmented_one_refused() {
    let mut servers: Vec<(UsdoServer, Od)> = [5u8, 6]
        .iter()
        .map(|&n| (UsdoServer::new(NodeId::must(n), T, 1024), od()))
        .collect();
    let data = UsdoPayload::new(&[1, 0, 0, 0]).unwrap();
    let msg = Msg::DownloadExpedited {
        index: VALUE,
        sub: 0,
        data_type: 7,
        data,
    };
    let f = Usdo {
        dest: BROADCAST,
        session: 3,
        msg,
    }
    .encode(request_id(CLIENT));
    let init = Msg::DownloadInitiate {
        index: DOMAIN,
        sub: 0,
        data_type: 0,
        size: 100,
    };
    let g = Usdo {
        dest: BROADCAST,
        session: 4,
        msg: init,
    }
    .encode(request_id(CLIENT));
    for (s, od) in &mut servers {
        s.handle_frame(Instant::ZERO, &f, od).unwrap();
        let a = s.poll_transmit().unwrap();
        assert_eq!(a.id(), answer_id(s.node()));
        assert_eq!(
            Usdo::decode(a.data()).unwrap().msg,
            Msg::DownloadAck {
                index: VALUE,
                sub: 0
            }
        );
        assert_eq!(od.read(VALUE, 0).unwrap(), [1, 0, 0, 0]);
        s.handle_frame(Instant::ZERO, &g, od).unwrap();
        let a = Usdo::decode(s.poll_transmit().unwrap().data()).unwrap();
        assert!(
            matches!(a.msg, Msg::Abort { code, .. } if code.code() == Some(AbortCode::UNSUPPORTED_ACCESS))
        );
    }
    // A request for another server is not this one's.
    let other = Usdo {
        dest: 9,
        session: 3,
        msg,
    }
    .encode(request_id(CLIENT));
    let (s, od) = &mut servers[0];
    s.handle_frame(Instant::ZERO, &other, od).unwrap();
    assert!(s.poll_transmit().is_none());
}

#[test]
fn garbage_is_refused_without_panic() {
    let mut net = Net::new();
    let f = FdFrame::new(
        request_id(CLIENT),
        &[SERVER.raw(), 0x77, 1, 0, 0x20, 0, 0, 0],
    )
    .unwrap();
    assert!(net
        .server
        .handle_frame(Instant::ZERO, &f, &mut net.od)
        .is_err());
    let a = Usdo::decode(net.server.poll_transmit().unwrap().data()).unwrap();
    assert!(
        matches!(a.msg, Msg::Abort { code, .. } if code.code() == Some(AbortCode::COMMAND_SPECIFIER))
    );
    let f = FdFrame::new(request_id(CLIENT), &[SERVER.raw()]).unwrap();
    assert!(net
        .server
        .handle_frame(Instant::ZERO, &f, &mut net.od)
        .is_err());
    assert!(net.server.poll_transmit().is_none());
    assert_eq!(net.server.stats().malformed, 2);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    #[test]
    fn any_size_up_to_2_kib_round_trips(len in 0usize..=2048, seed in any::<u8>()) {
        let mut net = Net::new();
        let data: Vec<u8> = (0..len).map(|i| (i as u8).wrapping_mul(seed | 1)).collect();
        let e = net.write(DOMAIN, 0, &data);
        prop_assert!(e.result.is_ok());
        let e = net.read(DOMAIN);
        prop_assert_eq!(e.data(), Some(&data[..]));
        // Frames on the bus: one exchange up to 56 bytes, else the initiate and a segment
        // per 60 bytes, each answered; both ways.
        let exchanges = if len <= 56 { 1 } else { 1 + len.div_ceil(60) };
        prop_assert_eq!(net.log.len(), 4 * exchanges);
        prop_assert_eq!(e.at, Instant::from_millis(4 * exchanges as u64));
    }
}
