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

mod refusals;
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

fn from_client(session: u8, msg: Msg) -> FdFrame {
    Usdo {
        dest: SERVER.raw(),
        session,
        msg,
    }
    .encode(request_id(CLIENT))
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
