//! The PDO configurator (CiA 301 order, the fallback for devices that refuse to disable a PDO)
//! with a configuration from the input and every access answered from the input: values of
//! any length, aborts of any code, no answer. Then the same job carried by an SDO client fed
//! hostile frames, and the master's mirror of the configuration into its own dictionary.
//! No panic; every access names the PDO's objects with the entry's size; the job ends within
//! a bound, exactly once, with the final COB-ID written last when it succeeds outright.
#![no_main]

mod common;

use common::sdo_answer;
use duocan::cia302::pdo_config::{
    mirror, AccessError, Local, Mirror, PdoConfig, PdoConfigurator, SdoAccess, SdoPdoJob,
};
use duocan::od::{comm, DataType};
use duocan::pdo::{Dir, MapEntry};
use duocan::sdo::{SdoClient, SdoOptions};
use duocan::{AbortCode, CobId, Duration, Frame, Id, Instant, Machine, Node, NodeConfig, NodeId};
use libfuzzer_sys::fuzz_target;

/// ReadCob, Disable, four parameters and their read-backs, MapClear, 64 entries, MapCount, the
/// fallback's count and 64 entries, Enable: no job asks for more.
const MAX_ACCESSES: usize = 2 + 8 + 1 + 64 + 1 + 1 + 64 + 1;

/// Pops `n` bytes from the front of `d` (zeros past its end).
fn take<const N: usize>(d: &mut &[u8]) -> [u8; N] {
    let mut b = [0u8; N];
    let n = d.len().min(N);
    b[..n].copy_from_slice(&d[..n]);
    *d = &d[n..];
    b
}

fn config(d: &mut &[u8]) -> (Dir, u16, PdoConfig) {
    let [flags, ttype, count, pdo] = take::<4>(d);
    let cob = u32::from_le_bytes(take::<4>(d));
    let [inh, timer, sync] = take::<3>(d);
    let dir = if flags & 1 == 0 {
        Dir::Transmit
    } else {
        Dir::Receive
    };
    let pdo = 1 + u16::from(pdo) * 2;
    let mut cfg = PdoConfig::new(CobId(cob), ttype);
    if flags & 2 != 0 {
        cfg = cfg.inhibit(u16::from(inh));
    }
    if flags & 4 != 0 {
        cfg = cfg.event_timer(u16::from(timer));
    }
    if flags & 8 != 0 {
        cfg = cfg.sync_start(sync);
    }
    if flags & 16 != 0 {
        let entries: Vec<MapEntry> = (0..count % 66)
            .map(|k| {
                let [i, s, b] = take::<3>(d);
                MapEntry::new(0x2000 + u16::from(i), s.wrapping_add(k), b)
            })
            .collect();
        // 65 entries is one too many: the builder refuses it.
        cfg = cfg.clone().mapping(&entries).unwrap_or(cfg);
    }
    (dir, pdo, cfg)
}

/// The answer the input gives to an access.
fn answer(d: &mut &[u8]) -> Result<Vec<u8>, AccessError> {
    let [kind, len] = take::<2>(d);
    let v = take::<8>(d);
    let code = AbortCode(u32::from_le_bytes([v[0], v[1], v[2], v[3]]));
    match kind % 8 {
        0..=3 => Ok(v[..usize::from(len % 9)].to_vec()),
        4 => Err(AccessError::Aborted(code)),
        // A refusal (the fallback's trigger) and a protocol abort (the device not heard).
        5 => Err(AccessError::Aborted(AbortCode(0x0609_0030))),
        6 => Err(AccessError::Aborted(AbortCode(0x0504_0000))),
        _ => Err(AccessError::NoAnswer(Some(code))),
    }
}

fn direct(node: NodeId, dir: Dir, pdo: u16, cfg: &PdoConfig, d: &mut &[u8]) {
    let (comm, map) = match dir {
        Dir::Receive => (0x1400 + pdo - 1, 0x1600 + pdo - 1),
        Dir::Transmit => (0x1800 + pdo - 1, 0x1A00 + pdo - 1),
    };
    let mut job = PdoConfigurator::new(node, dir, pdo, cfg.clone());
    let mut last = None;
    let mut accesses = 0;
    while let Some(a) = job.next() {
        accesses += 1;
        assert!(accesses <= MAX_ACCESSES, "the job does not end: {a:?}");
        assert!(job.result().is_none(), "a result while accesses remain");
        assert!(
            a.index() == comm || a.index() == map,
            "{a:?} is not PDO {pdo}'s"
        );
        if let SdoAccess::Write { len, .. } = a {
            assert!(matches!(len, 1 | 2 | 4), "{a:?}");
            assert_eq!(a.data().len(), usize::from(len));
        }
        last = Some(a);
        let r = answer(d);
        job.handle(r.as_deref().map_err(|e| *e));
    }
    match job.result().expect("a finished job has its result") {
        Ok(c) if !c.fallback => assert_eq!(
            last,
            Some(SdoAccess::Write {
                index: comm,
                sub: 1,
                data: cfg.cob_id.0.to_le_bytes(),
                len: 4
            }),
            "the final COB-ID is written last"
        ),
        Ok(_) => {}
        Err(e) => {
            assert_eq!(e.node, node);
            let _ = e.to_string();
        }
    }
}

