//! SDO client ↔ server on the simulated bus at 1 Mbit/s: every size in every mode, random frame
//! loss and delay (a transfer completes correctly or aborts with the timeout code; it never hangs
//! and never leaves a half-written entry), and throughput against the bus limit.
//!
//! Block transfer sends a whole sub-block (up to 127 segments) at once. The simulator drains
//! `poll_transmit` completely into the port's transmit queue, so the ports get room for a
//! sub-block; a driver with back-pressure simply pulls segments as the controller has room.

use crate::net::DOMAIN;
use duocan::machine::{Composite, CompositeEvent, SinglePort, StationEvent};
use duocan::od::{DynamicDictionary, ObjectDictionary};
use duocan::sdo::codec::{BlockSegment, Init, Request, Response, SegmentData};
use duocan::sdo::{block, crc, SdoClient, SdoError, SdoEvent, SdoOptions, TransferMode};
use duocan::sim::{timing, BusConfig, BusId, DevId, FaultRates, RxFault, SimNetwork, TraceRecord};
use duocan::{AbortCode, Duration, Frame, Id, Instant, Node, NodeConfig, NodeId, Station};

type Master = Station<SinglePort, Composite<Node<DynamicDictionary>, SdoClient>>;
type Slave = Station<SinglePort, Node<DynamicDictionary>>;

const BITRATE: u32 = 1_000_000;
const S: NodeId = NodeId::must(5);
const SIZES: [usize; 9] = [0, 1, 4, 5, 7, 8, 889, 890, 64 * 1024];

struct Rig {
    sim: SimNetwork,
    bus: BusId,
    m: DevId<Master>,
    s: DevId<Slave>,
}

fn rig(seed: u64, faults: FaultRates) -> Rig {
    let mut sim = SimNetwork::new(seed);
    let bus = sim.add_bus(BusConfig::new("can0", BITRATE));
    sim.set_bus_faults(bus, faults);
    let master = Node::new(
        NodeConfig::master(NodeId::must(1)),
        duocan::od::comm::standard_dictionary(1, Default::default()),
    );
    let client = SdoClient::new(duocan::sdo::DEFAULT_LIMIT + 16);
    let m = sim
        .add_device(
            "master",
            Station::single(Composite::new(master, client)),
            &[bus],
        )
        .unwrap();
    let s = sim
        .add_device("slave", Station::single(crate::net::server(5)), &[bus])
        .unwrap();
    // A small controller queue: block transfers must live with back-pressure.
    for p in [m.port(0), s.port(0)] {
        sim.set_tx_capacity(p, 4);
    }
    sim.device_mut(m).machine.a.boot(Instant::ZERO);
    sim.device_mut(s).machine.boot(Instant::ZERO);
    sim.run_for(Duration::from_millis(1));
    sim.take_events(m);
    Rig { sim, bus, m, s }
}

impl Rig {
    fn client(&mut self) -> &mut SdoClient {
        &mut self.sim.device_mut(self.m).machine.b
    }

    /// Starts a request and runs the simulation until its result arrives.
    fn run(
        &mut self,
        start: impl FnOnce(&mut SdoClient, Instant) -> Result<duocan::sdo::RequestId, SdoError>,
    ) -> (Instant, SdoEvent) {
        let t0 = self.sim.now();
        let id = start(self.client(), t0).unwrap();
        loop {
            let t = self
                .sim
                .step()
                .expect("the simulation went idle without a result");
            assert!(t - t0 < Duration::from_secs(120), "transfer hangs");
            for (_, e) in self.sim.take_events(self.m) {
                if let StationEvent::Machine(CompositeEvent::B(e)) = e {
                    assert_eq!(e.request, id);
                    return (t0, e);
                }
            }
        }
    }

    fn domain(&self) -> Vec<u8> {
        self.sim
            .device(self.s)
            .machine
            .od()
            .read(DOMAIN, 0)
            .unwrap()
            .to_vec()
    }
}

fn pattern(len: usize, seed: u64) -> Vec<u8> {
    let mut rng = fastrand::Rng::with_seed(seed);
    (0..len).map(|_| rng.u8(..)).collect()
}

