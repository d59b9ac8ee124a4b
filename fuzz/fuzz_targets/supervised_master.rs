//! The supervised master as a driver runs it: a `SupervisedStation` (dual bus, CiA 302-2
//! master, two slave pairs, a flying-master peer) fed hostile traffic on either port or both —
//! boot-ups, heartbeats in every state, SDO answers shaped after its requests, flying-master
//! frames on 0x71–0x76, NMT, SYNC, TIME and EMCY frames — port statuses, the application's
//! commands, and the shared misbehaving clock (steps back, an hour ahead, the end of time). No
//! panic, bounded output per step, no deadline that stays due (after every step, and at the end
//! of time nothing is due at all), a status table that always prints.
#![no_main]

mod common;

use common::{
    advance, drain, expire, misbehave, port_status, sdo_answer, std_frame, Requests,
};
use duocan::master::{objects, Master, MasterConfig};
use duocan::od::comm;
use duocan::{Device, Duration, Frame, Id, Instant, NmtCommand, NmtTarget, NodeId};
use duocan_redundancy::{
    DualBus, DualBusConfig, LinkMode, Member, PairId, PairSpec, RedundantMaster, Supervisor,
    SupervisorConfig,
};
use libfuzzer_sys::fuzz_target;

const SELF: u8 = 1;
const PEER: u8 = 2;
/// Pair i: A = 0x10 + i, B = 0x50 + i.
const PAIRS: u8 = 2;

fn station(weak: bool) -> RedundantMaster {
    let (me, peer) = if weak { (PEER, SELF) } else { (SELF, PEER) };
    let nid = NodeId::must(me);
    let od = objects::master_dictionary(me, comm::Identity::default());
    let master = Master::new(nid, od, MasterConfig::new()).expect("a valid master");
    let ms = Duration::from_millis;
    let cfg = SupervisorConfig::new(me - 1, nid, ms(20), ms(50), ms(10))
        .with_peer(peer - 1, NodeId::must(peer))
        .with_time_period(ms(100));
    let mut sup = Supervisor::new(master, cfg, Instant::ZERO);
    for i in 0..PAIRS {
        let spec = PairSpec::new(
            NodeId::must(0x10 + i),
            NodeId::must(0x50 + i),
            ms(20),
            ms(50),
        );
        sup.add_pair(Instant::ZERO, spec).expect("two pairs fit");
    }
    let link = DualBus::new(DualBusConfig::with_guard_period(
        LinkMode::ActiveActive,
        ms(20),
    ));
    RedundantMaster::new(link, sup).expect("the pairs fit the layer")
}

/// The node an input talks about: mostly the pairs' members and the other master.
fn node(sel: u8) -> u8 {
    match sel % 8 {
        0 => 0x10,
        1 => 0x50,
        2 => 0x11,
        3 => 0x51,
        4 => PEER,
        5 => SELF,
        _ => (sel >> 1).clamp(1, 127),
    }
}

fuzz_target!(|data: &[u8]| {
    let Some((&setup, rest)) = data.split_first() else {
        return;
    };
    let mut st = station(setup & 1 == 1);
    let mut req = Requests::new();
    let mut now = Instant::ZERO;
    expire(&mut st, now, &mut req);
    for c in rest.chunks_exact(13) {
        let [op, sel, b2, dlc, step, d @ ..] = c else {
            continue;
        };
        let d: [u8; 8] = d.try_into().unwrap_or([0; 8]);
        // The shared misbehaving clock: steps back, an hour ahead, the end of time.
        now = misbehave(now, *step).unwrap_or_else(|| advance(now, *step));
        expire(&mut st, now, &mut req);
        let n = node(*sel);
        let frame = match op & 0x0F {
            0 => Some(Frame::from_array(Id::Standard(0x700 + u16::from(n)), [0])),
            1 | 2 => {
                let state = [0x04, 0x05, 0x7F, d[0]][usize::from(*b2 & 3)];
                Some(Frame::from_array(
                    Id::Standard(0x700 + u16::from(n)),
                    [state],
                ))
            }
            3..=5 => {
                let a = sdo_answer(req.last(n), *b2, d);
                Some(Frame::from_array(Id::Standard(0x580 + u16::from(n)), a))
            }
            6 | 7 => Some(std_frame(0x71 + u16::from(*b2 % 6), *dlc, &d)),
            8 => {
                st.handle_port_status(now, usize::from(*b2 & 1), port_status(*dlc, d[0]));
                None
            }
            9 => Some(std_frame(0x000, 2, &[d[0], n, 0, 0, 0, 0, 0, 0])),
            10 => Some(std_frame(
                [0x080, 0x100, 0x080 + u16::from(n)][usize::from(*b2 % 3)],
                *dlc,
                &d,
            )),
            11 => Frame::remote(Id::Standard(0x700 + u16::from(n)), 1).ok(),
            12 => {
                // The application's commands; refusals are fine, panics are not.
                let pair = PairId(*b2 % PAIRS);
                let sup = st.sup_mut();
                match d[0] % 5 {
                    0 => drop(sup.switch_over(
                        now,
                        pair,
                        if d[1] & 1 == 0 { Member::A } else { Member::B },
                    )),
                    1 => drop(sup.set_standby(now)),
                    2 => drop(sup.set_active(now)),
                    3 => drop(sup.nmt(
                        now,
                        NmtCommand::Start,
                        NmtTarget::Node(NodeId::must(node(d[1]))),
                    )),
                    _ => drop(sup.nmt(now, NmtCommand::ResetCommunication, NmtTarget::All)),
                }
                None
            }
            _ => Some(std_frame(u16::from_le_bytes([*b2, d[7]]), *dlc, &d)),
        };
        if let Some(f) = frame {
            // Port 0, port 1, or both (the twin a little later).
            match op >> 4 & 3 {
                0 => st.handle_rx(now, 0, &f),
                1 => st.handle_rx(now, 1, &f),
                _ => {
                    st.handle_rx(now, 0, &f);
                    drain(&mut st, &mut req);
                    let twin = now + Duration::from_micros(u64::from(*dlc) * 100);
                    st.handle_rx(twin, 1, &f);
                }
            }
        }
        drain(&mut st, &mut req);
    }
    // Whatever happened, the status table prints.
    let _ = format!("{}", st.status(now));
    // At the end of time what is due is handled once, and then nothing stays due.
    expire(&mut st, Instant::MAX, &mut req);
    assert_eq!(st.poll_timeout(), None, "a deadline stays due at the end of time");
});
