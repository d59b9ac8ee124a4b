//! The master under random input: frames of any kind (boot-ups, heartbeats, SDO answers right,
//! wrong or garbled, NMT, noise), time jumps ahead, steps back and the end of time (the clock
//! contract), and application calls in any order. It never panics, never spins on a deadline, its
//! queues stay bounded, and a standby never sends NMT, SYNC or SDO requests.

use crate::net::*;
use duocan::cia302::pdo_config::PdoConfig;
use duocan::master::{
    Master, MasterConfig, MasterEventKind as K, NmtStartup, SlaveConfig, StartPolicy,
};
use duocan::od::{comm, DynamicDictionary};
use duocan::pdo::MapEntry;
use duocan::sdo::codec::{Init, Request, Response};
use duocan::{
    AbortCode, CobId, Duration, Frame, Id, Instant, Machine, NmtCommand, NmtTarget, NodeId,
};
use proptest::prelude::*;

const SLAVES: std::ops::RangeInclusive<u8> = 2..=9;

#[derive(Clone, Debug)]
enum Op {
    /// Any frame at all.
    Noise {
        id: u16,
        data: Vec<u8>,
        rtr: bool,
    },
    BootUp(u8),
    Heartbeat(u8, u8),
    /// Answer the last request to the node: correctly (identity as expected or not), with an
    /// abort, or with a garbled frame.
    Answer {
        node: u8,
        how: u8,
    },
    /// Every slave answers every request correctly, this many rounds (slaves at work).
    Respond(u8),
    Advance(u32),
    /// The caller's clock steps back this many µs; the driver reports it with `handle_timeout`.
    Back(u32),
    /// One `handle_timeout` an hour ahead, and time goes on from there.
    FarAhead,
    /// The clock reaches `Instant::MAX`.
    End,
    SetActive(bool),
    Nmt(u8, u8),
    BootSlave(u8),
    StartSlave(u8),
    AddSlave(u8),
    /// A 0x1F82 request NMT written locally.
    Request(u8, u8),
}

fn op() -> impl Strategy<Value = Op> {
    let node = 1u8..=12;
    prop_oneof![
        (
            0u16..0x800,
            prop::collection::vec(any::<u8>(), 0..=8),
            any::<bool>()
        )
            .prop_map(|(id, data, rtr)| Op::Noise { id, data, rtr }),
        node.clone().prop_map(Op::BootUp),
        (
            node.clone(),
            prop_oneof![Just(4u8), Just(5), Just(127), any::<u8>()]
        )
            .prop_map(|(n, s)| Op::Heartbeat(n, s)),
        (node.clone(), 0u8..8).prop_map(|(node, how)| Op::Answer { node, how }),
        (1u8..30).prop_map(Op::Respond),
        (1u8..30).prop_map(Op::Respond),
        (1u8..30).prop_map(Op::Respond),
        (0u32..400_000).prop_map(Op::Advance),
        (0u32..2_000_000).prop_map(Op::Back),
        Just(Op::FarAhead),
        Just(Op::End),
        any::<bool>().prop_map(Op::SetActive),
        (0u8..6, 0u8..=12).prop_map(|(c, n)| Op::Nmt(c, n)),
        node.clone().prop_map(Op::BootSlave),
        node.clone().prop_map(Op::StartSlave),
        node.clone().prop_map(Op::AddSlave),
        (0u8..=129, any::<u8>()).prop_map(|(s, v)| Op::Request(s, v)),
    ]
}

fn slave_cfg(id: u8, variant: u8) -> SlaveConfig {
    let mut s = SlaveConfig::new(NodeId::must(id))
        .identity(expected(id))
        .heartbeat(50, 120)
        .write_u16(APP, 1, 1);
    if variant & 1 != 0 {
        s = s.mandatory();
    }
    if variant & 2 != 0 {
        s = s.keep_alive();
    }
    if variant & 4 != 0 {
        s = s.start(StartPolicy::Application);
    }
    if variant & 8 != 0 {
        s = s.tpdo(
            1,
            PdoConfig::new(CobId(0x180 + id as u32), 254)
                .mapping(&[MapEntry::new(APP, 1, 16)])
                .unwrap(),
        );
    }
    s
}

