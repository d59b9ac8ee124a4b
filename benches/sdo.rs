//! SDO: throughput in simulated time at 1 Mbit/s against the bus limit (printed first), and the
//! CPU cost per segment of server and client (criterion).
//!
//! The simulated figures are deterministic; `tests/sdo_sim.rs` asserts them (≥ 90 % of the limit).
//! Here they are printed next to the limit computed from the exact lengths of the protocol's
//! frames: the fastest any implementation can go on that bus.
//!
//! The CPU benchmarks replay a recorded 889-byte transfer (127 segments, one full sub-block) into
//! a server or a client; criterion's time is per transfer, its throughput in segments per second.

use criterion::{criterion_group, Criterion, Throughput};
use duocan::machine::{Composite, CompositeEvent, StationEvent};
use duocan::od::{comm, DataType, DynamicDictionary, ObjectDef};
use duocan::sdo::codec::{BlockSegment, Init, Request, Response, SegmentData};
use duocan::sdo::{block, crc, SdoClient, SdoOptions, TransferMode};
use duocan::sim::{timing, BusConfig, SimNetwork};
use duocan::{Duration, Frame, Id, Instant, Machine, Node, NodeConfig, NodeId, Station};
use std::hint::black_box;

const BITRATE: u32 = 1_000_000;
const DOMAIN: u16 = 0x2000;
const S: NodeId = NodeId::must(5);

fn server() -> Node<DynamicDictionary> {
    let mut od = comm::standard_dictionary(5, comm::Identity::default());
    od.insert(ObjectDef::bytes(DOMAIN, 0, DataType::Domain, 70_000))
        .unwrap();
    let mut n = Node::new(NodeConfig::slave(S), od);
    n.boot(Instant::ZERO);
    while n.poll_transmit().is_some() {}
    n
}

fn data(len: usize) -> Vec<u8> {
    (0..len).map(|i| (i * 131 % 251) as u8).collect()
}

// ----- simulated time -----

/// Runs one transfer on a simulated 1 Mbit/s bus; returns how long it took.
fn simulated(mode: TransferMode, payload: &[u8]) -> Duration {
    let mut sim = SimNetwork::new(1);
    let bus = sim.add_bus(BusConfig::new("can0", BITRATE));
    let master = Node::new(
        NodeConfig::master(NodeId::must(1)),
        comm::standard_dictionary(1, comm::Identity::default()),
    );
    let m = sim
        .add_device(
            "master",
            Station::single(Composite::new(master, SdoClient::new(70_000))),
            &[bus],
        )
        .unwrap();
    let _slave = sim
        .add_device("slave", Station::single(server()), &[bus])
        .unwrap();
    sim.device_mut(m).machine.a.boot(Instant::ZERO);
    sim.run_for(Duration::from_millis(1));
    sim.take_events(m);
    let t0 = sim.now();
    sim.device_mut(m)
        .machine
        .b
        .download(t0, S, DOMAIN, 0, payload, SdoOptions::mode(mode))
        .unwrap();
    loop {
        sim.step().expect("a result");
        for (_, e) in sim.take_events(m) {
            if let StationEvent::Machine(CompositeEvent::B(e)) = e {
                assert!(e.result.is_ok());
                return e.at - t0;
            }
        }
    }
}

fn bus_time(frames: &[Frame]) -> Duration {
    frames.iter().fold(Duration::ZERO, |t, f| {
        t + timing::frame_duration(f, BITRATE)
    })
}

