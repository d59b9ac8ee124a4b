//! Streamed transfers (`download_stream`/`feed`, `upload_stream`/`read_stream`): values far
//! larger than the window, in both directions and modes, with the client's buffer checked
//! against the window after every frame.

use crate::net::{Net, DOMAIN, SMALL_DOMAIN};
use duocan::od::ObjectDictionary;
use duocan::sdo::codec::{BlockSegment, Request, Response};
use duocan::sdo::{RequestId, SdoErrorKind, SdoEvent, SdoOptions, TransferMode, MIN_WINDOW};
use duocan::Duration;
use duocan::{AbortCode, Frame, Id, Instant, Machine, NodeId};
use proptest::prelude::*;
use std::cell::Cell;
use std::rc::Rc;

const N: NodeId = NodeId::must(5);

fn pattern(len: usize, seed: u8) -> Vec<u8> {
    (0..len)
        .map(|i| (i as u32).wrapping_mul(2_654_435_761).to_le_bytes()[2] ^ seed)
        .collect()
}

/// Fails the test at the first frame after which the client holds more than `window` bytes;
/// returns the largest buffer seen.
fn bound(net: &mut Net, window: usize) -> Rc<Cell<usize>> {
    let max = Rc::new(Cell::new(0));
    let m = max.clone();
    net.check = Some(Box::new(move |c, _| {
        let len = c.max_buffer_len();
        assert!(len <= window, "buffer {len} above the window {window}");
        m.set(m.get().max(len));
    }));
    max
}

/// Streams `data` to `index` in chunks of at most `chunk`, the size announced or not; returns
/// the result event.
fn download(
    net: &mut Net,
    index: u16,
    data: &[u8],
    known: bool,
    window: usize,
    chunk: usize,
    opts: SdoOptions,
) -> SdoEvent {
    let size = known.then_some(data.len() as u32);
    let id = net
        .client
        .download_stream(net.now, N, index, 0, size, window, opts)
        .unwrap();
    let mut fed = 0;
    let start = net.events.len();
    let mut last_done = 0;
    while net.events.len() == start {
        let room = net.client.wants_data(id).min(chunk);
        if room > 0 || fed == data.len() {
            let n = room.min(data.len() - fed);
            let end = fed + n == data.len();
            if let Some(took) = net.client.feed(net.now, id, &data[fed..fed + n], end) {
                assert_eq!(took, n);
                fed += took;
            }
        }
        net.flush();
        assert_eq!(
            net.client.progress(id),
            None,
            "whole-value progress is not for streams"
        );
        if let Some((done, total)) = net.client.stream_progress(id) {
            assert!(done >= last_done && done <= fed, "progress {done} of {fed}");
            assert_eq!(total, size.map(|n| n as usize));
            last_done = done;
        }
        if net.events.len() == start && net.client.wants_data(id) == 0 && fed == data.len() {
            let d = net.client.poll_timeout().unwrap();
            net.run_until(d);
        }
    }
    net.events[start].clone()
}

/// Streams `index` back, taking at most `chunk` bytes at a time; returns the bytes and the
/// result.
fn upload(
    net: &mut Net,
    index: u16,
    window: usize,
    chunk: usize,
    opts: SdoOptions,
) -> (Vec<u8>, SdoEvent) {
    let id = net
        .client
        .upload_stream(net.now, N, index, 0, window, opts)
        .unwrap();
    let mut got = Vec::new();
    let mut out = vec![0; chunk];
    let start = net.events.len();
    loop {
        net.flush();
        if net.events.len() > start {
            break;
        }
        match net.client.read_stream(net.now, id, &mut out) {
            Some(0) | None => {
                let d = net.client.poll_timeout().unwrap();
                net.run_until(d);
            }
            Some(n) => got.extend_from_slice(&out[..n]),
        }
    }
    let ev = net.events[start].clone();
    got.extend_from_slice(ev.data().unwrap_or(&[]));
    (got, ev)
}