fn build(variants: &[u8], start_all: bool, active: bool) -> Master<DynamicDictionary> {
    let mut net = MasterConfig::new()
        .boot_time_ms(300)
        .sdo_timeout(Duration::from_millis(50))
        .probe_interval(Duration::from_millis(200))
        .startup(if start_all {
            NmtStartup::MASTER.with(NmtStartup::START_ALL)
        } else {
            NmtStartup::MASTER
        });
    if !active {
        net = net.standby();
    }
    for (id, v) in SLAVES.zip(variants.iter().copied()) {
        net = net.slave(slave_cfg(id, v));
    }
    master_with(MASTER_ID, net, |od| {
        use duocan::od::ObjectDictionary;
        od.write(comm::SYNC_COB_ID, 0, &0x4000_0080u32.to_le_bytes())
            .unwrap();
        od.write(comm::SYNC_PERIOD, 0, &20_000u32.to_le_bytes())
            .unwrap();
    })
}

/// The answer a slave would give to `req`.
fn answer(node: u8, req: &Frame, how: u8) -> Frame {
    let id = Id::Standard(0x580 + node as u16);
    let Ok(d) = <[u8; 8]>::try_from(req.data()) else {
        return Frame::new(id, &[0x80]).unwrap();
    };
    let value = |index: u16, sub: u8| -> u32 {
        let e = expected(node);
        let right = match (index, sub) {
            (0x1000, _) => e.device_type,
            (0x1018, 1) => e.vendor,
            (0x1018, 2) => e.product,
            (0x1018, 3) => e.revision,
            (0x1018, 4) => e.serial,
            (0x1800, 1) => 0x180 + node as u32,
            _ => 0,
        };
        if how == 1 {
            right ^ 1
        } else {
            right
        }
    };
    let resp = match Request::decode(&d) {
        Ok(Request::InitiateUpload { index, sub }) if how <= 1 || how >= 5 => {
            Response::InitiateUpload {
                index,
                sub,
                init: Init::expedited(&value(index, sub).to_le_bytes()).unwrap(),
            }
        }
        Ok(Request::InitiateDownload { index, sub, .. }) if how <= 1 || how >= 5 => {
            Response::InitiateDownload { index, sub }
        }
        Ok(
            Request::InitiateUpload { index, sub } | Request::InitiateDownload { index, sub, .. },
        ) if how == 2 => Response::Abort {
            index,
            sub,
            code: AbortCode::READ_ONLY,
        },
        _ => return Frame::new(id, &[how, 0xFF, 0x12]).unwrap(),
    };
    Frame::from_array(id, resp.encode())
}

struct Harness {
    m: Master<DynamicDictionary>,
    now: Instant,
    last_request: [Option<Frame>; 128],
    active: bool,
}

impl Harness {
    /// Drains frames and events; checks what a standby may send.
    fn drain(&mut self, may_abort: bool) -> Result<(), TestCaseError> {
        while let Some(f) = self.m.poll_transmit() {
            let raw = f.id().raw() as u16;
            if !self.active {
                prop_assert!(raw != 0, "standby sent NMT {f:?}");
                prop_assert!(raw != 0x80, "standby sent SYNC");
                if (0x601..=0x67F).contains(&raw) {
                    prop_assert!(may_abort && f.data()[0] == 0x80, "standby sent SDO {f:?}");
                }
            }
            if (0x601..=0x67F).contains(&raw) {
                self.last_request[(raw - 0x600) as usize] = Some(f);
            }
        }
        let mut n = 0;
        while let Some(e) = self.m.poll_event() {
            n += 1;
            prop_assert!(e.at <= self.now);
            if let K::MandatoryMissing { nodes } = e.kind {
                prop_assert!(!nodes.is_empty());
            }
        }
        prop_assert!(n <= duocan::master::EVENT_QUEUE);
        let s = self.m.stats();
        prop_assert_eq!(s.events_dropped, 0);
        prop_assert!(s.max_waiting <= 127);
        prop_assert!(self.m.sdo().in_flight() <= 8);
        Ok(())
    }