/// The frames of a block download with nothing lost: the protocol's minimum.
fn block_frames(data: &[u8]) -> Vec<Frame> {
    let (rx, tx) = (Id::Standard(0x605), Id::Standard(0x585));
    let mut v = vec![
        Frame::from_array(
            rx,
            Request::BlockDownloadInitiate {
                index: DOMAIN,
                sub: 0,
                crc: true,
                size: Some(data.len() as u32),
            }
            .encode(),
        ),
        Frame::from_array(
            tx,
            Response::BlockDownloadInitiate {
                index: DOMAIN,
                sub: 0,
                crc: true,
                blksize: 127,
            }
            .encode(),
        ),
    ];
    let n = block::segments(data.len());
    for i in 0..n {
        let mut d = [0u8; 7];
        let chunk = &data[i * 7..((i + 1) * 7).min(data.len())];
        d[..chunk.len()].copy_from_slice(chunk);
        let seqno = (i % 127) as u8 + 1;
        let last = i + 1 == n;
        v.push(Frame::from_array(
            rx,
            BlockSegment {
                seqno,
                last,
                data: d,
            }
            .encode(),
        ));
        if seqno == 127 || last {
            let ack = Response::BlockDownloadAck {
                ackseq: seqno,
                blksize: 127,
            };
            v.push(Frame::from_array(tx, ack.encode()));
        }
    }
    let end = Request::BlockDownloadEnd {
        unused: block::unused(data.len()),
        crc: crc::crc16(data),
    };
    v.push(Frame::from_array(rx, end.encode()));
    v.push(Frame::from_array(tx, Response::BlockDownloadEnd.encode()));
    v
}

/// The frames of a segmented download: one round trip per 7 bytes.
fn segmented_frames(data: &[u8]) -> Vec<Frame> {
    let (rx, tx) = (Id::Standard(0x605), Id::Standard(0x585));
    let init = Request::InitiateDownload {
        index: DOMAIN,
        sub: 0,
        init: Init::Segmented {
            size: Some(data.len() as u32),
        },
    };
    let mut v = vec![
        Frame::from_array(rx, init.encode()),
        Frame::from_array(
            tx,
            Response::InitiateDownload {
                index: DOMAIN,
                sub: 0,
            }
            .encode(),
        ),
    ];
    let n = data.chunks(7).count();
    for (i, c) in data.chunks(7).enumerate() {
        let toggle = i % 2 == 1;
        let seg = Request::DownloadSegment {
            toggle,
            data: SegmentData::from_slice(c),
            last: i + 1 == n,
        };
        v.push(Frame::from_array(rx, seg.encode()));
        v.push(Frame::from_array(
            tx,
            Response::DownloadSegment { toggle }.encode(),
        ));
    }
    v
}

fn print_simulated_throughput() {
    let payload = data(64 * 1024);
    let kib = |d: Duration| payload.len() as f64 / 1024.0 / (d.as_micros() as f64 / 1e6);
    for (mode, frames) in [
        (TransferMode::Block, block_frames(&payload)),
        (TransferMode::Segmented, segmented_frames(&payload)),
    ] {
        let took = simulated(mode, &payload);
        let limit = bus_time(&frames);
        println!(
            "sdo {mode:?} download of 64 KiB at 1 Mbit/s (simulated): {:.1} KiB/s in {took}; \
             bus limit of the protocol {:.1} KiB/s ({limit}, {} frames): {:.1} %",
            kib(took),
            kib(limit),
            frames.len(),
            100.0 * limit.as_micros() as f64 / took.as_micros() as f64,
        );
    }
}

// ----- CPU cost per segment -----

/// A transfer recorded frame by frame: what the client sent and what the server answered.
struct Recording {
    from_client: Vec<Frame>,
    from_server: Vec<Frame>,
}

fn record(start: impl FnOnce(&mut SdoClient)) -> Recording {
    let mut n = server();
    let mut c: SdoClient = SdoClient::new(70_000);
    n.write(Instant::ZERO, DOMAIN, 0, &data(889)).unwrap();
    start(&mut c);
    let mut rec = Recording {
        from_client: vec![],
        from_server: vec![],
    };
    loop {
        let mut moved = false;
        while let Some(f) = c.poll_transmit() {
            moved = true;
            rec.from_client.push(f);
            n.handle_frame(Instant::ZERO, &f);
        }
        while let Some(f) = n.poll_transmit() {
            moved = true;
            rec.from_server.push(f);
            c.handle_frame(Instant::ZERO, &f);
        }
        if !moved {
            break;
        }
    }
    assert!(c.poll_event().unwrap().result.is_ok());
    rec
}