fn modes(len: usize) -> Vec<SdoOptions> {
    let mut v = vec![
        SdoOptions::default(),
        SdoOptions::mode(TransferMode::Segmented),
        SdoOptions::mode(TransferMode::Block),
        SdoOptions::mode(TransferMode::Block).with_crc(false),
    ];
    if (1..=4).contains(&len) {
        v.push(SdoOptions::mode(TransferMode::Expedited));
    }
    v
}

#[test]
fn every_size_in_every_mode_at_1_mbit() {
    let mut r = rig(1, FaultRates::NONE);
    for len in SIZES {
        for opts in modes(len) {
            let data = pattern(len, len as u64);
            let (_, e) = r.run(|c, now| c.download(now, S, DOMAIN, 0, &data, opts));
            assert!(e.result.is_ok(), "{len} {opts:?}: {:?}", e.result);
            assert_eq!(r.domain(), data, "{len} {:?}", opts.mode);
            let (_, e) = r.run(|c, now| c.upload(now, S, DOMAIN, 0, opts));
            assert_eq!(e.data(), Some(&data[..]), "{len} {:?}", opts.mode);
        }
    }
    // Sub-blocks of 127 segments went through 4-frame controller queues: held back, not lost.
    assert!(r.sim.port_stats(r.m.port(0)).tx_blocked > 0);
    assert_eq!(r.sim.port_stats(r.m.port(0)).tx_failed, 0);
}

/// Loss and delay on every frame: each transfer completes with the right data or fails with the
/// timeout code of either side; a download leaves the old or the new value, nothing else.
#[test]
fn random_loss_and_delay_complete_or_time_out_never_corrupt() {
    let mut ok = 0;
    let mut failed = 0;
    let mut recovered = 0;
    for seed in 0..8u64 {
        let faults = FaultRates::NONE
            .with_drop([0.002, 0.01, 0.03, 0.1][seed as usize % 4])
            .with_delay(0.2, Duration::from_micros(700));
        let mut r = rig(seed, faults);
        let mut outcome = |r: &mut Rig, e: &SdoEvent, ok_data: Option<&[u8]>| {
            let dropped = r
                .sim
                .trace()
                .iter()
                .filter(|t| matches!(t, TraceRecord::Rx(x) if x.fault == RxFault::Dropped))
                .count();
            match (&e.result, ok_data) {
                (Ok(_), _) => {
                    ok += 1;
                    if dropped > 0 {
                        // Only block transfer survives a lost frame: by retransmission.
                        assert_eq!(e.mode, TransferMode::Block);
                        recovered += 1;
                    }
                }
                (Err(err), _) => {
                    failed += 1;
                    assert!(dropped > 0, "failed without loss: {err}");
                    assert!(err.is_timeout(), "seed {seed}: {err}");
                }
            }
        };
        for len in SIZES {
            for opts in modes(len) {
                let data = pattern(len, seed * 1000 + len as u64);
                let before = r.domain();
                r.sim.clear_trace();
                let (_, e) = r.run(|c, now| c.download(now, S, DOMAIN, 0, &data, opts));
                let after = r.domain();
                if e.result.is_ok() {
                    assert_eq!(after, data, "seed {seed} len {len} {:?}", opts.mode);
                } else {
                    assert!(after == before || after == data, "half-written entry");
                }
                outcome(&mut r, &e, Some(&data));
                // Let both sides forget a failed transfer before the next one.
                r.sim.run_for(Duration::from_secs(2));
                let value = r.domain();
                r.sim.clear_trace();
                let (_, e) = r.run(|c, now| c.upload(now, S, DOMAIN, 0, opts));
                if let Ok(b) = &e.result {
                    assert_eq!(&b[..], &value[..], "seed {seed} len {len} {:?}", opts.mode);
                }
                outcome(&mut r, &e, None);
                r.sim.run_for(Duration::from_secs(2));
            }
        }
        let slave = r.sim.device(r.s).machine.sdo_server();
        assert!(slave.is_idle());
        assert_eq!(slave.buffer_len(), 0);
    }
    println!(
        "{ok} transfers completed ({recovered} of them after losing frames), {failed} timed out"
    );
    assert!(
        ok > 100 && failed > 20 && recovered > 10,
        "{ok} completed, {recovered} recovered, {failed} failed"
    );
}