/// The job over an SDO client whose server answers from the input.
fn over_sdo(node: NodeId, dir: Dir, pdo: u16, cfg: &PdoConfig, d: &mut &[u8]) {
    let mut client: SdoClient = SdoClient::with_limit(64);
    let opts = SdoOptions::default().with_timeout(Duration::from_millis(50));
    let mut job =
        SdoPdoJob::new(PdoConfigurator::new(node, dir, pdo, cfg.clone())).with_options(opts);
    let mut now = Instant::ZERO;
    let mut request = None;
    job.poll(now, &mut client);
    // A segmented upload of the 64-byte limit takes a dozen frames; an access that gets
    // nothing takes one step.
    for _ in 0..16 * MAX_ACCESSES {
        if job.result().is_some() {
            break;
        }
        while let Some(f) = client.poll_transmit() {
            request = f.data().try_into().ok();
        }
        // Forward only: the job's end rests on the client's timeouts, which need time to pass.
        let [kind, step] = take::<2>(d);
        now += Duration::from_millis(u64::from(step % 32));
        if kind & 1 == 0 && !d.is_empty() {
            let a = sdo_answer(request, kind >> 1, take::<8>(d));
            client.handle_frame(
                now,
                &Frame::from_array(Id::Standard(0x580 + u16::from(node.raw())), a),
            );
        } else {
            // Silence: the client's timeout ends the access.
            now += Duration::from_millis(60);
        }
        if client.poll_timeout().is_some_and(|t| t <= now) {
            client.handle_timeout(now);
        }
        while let Some(ev) = client.poll_event() {
            assert!(job.handle_event(&ev), "an event of another request");
        }
        job.poll(now, &mut client);
    }
    assert!(
        job.result().is_some(),
        "every access answered or timed out: the job ends"
    );
}

/// The master's end of the PDO: its own dictionary, entries from the input.
fn mirrored(dir: Dir, cfg: &PdoConfig, d: &mut &[u8]) {
    const TYPES: [DataType; 6] = [
        DataType::Unsigned8,
        DataType::Unsigned16,
        DataType::Unsigned32,
        DataType::Integer64,
        DataType::Boolean,
        DataType::VisibleString,
    ];
    let n = cfg.mapping.as_ref().map_or(0, |m| m.len());
    let [extra, pdo, ttype] = take::<3>(d);
    let locals: Vec<Option<Local>> = (0..n + usize::from(extra % 2))
        .map(|_| {
            let [i, s, t] = take::<3>(d);
            (t != 0)
                .then(|| Local::new(0x2100 + u16::from(i % 4), s % 4, TYPES[usize::from(t) % 6]))
        })
        .collect();
    let mut master = Node::new(
        NodeConfig::master(NodeId::must(1)),
        comm::standard_dictionary(1, comm::Identity::default()),
    );
    let m = Mirror {
        pdo: u16::from(pdo % 8),
        transmission_type: ttype,
        event_timer_ms: 100,
        inhibit_100us: 0,
        locals: &locals,
    };
    let _ = mirror(&mut master, Instant::ZERO, dir, cfg, &m).map_err(|e| e.to_string());
    master.handle_timeout(Instant::from_millis(200));
    while master.poll_transmit().is_some() {}
    while master.poll_event().is_some() {}
}

fuzz_target!(|data: &[u8]| {
    let mut d = data;
    let [id] = take::<1>(&mut d);
    let node = NodeId::new(id & 0x7F).unwrap_or(NodeId::must(5));
    let (dir, pdo, cfg) = config(&mut d);
    direct(node, dir, pdo, &cfg, &mut d);
    over_sdo(node, dir, pdo, &cfg, &mut d);
    mirrored(dir, &cfg, &mut d);
});