    fn frame(&mut self, f: Frame) -> Result<(), TestCaseError> {
        self.m.handle_frame(self.now, &f);
        self.drain(false)
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, ..ProptestConfig::default() })]

    #[test]
    fn random_input_never_breaks_the_master(
        variants in prop::collection::vec(0u8..16, 8),
        start_all in any::<bool>(),
        active in any::<bool>(),
        ops in prop::collection::vec(op(), 1..250),
    ) {
        let mut h = Harness {
            m: build(&variants, start_all, active),
            now: Instant::ZERO,
            last_request: [None; 128],
            active,
        };
        h.m.boot(h.now);
        h.drain(false)?;
        for op in ops {
            match op {
                Op::Noise { id, data, rtr } => {
                    let id = Id::Standard(id);
                    let f = if rtr {
                        Frame::remote(id, data.len() as u8).unwrap()
                    } else {
                        Frame::new(id, &data).unwrap()
                    };
                    h.frame(f)?;
                }
                Op::BootUp(n) => h.frame(Frame::new(Id::Standard(0x700 + n as u16), &[0]).unwrap())?,
                Op::Heartbeat(n, s) => {
                    h.frame(Frame::new(Id::Standard(0x700 + n as u16), &[s]).unwrap())?
                }
                Op::Answer { node, how } => {
                    if let Some(req) = h.last_request[node as usize].take() {
                        let f = answer(node, &req, how);
                        h.frame(f)?;
                    }
                }
                Op::Respond(rounds) => {
                    for _ in 0..rounds {
                        for node in 1..=12u8 {
                            if let Some(req) = h.last_request[node as usize].take() {
                                let f = answer(node, &req, 0);
                                h.frame(f)?;
                            }
                        }
                    }
                }
                Op::Advance(us) => {
                    let until = h.now + Duration::from_micros(us as u64);
                    let mut wakeups = 0;
                    while let Some(t) = h.m.poll_timeout().filter(|t| *t <= until) {
                        // Every deadline handled moves on: no busy loop at one instant.
                        wakeups += 1;
                        prop_assert!(wakeups < 10_000, "stuck at {t:?}");
                        h.now = h.now.max(t);
                        h.m.handle_timeout(h.now);
                        h.drain(false)?;
                    }
                    h.now = until;
                    h.m.handle_timeout(h.now);
                    h.drain(false)?;
                }
                Op::Back(us) => {
                    h.now = h.now - Duration::from_micros(us as u64);
                    h.m.handle_timeout(h.now);
                    h.drain(false)?;
                }
                Op::FarAhead | Op::End => {
                    h.now = match op {
                        Op::End => Instant::MAX,
                        _ => h.now + Duration::from_secs(3600),
                    };
                    // A driver loop at that instant: what is due is handled, then it waits.
                    let mut rounds = 0;
                    while let Some(t) = h.m.poll_timeout().filter(|t| *t <= h.now) {
                        rounds += 1;
                        prop_assert!(rounds <= 3, "still due at {t:?} after {rounds} rounds");
                        h.m.handle_timeout(h.now);
                        h.drain(false)?;
                    }
                }
                Op::SetActive(a) => {
                    h.m.set_active(h.now, a);
                    prop_assert_eq!(h.m.is_active(), a);
                    let was = h.active;
                    h.active = a;
                    h.drain(was && !a)?;
                }
                Op::Nmt(c, n) => {
                    let cmd = [
                        NmtCommand::Start,
                        NmtCommand::Stop,
                        NmtCommand::EnterPreOperational,
                        NmtCommand::ResetNode,
                        NmtCommand::ResetCommunication,
                        NmtCommand::Start,
                    ][c as usize];
                    let target = NodeId::new(n).map_or(NmtTarget::All, NmtTarget::Node);
                    let r = h.m.nmt(h.now, cmd, target);
                    prop_assert_eq!(r.is_ok(), h.active && target != NmtTarget::Node(MASTER_ID));
                    h.drain(false)?;
                }
                Op::BootSlave(n) => {
                    let _ = h.m.boot_slave(h.now, NodeId::must(n));
                    h.drain(false)?;
                }
                Op::StartSlave(n) => {
                    let _ = h.m.start_slave(h.now, NodeId::must(n));
                    h.drain(false)?;
                }
                Op::AddSlave(n) => {
                    let r = h.m.add_slave(h.now, slave_cfg(n, n));
                    prop_assert_eq!(r.is_ok(), n != MASTER_ID.raw());
                    h.drain(false)?;
                }
                Op::Request(sub, v) => {
                    let _ = h.m.node_mut().write(h.now, duocan::master::objects::REQUEST_NMT, sub, &[v]);
                    h.m.handle_timeout(h.now);
                    h.drain(false)?;
                }
            }
            for v in h.m.slaves() {
                prop_assert!(v.assignment.is_slave());
            }
        }
    }
}
