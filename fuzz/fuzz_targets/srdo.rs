//! Random frames, time steps and application calls into an SRDO consumer alone and into a
//! consumer node (SRDO 1 on 0x101/0x102, GFC in use): no panic; a value is delivered only as
//! the data of a normal frame paired with its exact inverse (the held half and the frame that
//! completes it); nothing is delivered in the safe state; one trip per start; bounded queues;
//! deadlines move on.
#![no_main]

use duocan::cia304::srdo::config::{self, signature, SrdoMapping};
use duocan::cia304::srdo::consumer::{ConsumerStep, SrdoConsumer};
use duocan::cia304::srdo::objects;
use duocan::od::{comm, Access, DynamicDictionary, ObjectDef};
use duocan::pdo::MapEntry;
use duocan::{Duration, Frame, Id, Instant, Machine, Node, NodeConfig, NodeId};
use libfuzzer_sys::fuzz_target;

const MAX_PER_INPUT: usize = 1024;
const IDS: [u16; 6] = [0x000, 0x001, 0x101, 0x102, 0x103, 0x603];

fn consumer_node() -> Node<DynamicDictionary> {
    let mut od = comm::standard_dictionary(3, comm::Identity::default());
    let _ = od.insert_all(&[
        ObjectDef::u16(0x6000, 0, Access::Rw, 0).mappable(),
        ObjectDef::u16(0x6010, 0, Access::Rw, 0).mappable(),
    ]);
    let _ = od.insert_all(&objects::srdo(1, 0x101));
    let _ = od.insert_all(&objects::shared::<4>());
    let mut n = Node::new(NodeConfig::slave(NodeId::must(3)), od);
    let t = Instant::ZERO;
    let m = SrdoMapping::pairs(&[(MapEntry::new(0x6000, 0, 16), MapEntry::new(0x6010, 0, 16))]);
    let _ = n.set(t, config::COMM, config::sub::DIRECTION, 2u8);
    let _ = n.set(t, config::COMM, config::sub::SCT, 50u16);
    let _ = n.set(t, config::COMM, config::sub::SRVT, 10u8);
    for (k, e) in m.entries().iter().enumerate() {
        let _ = n.set(t, config::MAPPING, k as u8 + 1, e.raw());
    }
    let _ = n.set(t, config::MAPPING, 0, m.count());
    if let Ok(Some((p, m))) = config::read(n.od(), 1) {
        let _ = n.set(t, config::CHECKSUMS, 1, signature(&p, &m));
    }
    let _ = n.set(t, config::CONFIG_VALID, 0, config::VALID);
    let _ = n.set(t, config::GFC_PARAMETER, 0, 1u8);
    n.boot(t);
    n
}

fn drain(n: &mut Node<DynamicDictionary>) {
    let mut k = 0;
    while n.poll_transmit().is_some() || n.poll_event().is_some() {
        k += 1;
        assert!(k <= MAX_PER_INPUT, "unbounded queues");
    }
}

fuzz_target!(|data: &[u8]| {
    let len = 1 + data.first().copied().unwrap_or(0) % 8;
    let (sct, srvt) = (Duration::from_millis(50), Duration::from_millis(10));
    let mut c = SrdoConsumer::new(0x101, 0x102, sct, srvt, len);
    let mut node = consumer_node();
    let mut now = Instant::ZERO;
    c.start(now);
    // The half the consumer holds, as this harness saw it: (normal?, data).
    let mut held: Option<(bool, Vec<u8>)> = None;
    let mut tripped = false;
    for op in data.get(1..).unwrap_or(&[]).chunks(11) {
        let [kind, step, rest @ ..] = op else { break };
        // Time moves by up to 25.5 ms; now and then it steps back (the node follows the clock
        // contract; the consumer alone must not panic on it).
        now = if *kind == 0xFF {
            now - Duration::from_millis(*step as u64)
        } else {
            now + Duration::from_micros(*step as u64 * 100)
        };
        match kind % 8 {
            0 => {
                let was = tripped;
                if c.acknowledge(now) {
                    assert!(was, "acknowledged without a trip");
                    tripped = false;
                    held = None;
                }
                node.srdo_acknowledge(now, 1);
            }
            1 => {
                c.start(now);
                tripped = false;
                held = None;
                node.set_nmt_state(now, duocan::NmtState::Operational);
            }
            _ => {
                let id = IDS[*kind as usize / 8 % IDS.len()];
                let Some((dlc, payload)) = rest.split_first() else {
                    break;
                };
                let n = (*dlc as usize % 9).min(payload.len());
                let Ok(f) = Frame::new(Id::Standard(id), &payload[..n]) else {
                    continue;
                };
                // Deadlines first, as a driver does.
                while let Some(d) = c.poll_timeout().filter(|d| *d <= now) {
                    if let Some(ConsumerStep::Trip(_)) = c.handle_timeout(d) {
                        assert!(!tripped, "two trips without a restart");
                        tripped = true;
                    }
                    assert!(c.poll_timeout().is_none_or(|x| x > d), "deadline stays due");
                }
                match c.handle_frame(now, &f) {
                    Some(ConsumerStep::Deliver(v)) => {
                        assert!(!tripped, "delivered in the safe state");
                        let l = len as usize;
                        let (h, data) = held.take().expect("delivered without a held half");
                        assert_ne!(h, id == 0x101, "delivered on two halves of one kind");
                        let this = &f.data()[..l];
                        let (n, i) = if h {
                            (&data[..], this)
                        } else {
                            (this, &data[..])
                        };
                        assert_eq!(&v[..l], n, "not the normal data");
                        assert!(n.iter().zip(i).all(|(a, b)| *a == !*b), "not inverse");
                    }
                    Some(ConsumerStep::Trip(_)) => {
                        assert!(!tripped, "two trips without a restart");
                        tripped = true;
                    }
                    Some(ConsumerStep::Held) if held.is_none() => {
                        held = Some((id == 0x101, f.data()[..len as usize].to_vec()));
                    }
                    _ => {}
                }
                node.handle_frame(now, &f);
            }
        }
        drain(&mut node);
        for _ in 0..64 {
            match node.poll_timeout() {
                Some(t) if t <= now => node.handle_timeout(now),
                _ => break,
            }
            drain(&mut node);
        }
        assert!(
            node.poll_timeout().is_none_or(|t| t > now),
            "node deadline stays due"
        );
    }
});
