//! The CiA 302-2 master booting three slaves it is configured for from the input (mandatory,
//! keep-alive, guarded, identity checks, SDO writes short and long, TPDO configuration, start
//! policy, 0x1F80 bits, boot time) while the slaves answer with hostile SDO responses shaped
//! after its requests, boot up and beat at any moment, and the application commands; the clock
//! jumps and goes backwards. No panic, bounded output per step, no deadline that stays due.
#![no_main]

mod common;

use common::{advance, drain, expire, sdo_answer, std_frame, Requests};
use duocan::cia302::pdo_config::PdoConfig;
use duocan::machine::SinglePort;
use duocan::master::{
    objects, Assignment, ExpectedIdentity, Master, MasterConfig, NmtStartup, SlaveConfig,
    StartPolicy,
};
use duocan::od::{comm, DynamicDictionary};
use duocan::pdo::MapEntry;
use duocan::{CobId, Device, Duration, Frame, Id, Instant, NmtCommand, NmtTarget, NodeId, Station};
use libfuzzer_sys::fuzz_target;

type Dev = Station<SinglePort, Master<DynamicDictionary>>;

const SLAVES: [u8; 3] = [5, 6, 7];

/// Slave `node` as 8 setup bytes describe it.
fn slave(node: u8, s: &[u8]) -> SlaveConfig {
    let [flags, guard, id, write_len, pdo, map, hb_prod, hb_cons] = *s else {
        return SlaveConfig::new(NodeId::must(node));
    };
    let mut assignment = Assignment::slave();
    if flags & 1 != 0 {
        assignment.0 |= Assignment::MANDATORY;
    }
    if flags & 2 != 0 {
        assignment.0 |= Assignment::KEEP_ALIVE;
    }
    if flags & 4 != 0 {
        assignment.0 &= !Assignment::BOOT;
    }
    if guard != 0 {
        assignment = assignment.guarded(u16::from(guard) * 10, guard % 4);
    }
    let mut c = SlaveConfig::new(NodeId::must(node)).with_assignment(assignment);
    if flags & 8 != 0 {
        c = c.start(StartPolicy::Application);
    }
    if flags & 16 != 0 {
        // Small expected values: the fuzzer can answer them.
        let v = u32::from(id);
        c = c.identity(ExpectedIdentity {
            device_type: v,
            vendor: v ^ 1,
            product: 0,
            revision: v & 0xF,
            serial: 0,
        });
    }
    if flags & 32 != 0 {
        // Expedited (≤ 4 bytes) or segmented.
        let data = [id; 40];
        c = c.write(0x2000, id, &data[..usize::from(write_len % 41)]);
    }
    if flags & 64 != 0 {
        // Any PDO number: the master refuses those outside 1–512 when it is built.
        let number = u16::from(pdo) * 3;
        let entries: Vec<MapEntry> = (0..map % 10)
            .map(|k| MapEntry::new(0x6000 + u16::from(k), k, 8 * (k % 9)))
            .collect();
        let cfg = PdoConfig::new(
            CobId(0x180 + u32::from(node) | u32::from(map & 0x80) << 24),
            map,
        )
        .inhibit(u16::from(id))
        .event_timer(u16::from(hb_prod));
        let cfg = cfg.clone().mapping(&entries).unwrap_or(cfg);
        c = if flags & 128 != 0 {
            c.rpdo(number, cfg)
        } else {
            c.tpdo(number, cfg)
        };
    }
    if hb_prod != 0 {
        c = c.heartbeat(u16::from(hb_prod), u16::from(hb_cons));
    }
    c
}

fn node(sel: u8) -> u8 {
    match sel % 6 {
        0..=2 => SLAVES[usize::from(sel % 3)],
        3 => 1,
        _ => (sel >> 1).clamp(1, 127),
    }
}

fuzz_target!(|data: &[u8]| {
    if data.len() < 3 + 8 * SLAVES.len() {
        return;
    }
    let (setup, rest) = data.split_at(3 + 8 * SLAVES.len());
    let mut net = MasterConfig::new()
        .startup(NmtStartup(u32::from(setup[0] & 0x7F)))
        .boot_time_ms(u32::from(setup[1]) * 50)
        .sdo_timeout(Duration::from_millis(10 + u64::from(setup[2])));
    for (k, n) in SLAVES.iter().enumerate() {
        net = net.slave(slave(*n, &setup[3 + 8 * k..11 + 8 * k]));
    }
    let od = objects::master_dictionary(1, comm::Identity::default());
    let Ok(master) = Master::new(NodeId::must(1), od, net) else {
        return;
    };
    let mut dev: Dev = Station::single(master);
    let mut req = Requests::new();
    let mut now = Instant::ZERO;
    dev.machine.boot(now);
    drain(&mut dev, &mut req);
    for c in rest.chunks_exact(13) {
        let [op, sel, b2, dlc, step, d @ ..] = c else {
            continue;
        };
        let d: [u8; 8] = d.try_into().unwrap_or([0; 8]);
        now = advance(now, *step);
        expire(&mut dev, now, &mut req);
        let n = node(*sel);
        let nid = NodeId::must(n);
        let ec = Id::Standard(0x700 + u16::from(n));
        let frame = match op % 12 {
            0 => Some(Frame::from_array(ec, [0])),
            1 | 2 => Some(Frame::from_array(
                ec,
                [[0x04, 0x05, 0x7F, d[0]][usize::from(*b2 & 3)]],
            )),
            3..=6 => {
                let a = sdo_answer(req.last(n), *b2, d);
                Some(Frame::from_array(Id::Standard(0x580 + u16::from(n)), a))
            }
            // A guarding answer with either toggle.
            7 => Some(Frame::from_array(
                ec,
                [d[0] & 0x80 | [0x04, 0x05, 0x7F][usize::from(*b2 % 3)]],
            )),
            8 => Some(std_frame(
                [0x000, 0x080 + u16::from(n), 0x100][usize::from(*b2 % 3)],
                *dlc,
                &d,
            )),
            9 => {
                let m = &mut dev.machine;
                let _ = match d[0] % 7 {
                    0 => m.start_slave(now, nid),
                    1 => m.reset_slave(now, nid),
                    2 => m.boot_slave(now, nid),
                    3 => m.start_network(now),
                    4 => {
                        m.set_active(now, d[1] & 1 == 0);
                        Ok(())
                    }
                    5 => m.nmt(now, NmtCommand::Stop, NmtTarget::Node(nid)),
                    _ => m.nmt(now, NmtCommand::ResetNode, NmtTarget::All),
                };
                None
            }
            10 => Some(std_frame(u16::from_le_bytes([*b2, d[7]]), *dlc, &d)),
            _ => Frame::remote(ec, 1).ok(),
        };
        if let Some(f) = frame {
            dev.handle_rx(now, 0, &f);
        }
        drain(&mut dev, &mut req);
    }
    for v in dev.machine.slaves() {
        let _ = format!("{v:?}");
    }
    let _ = dev.machine.stats();
});