fn modes() -> [(&'static str, SdoOptions); 4] {
    [
        ("segmented", SdoOptions::mode(TransferMode::Segmented)),
        ("block+crc", SdoOptions::mode(TransferMode::Block)),
        (
            "block blksize 5",
            SdoOptions::mode(TransferMode::Block).with_block_size(5),
        ),
        (
            "block no crc",
            SdoOptions::mode(TransferMode::Block).with_crc(false),
        ),
    ]
}

#[test]
fn values_many_windows_long_go_both_ways_through_one_window() {
    let mut net = Net::new(&[5]);
    let max = bound(&mut net, MIN_WINDOW);
    let mut seed = 0;
    for len in [0, 1, 7, 8, 889, 890, 897, 5000, 64 * 1024] {
        for (name, opts) in modes() {
            for known in [true, false] {
                seed += 1;
                let data = pattern(len, seed);
                let ev = download(&mut net, DOMAIN, &data, known, MIN_WINDOW, 300, opts);
                assert!(ev.result.is_ok(), "{len} {name} {known}: {:?}", ev.result);
                assert_eq!(
                    net.nodes[0].od().read(DOMAIN, 0).unwrap(),
                    data,
                    "{len} {name} sized {known}"
                );
                let (got, ev) = upload(&mut net, DOMAIN, MIN_WINDOW, 200, opts);
                assert!(ev.result.is_ok(), "{len} {name}: {:?}", ev.result);
                assert!(got == data, "upload {len} {name}: {} bytes", got.len());
            }
        }
    }
    assert!(max.get() > 800, "the window was used: {}", max.get());
    // Whole-value transfers are untouched: the buffer then holds all of it.
    let data = pattern(5000, 1);
    net.check = None;
    net.client
        .download(net.now, N, DOMAIN, 0, &data, SdoOptions::default())
        .unwrap();
    assert_eq!(net.client.max_buffer_len(), 5000);
    assert!(net.finish()[0].result.is_ok());
}

#[test]
fn a_partial_block_ack_is_answered_from_the_window() {
    let mut net = Net::new(&[5]);
    bound(&mut net, MIN_WINDOW);
    // Lose the 5th and the 200th block segment the client sends: the server acknowledges
    // what came in sequence, and the client sends the rest of the sub-block again, from
    // bytes it still holds although the window moved on many times.
    // (A client frame whose first byte is 1–127 is a block segment that is not the last.)
    let sent = Rc::new(Cell::new(0));
    let s = sent.clone();
    net.lose = Some(Box::new(move |f: &Frame| {
        if f.id() != Id::Standard(0x605) || !(1..=127).contains(&f.data()[0]) {
            return false;
        }
        s.set(s.get() + 1);
        s.get() == 5 || s.get() == 200
    }));
    let data = pattern(20_000, 9);
    let ev = download(
        &mut net,
        DOMAIN,
        &data,
        false,
        MIN_WINDOW,
        1000,
        SdoOptions::mode(TransferMode::Block),
    );
    assert!(ev.result.is_ok(), "{:?}", ev.result);
    assert_eq!(net.nodes[0].od().read(DOMAIN, 0).unwrap(), data);
    // 20 000 bytes are 2858 segments, the last one marked: more went out, the lost ones and
    // the rest of their sub-blocks again.
    assert!(sent.get() > 2857 + 2, "retransmitted: {}", sent.get());
}

/// A hand-driven server for the upload side: the client's frames are checked and answered
/// with exactly the frames a test wants.
fn expect(net: &mut Net, want: Request) {
    let f = net.client.poll_transmit().expect("a request");
    assert_eq!(f.data(), want.encode(), "{want:?}");
}

fn answer(net: &mut Net, d: [u8; 8]) {
    let now = net.now;
    net.client
        .handle_frame(now, &Frame::from_array(Id::Standard(0x585), d));
}

fn block_upload_by_hand(crc_ok: bool) -> (Vec<u8>, SdoEvent) {
    let mut net = Net::new(&[]);
    let data = pattern(3000, 3);
    let id: RequestId = net
        .client
        .upload_stream(
            net.now,
            N,
            0x2000,
            0,
            MIN_WINDOW,
            SdoOptions::mode(TransferMode::Block)
                .with_block_size(100)
                .with_crc(true),
        )
        .unwrap();
    let f = net.client.poll_transmit().unwrap();
    assert_eq!(f.data()[0], 0xA4, "block upload initiate with CRC");
    answer(
        &mut net,
        Response::BlockUploadInitiate {
            index: 0x2000,
            sub: 0,
            crc: true,
            size: Some(3000),
        }
        .encode(),
    );
    expect(&mut net, Request::BlockUploadStart);
    let mut got = Vec::new();
    let mut out = [0u8; 333];
    let segs = data.chunks(7).collect::<Vec<_>>();
    for (k, seg) in segs.iter().enumerate() {
        let mut d = [0u8; 7];
        d[..seg.len()].copy_from_slice(seg);
        let seqno = (k % 100) as u8 + 1;
        let last = k + 1 == segs.len();
        answer(
            &mut net,
            BlockSegment {
                seqno,
                last,
                data: d,
            }
            .encode(),
        );
        if seqno == 100 || last {
            // Take what arrived in odd-sized pieces: the CRC runs over them as they leave.
            while let Some(n) = net
                .client
                .read_stream(net.now, id, &mut out)
                .filter(|n| *n > 0)
            {
                got.extend_from_slice(&out[..n]);
            }
            let f = net.client.poll_transmit().expect("the ack");
            assert_eq!(f.data()[..3], [0xA2, seqno, 100]);
        }
        assert!(net.client.max_buffer_len() <= MIN_WINDOW);
    }
    let crc = duocan::sdo::crc::crc16(&data) ^ u16::from(!crc_ok);
    let unused = (segs.len() * 7 - data.len()) as u8;
    answer(&mut net, Response::BlockUploadEnd { unused, crc }.encode());
    let ev = net.client.poll_event().unwrap();
    got.extend_from_slice(ev.data().unwrap_or(&[]));
    if crc_ok {
        assert_eq!(got, data);
    }
    (got, ev)
}

#[test]
fn the_crc_of_a_streamed_block_upload_is_checked_over_the_chunks() {
    let (_, ev) = block_upload_by_hand(true);
    assert!(ev.result.is_ok(), "{:?}", ev.result);
    let (_, ev) = block_upload_by_hand(false);
    assert_eq!(
        ev.result.unwrap_err().kind,
        SdoErrorKind::Client(AbortCode::CRC_ERROR)
    );
}

/// A server that announced fewer bytes than it sends in a block upload is refused with the
/// segment that goes past the size, before a reader can take any of the excess (found by the
/// `sdo_client` fuzz target: announced 0, then a full segment).
#[test]
fn a_block_upload_past_its_announced_size_is_aborted_at_once() {
    for streamed in [true, false] {
        let mut net = Net::new(&[]);
        let opts = SdoOptions::mode(TransferMode::Block).with_block_size(10);
        let id: RequestId = if streamed {
            net.client
                .upload_stream(net.now, N, 0x2000, 0, MIN_WINDOW, opts)
                .unwrap()
        } else {
            net.client.upload(net.now, N, 0x2000, 0, opts).unwrap()
        };
        net.client.poll_transmit().expect("block upload initiate");
        answer(
            &mut net,
            Response::BlockUploadInitiate {
                index: 0x2000,
                sub: 0,
                crc: false,
                size: Some(10),
            }
            .encode(),
        );
        expect(&mut net, Request::BlockUploadStart);
        // 7 bytes: within the size; 14: past it, though the block is not over.
        for seqno in 1..=2u8 {
            let seg = BlockSegment {
                seqno,
                last: false,
                data: [seqno; 7],
            };
            answer(&mut net, seg.encode());
        }
        let f = net.client.poll_transmit().expect("an abort");
        assert_eq!(
            f.data(),
            [0x80, 0x00, 0x20, 0x00, 0x12, 0x00, 0x07, 0x06],
            "abort 0x06070012, length too high"
        );
        let ev = net.client.poll_event().expect("the result");
        assert_eq!(ev.request, id);
        assert_eq!(
            ev.result.unwrap_err().kind,
            SdoErrorKind::Client(AbortCode::LENGTH_TOO_HIGH)
        );
        let mut out = [0u8; 64];
        assert_eq!(net.client.read_stream(net.now, id, &mut out), None);
    }
}

#[test]
fn a_reader_that_does_not_read_stops_the_server_not_grows_the_buffer() {
    for (name, opts) in modes() {
        let mut net = Net::new(&[5]);
        let data = pattern(20_000, 4);
        net.nodes[0].od_mut().write_local(DOMAIN, 0, &data).unwrap();
        let opts = opts.with_timeout(Duration::from_millis(500));
        let id = net
            .client
            .upload_stream(net.now, N, DOMAIN, 0, MIN_WINDOW, opts)
            .unwrap();
        net.flush();
        let held = net.log.len();
        assert!(net.client.max_buffer_len() <= MIN_WINDOW, "{name}");
        assert!(
            net.client.max_buffer_len() > MIN_WINDOW / 2,
            "{name}: filled"
        );
        assert_eq!(
            net.client.poll_stream(),
            Some(id),
            "{name}: the reader is told"
        );
        net.run_until(Instant::ZERO + Duration::from_millis(300));
        assert_eq!(
            net.log.len(),
            held,
            "{name}: nothing moves while the window is full"
        );
        // Reading lets it go on, and it finishes with every byte.
        let mut got = Vec::new();
        let mut out = [0u8; 4096];
        loop {
            let n = net.client.read_stream(net.now, id, &mut out);
            got.extend_from_slice(&out[..n.unwrap_or(0)]);
            net.flush();
            if let Some(e) = net.events.first() {
                got.extend_from_slice(e.data().unwrap());
                break;
            }
        }
        assert!(got == data, "{name}");
        // A reader that never reads: the transfer times out (the server is told).
        let id = net
            .client
            .upload_stream(net.now, N, DOMAIN, 0, MIN_WINDOW, opts)
            .unwrap();
        let ev = net.finish();
        assert_eq!(
            ev[0].result.as_ref().unwrap_err().kind,
            SdoErrorKind::Client(AbortCode::TIMEOUT),
            "{name}"
        );
        assert_eq!(ev[0].request, id);
    }
}

#[test]
fn a_feeder_that_stops_times_out_with_the_window_full() {
    for (name, opts) in modes() {
        let mut net = Net::new(&[5]);
        bound(&mut net, MIN_WINDOW);
        let id = net
            .client
            .download_stream(net.now, N, DOMAIN, 0, None, MIN_WINDOW, opts)
            .unwrap();
        let fed = net.client.feed(net.now, id, &[9; 5000], false).unwrap();
        assert_eq!(fed, MIN_WINDOW, "{name}: one window's worth");
        let ev = net.finish();
        let e = ev[0].result.as_ref().unwrap_err();
        assert_eq!(e.code(), Some(AbortCode::TIMEOUT), "{name}: {e:?}");
        assert_eq!(
            net.client.feed(net.now, id, &[9; 10], true),
            None,
            "{name}: over"
        );
    }
}

/// A streamed download of 100 bytes, announced.
fn hundred(net: &mut Net) -> RequestId {
    let opts = SdoOptions::default();
    let now = net.now;
    net.client
        .download_stream(now, N, DOMAIN, 0, Some(100), 1000, opts)
        .unwrap()
}

#[test]
fn a_feeder_that_falls_short_of_the_size_aborts_and_too_much_is_refused() {
    let mut net = Net::new(&[5]);
    let id = hundred(&mut net);
    assert_eq!(net.client.wants_data(id), 100, "no more than announced");
    assert_eq!(net.client.feed(net.now, id, &[1; 500], false), Some(100));
    net.finish();
    assert_eq!(net.nodes[0].od().read(DOMAIN, 0).unwrap(), [1; 100]);
    let id = hundred(&mut net);
    assert_eq!(net.client.feed(net.now, id, &[1; 50], true), Some(50));
    let ev = net.finish();
    assert_eq!(
        ev[0].result.as_ref().unwrap_err().kind,
        SdoErrorKind::Client(AbortCode::GENERAL)
    );
    // The entry's own limit is the server's to enforce, as with whole values.
    let ev = download(
        &mut net,
        SMALL_DOMAIN,
        &[2; 300],
        false,
        MIN_WINDOW,
        1000,
        SdoOptions::default(),
    );
    assert!(ev.result.is_err());
    // A window above the client's limit is refused before anything is sent.
    let e = net
        .client
        .upload_stream(net.now, N, DOMAIN, 0, 1 << 30, SdoOptions::default())
        .unwrap_err();
    assert!(matches!(e.kind, SdoErrorKind::TooLong { .. }), "{e:?}");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]
    #[test]
    fn random_sizes_windows_and_block_sizes_round_trip(
        len in 0usize..6000,
        blksize in 1u8..=127,
        extra in 0usize..2000,
        chunk in 1usize..1500,
        block in any::<bool>(),
        known in any::<bool>(),
    ) {
        let mut net = Net::new(&[5]);
        let window = MIN_WINDOW + extra;
        bound(&mut net, window);
        let mode = if block { TransferMode::Block } else { TransferMode::Segmented };
        let opts = SdoOptions::mode(mode).with_block_size(blksize);
        let data = pattern(len, blksize);
        let ev = download(&mut net, DOMAIN, &data, known, window, chunk, opts);
        prop_assert!(ev.result.is_ok(), "{:?}", ev.result);
        prop_assert_eq!(net.nodes[0].od().read(DOMAIN, 0).unwrap(), data.clone());
        let (got, ev) = upload(&mut net, DOMAIN, window, chunk, opts);
        prop_assert!(ev.result.is_ok(), "{:?}", ev.result);
        prop_assert_eq!(got, data);
    }
}