/// The frames of the shortest exchange of each protocol, for the bus-time limit.
fn block_download_frames(data: &[u8]) -> Vec<Frame> {
    let (rx, tx) = (Id::Standard(0x605), Id::Standard(0x585));
    let mut v = vec![Frame::from_array(
        rx,
        Request::BlockDownloadInitiate {
            index: DOMAIN,
            sub: 0,
            crc: true,
            size: Some(data.len() as u32),
        }
        .encode(),
    )];
    v.push(Frame::from_array(
        tx,
        Response::BlockDownloadInitiate {
            index: DOMAIN,
            sub: 0,
            crc: true,
            blksize: 127,
        }
        .encode(),
    ));
    let n = block::segments(data.len());
    for i in 0..n {
        let mut d = [0u8; 7];
        let chunk = &data[i * 7..((i + 1) * 7).min(data.len())];
        d[..chunk.len()].copy_from_slice(chunk);
        let seqno = (i % 127) as u8 + 1;
        v.push(Frame::from_array(
            rx,
            BlockSegment {
                seqno,
                last: i + 1 == n,
                data: d,
            }
            .encode(),
        ));
        if seqno == 127 || i + 1 == n {
            v.push(Frame::from_array(
                tx,
                Response::BlockDownloadAck {
                    ackseq: seqno,
                    blksize: 127,
                }
                .encode(),
            ));
        }
    }
    v.push(Frame::from_array(
        rx,
        Request::BlockDownloadEnd {
            unused: block::unused(data.len()),
            crc: crc::crc16(data),
        }
        .encode(),
    ));
    v.push(Frame::from_array(tx, Response::BlockDownloadEnd.encode()));
    v
}

fn segmented_download_frames(data: &[u8]) -> Vec<Frame> {
    let (rx, tx) = (Id::Standard(0x605), Id::Standard(0x585));
    let mut v = vec![
        Frame::from_array(
            rx,
            Request::InitiateDownload {
                index: DOMAIN,
                sub: 0,
                init: Init::Segmented {
                    size: Some(data.len() as u32),
                },
            }
            .encode(),
        ),
        Frame::from_array(
            tx,
            Response::InitiateDownload {
                index: DOMAIN,
                sub: 0,
            }
            .encode(),
        ),
    ];
    let chunks: Vec<&[u8]> = data.chunks(7).collect();
    for (i, c) in chunks.iter().enumerate() {
        let toggle = i % 2 == 1;
        v.push(Frame::from_array(
            rx,
            Request::DownloadSegment {
                toggle,
                data: SegmentData::from_slice(c),
                last: i + 1 == chunks.len(),
            }
            .encode(),
        ));
        v.push(Frame::from_array(
            tx,
            Response::DownloadSegment { toggle }.encode(),
        ));
    }
    v
}

fn bus_time(frames: &[Frame]) -> Duration {
    frames.iter().fold(Duration::ZERO, |t, f| {
        t + timing::frame_duration(f, BITRATE)
    })
}

fn kib_per_s(bytes: usize, d: Duration) -> f64 {
    bytes as f64 / 1024.0 / (d.as_micros() as f64 / 1e6)
}

#[test]
fn block_and_segmented_download_reach_90_percent_of_their_bus_limits() {
    let data = pattern(64 * 1024, 77);
    let mut r = rig(5, FaultRates::NONE);

    let (t0, e) = r.run(|c, now| {
        c.download(
            now,
            S,
            DOMAIN,
            0,
            &data,
            SdoOptions::mode(TransferMode::Block),
        )
    });
    assert!(e.result.is_ok());
    let took = e.at - t0;
    let frames = block_download_frames(&data);
    let limit = bus_time(&frames);
    // The stricter bound: the data segments alone, back to back.
    let segments_only = bus_time(
        &frames[2..]
            .iter()
            .filter(|f| f.id() == Id::Standard(0x605))
            .copied()
            .collect::<Vec<_>>(),
    );
    println!(
        "block download 64 KiB at 1 Mbit/s: {:.1} KiB/s in {took}; bus limit of the protocol {:.1} KiB/s ({limit}), segments alone {:.1} KiB/s",
        kib_per_s(data.len(), took),
        kib_per_s(data.len(), limit),
        kib_per_s(data.len(), segments_only),
    );
    assert!(took.as_micros() as f64 <= limit.as_micros() as f64 / 0.9);
    assert!(took.as_micros() as f64 <= segments_only.as_micros() as f64 / 0.9);
    // The simulated exchange is exactly the protocol's frames, back to back.
    assert_eq!(took, limit);

    let (t0, e) = r.run(|c, now| {
        c.download(
            now,
            S,
            DOMAIN,
            0,
            &data,
            SdoOptions::mode(TransferMode::Segmented),
        )
    });
    assert!(e.result.is_ok());
    let took = e.at - t0;
    let limit = bus_time(&segmented_download_frames(&data));
    println!(
        "segmented download 64 KiB at 1 Mbit/s: {:.1} KiB/s in {took}; round-trip limit {:.1} KiB/s ({limit})",
        kib_per_s(data.len(), took),
        kib_per_s(data.len(), limit),
    );
    assert!(took.as_micros() as f64 <= limit.as_micros() as f64 / 0.9);
    assert_eq!(r.domain(), data);
}