fn download(mode: TransferMode, len: usize) -> impl FnOnce(&mut SdoClient) {
    move |c| {
        c.download(
            Instant::ZERO,
            S,
            DOMAIN,
            0,
            &data(len),
            SdoOptions::mode(mode),
        )
        .unwrap();
    }
}

fn upload(mode: TransferMode) -> impl FnOnce(&mut SdoClient) {
    move |c| {
        c.upload(Instant::ZERO, S, DOMAIN, 0, SdoOptions::mode(mode))
            .unwrap();
    }
}

/// 889 bytes: 127 segments, one full sub-block.
const SEGMENTS: u64 = 127;

fn server_per_segment(c: &mut Criterion) {
    let mut g = c.benchmark_group("sdo_server");
    g.throughput(Throughput::Elements(SEGMENTS));
    for (name, start) in [
        (
            "block_download_per_segment",
            download(TransferMode::Block, 889),
        ),
        (
            "segmented_download_per_segment",
            download(TransferMode::Segmented, 889),
        ),
    ] {
        let rec = record(start);
        let mut n = server();
        g.bench_function(name, |b| {
            b.iter(|| {
                for f in &rec.from_client {
                    n.handle_frame(Instant::ZERO, black_box(f));
                    while let Some(out) = n.poll_transmit() {
                        black_box(out);
                    }
                }
                while n.poll_event().is_some() {}
            })
        });
        // Every replay was a complete, successful transfer.
        let st = n.sdo_server().stats();
        assert!(
            st.completed > 0 && st.aborted == 0 && st.client_aborts == 0,
            "{name}: {st:?}"
        );
    }
    for (name, start) in [
        ("block_upload_per_segment", upload(TransferMode::Block)),
        (
            "segmented_upload_per_segment",
            upload(TransferMode::Segmented),
        ),
    ] {
        let rec = record(start);
        let mut n = server();
        n.write(Instant::ZERO, DOMAIN, 0, &data(889)).unwrap();
        g.bench_function(name, |b| {
            b.iter(|| {
                for f in &rec.from_client {
                    n.handle_frame(Instant::ZERO, black_box(f));
                    while let Some(out) = n.poll_transmit() {
                        black_box(out);
                    }
                }
            })
        });
        let st = n.sdo_server().stats();
        assert!(st.completed > 0 && st.aborted == 0, "{name}: {st:?}");
    }
    g.finish();
}

fn client_per_segment(c: &mut Criterion) {
    let mut g = c.benchmark_group("sdo_client");
    g.throughput(Throughput::Elements(SEGMENTS));
    type Start = Box<dyn Fn(&mut SdoClient)>;
    let cases: [(&str, Start); 4] = [
        (
            "block_upload_per_segment",
            Box::new(|c| upload(TransferMode::Block)(c)),
        ),
        (
            "segmented_upload_per_segment",
            Box::new(|c| upload(TransferMode::Segmented)(c)),
        ),
        (
            "block_download_per_segment",
            Box::new(|c| download(TransferMode::Block, 889)(c)),
        ),
        (
            "segmented_download_per_segment",
            Box::new(|c| download(TransferMode::Segmented, 889)(c)),
        ),
    ];
    for (name, start) in cases {
        let rec = record(&start);
        let mut client: SdoClient = SdoClient::new(70_000);
        g.bench_function(name, |b| {
            b.iter(|| {
                start(&mut client);
                while let Some(out) = client.poll_transmit() {
                    black_box(out);
                }
                for f in &rec.from_server {
                    client.handle_frame(Instant::ZERO, black_box(f));
                    while let Some(out) = client.poll_transmit() {
                        black_box(out);
                    }
                }
                black_box(client.poll_event().expect("result"));
            })
        });
        let st = client.stats();
        assert!(st.completed > 0 && st.failed == 0, "{name}: {st:?}");
    }
    g.finish();
}

criterion_group!(benches, server_per_segment, client_per_segment);

fn main() {
    print_simulated_throughput();
    benches();
    Criterion::default().configure_from_args().final_summary();
}