#[test]
fn a_stopped_server_stays_silent_and_the_client_times_out_exactly() {
    let mut r = rig(2, FaultRates::NONE);
    let now = r.sim.now();
    r.sim
        .device_mut(r.s)
        .machine
        .set_nmt_state(now, duocan::NmtState::Stopped);
    let (t0, e) = r.run(|c, now| c.upload(now, S, DOMAIN, 0, SdoOptions::default()));
    let err = e.result.unwrap_err();
    assert_eq!(
        err.kind,
        duocan::sdo::SdoErrorKind::Client(AbortCode::TIMEOUT)
    );
    assert_eq!(e.at, t0 + Duration::from_millis(1000));
    let from_slave = r
        .sim
        .trace()
        .iter()
        .filter(|t| matches!(t, TraceRecord::Tx(t) if t.frame.id() == Id::Standard(0x585)))
        .count();
    assert_eq!(from_slave, 0);
    let _ = r.bus;
}

/// CAN can deliver a frame twice. A second copy that arrives before its sender's next frame is
/// recognised by client and server (equal to the frame before it, and not what the transfer can
/// take: the old toggle bit, a segment after the end, …) and ignored, so every transfer
/// completes with its data; no protocol code is ever needed, nothing hangs, no entry is
/// half-written, no upload returns wrong data.
#[test]
fn duplicated_frames_never_corrupt_and_never_hang() {
    let protocol_codes = [
        AbortCode::TOGGLE_BIT,
        AbortCode::COMMAND_SPECIFIER,
        AbortCode::INVALID_SEQUENCE,
        AbortCode::LENGTH_TOO_LOW,
        AbortCode::LENGTH_TOO_HIGH,
        AbortCode::CRC_ERROR,
        AbortCode::TIMEOUT,
    ];
    let (mut ok, mut failed) = (0, 0);
    for seed in 0..6u64 {
        let mut r = rig(seed, FaultRates::NONE.with_duplicate(0.02));
        for len in SIZES {
            for opts in modes(len) {
                let data = pattern(len, seed * 1000 + len as u64);
                let before = r.domain();
                let (_, e) = r.run(|c, now| c.download(now, S, DOMAIN, 0, &data, opts));
                let after = r.domain();
                match &e.result {
                    Ok(_) => assert_eq!(after, data),
                    Err(err) => {
                        assert!(protocol_codes.contains(&err.code().unwrap()), "{err}");
                        assert!(after == before || after == data, "half-written entry");
                    }
                }
                r.sim.run_for(Duration::from_secs(2));
                let value = r.domain();
                let (_, e2) = r.run(|c, now| c.upload(now, S, DOMAIN, 0, opts));
                match &e2.result {
                    Ok(b) => assert_eq!(&b[..], &value[..]),
                    Err(err) => assert!(protocol_codes.contains(&err.code().unwrap()), "{err}"),
                }
                for e in [e, e2] {
                    if e.result.is_ok() {
                        ok += 1
                    } else {
                        failed += 1
                    }
                }
                r.sim.run_for(Duration::from_secs(2));
            }
        }
    }
    println!("with duplicates: {ok} completed, {failed} aborted");
    assert!(ok > 100);
    assert_eq!(failed, 0);
}
