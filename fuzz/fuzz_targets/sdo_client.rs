//! An SDO client with transfers under way (expedited, segmented and block, up and down, to
//! three servers, and one streamed through a bounded window to a fourth) fed random answers and
//! time steps (steps back, an hour ahead and the end of time among them: the clock contract): no
//! panic, bounded output, the streamed transfer never holds more than its window, every request
//! ends (result or abort) once its timeout has passed.
#![no_main]

mod common;

use duocan::sdo::stream::MIN_WINDOW;
use duocan::sdo::{HeapBuffer, SdoClient, SdoOptions, TransferMode};
use duocan::{Duration, Frame, Id, Instant, Machine, NodeId};
use libfuzzer_sys::fuzz_target;

const LIMIT: usize = 4096;
/// The streamed transfer's window: the smallest, so that the bound is reached often.
const WINDOW: usize = MIN_WINDOW;

fuzz_target!(|data: &[u8]| {
    let Some((&setup, rest)) = data.split_first() else {
        return;
    };
    let mut c: SdoClient<HeapBuffer, 4> = SdoClient::with_limit(LIMIT);
    let timeout = Duration::from_millis(100);
    let mut started = 0;
    for k in 0..3u8 {
        let node = NodeId::must(5 + k);
        let mode = match (setup >> (2 * k)) & 3 {
            0 => TransferMode::Expedited,
            1 => TransferMode::Segmented,
            _ => TransferMode::Block,
        };
        let opts = SdoOptions::default().with_mode(mode).with_timeout(timeout);
        let ok = if setup & (0x40 << (k & 1)) == 0 {
            c.upload(Instant::ZERO, node, 0x2000, k, opts).is_ok()
        } else {
            c.download(Instant::ZERO, node, 0x2000, k, &[k; 900], opts)
                .is_ok()
        };
        started += usize::from(ok);
    }
    // The fourth server: a streamed transfer, its size announced or not, up or down.
    let mode = if setup & 0x80 == 0 {
        TransferMode::Segmented
    } else {
        TransferMode::Block
    };
    let opts = SdoOptions::default().with_mode(mode).with_timeout(timeout);
    let node = NodeId::must(8);
    let size = (setup & 0x10 != 0).then_some(3000);
    let streamed = if setup & 0x20 == 0 {
        c.upload_stream(Instant::ZERO, node, 0x2001, 0, WINDOW, opts)
    } else {
        c.download_stream(Instant::ZERO, node, 0x2001, 0, size, WINDOW, opts)
    };
    started += usize::from(streamed.is_ok());
    let mut fed = 0usize;
    let mut sink = [0u8; 700];
    let mut now = Instant::ZERO;
    let mut ended = 0;
    for chunk in rest.chunks_exact(11) {
        let [who, dlc, step, d @ ..] = chunk else {
            continue;
        };
        now = common::misbehave(now, *step)
            .unwrap_or_else(|| now + Duration::from_millis(u64::from(*step % 32)));
        let id = Id::Standard(0x585 + u16::from(*who % 4));
        if let Ok(f) = Frame::new(id, &d[..usize::from(*dlc % 9)]) {
            c.handle_frame(now, &f);
        }
        if c.poll_timeout().is_some_and(|t| t <= now) {
            c.handle_timeout(now);
        }
        let mut k = 0;
        while c.poll_transmit().is_some() {
            k += 1;
            assert!(k <= 4 * 128, "unbounded client output");
        }
        while c.poll_event().is_some() {
            ended += 1;
        }
        // The streamed transfer's caller: feeds or reads as much as this step's byte says.
        if let Ok(req) = streamed {
            let _ = c.poll_stream();
            let n = usize::from(*step) * 4;
            if c.wants_data(req) > 0 && fed < 3000 {
                let take = n.min(3000 - fed).min(512);
                let last = size.is_none() && step & 1 == 1;
                if let Some(k) = c.feed(now, req, &[0x5A; 512][..take], last) {
                    fed += k;
                }
            }
            let _ = c.read_stream(now, req, &mut sink[..n.min(700)]);
            assert!(
                c.max_buffer_len() <= LIMIT,
                "a buffer above the client's limit"
            );
            if let Some((done, Some(total))) = c.stream_progress(req) {
                assert!(
                    done <= total,
                    "more moved than announced: {done} of {total}"
                );
            }
        }
    }
    // A clock that ended comes back (the driver reports the step with one `handle_timeout`); long
    // after every timeout, nothing is left under way.
    now = common::sane(now);
    c.handle_timeout(now);
    // Each round is long after the last: a sub-block the driver had not taken when its timeout
    // came starts its wait over (a slow bus, not a silent server), and then times out.
    for _ in 0..8 {
        now += Duration::from_secs(10);
        if c.poll_timeout().is_some_and(|t| t <= now) {
            c.handle_timeout(now);
        }
        while c.poll_transmit().is_some() {}
        while c.poll_event().is_some() {
            ended += 1;
        }
    }
    assert_eq!(ended, started, "every request ends exactly once");
    assert!(c.poll_timeout().is_none(), "no deadline without a transfer");
});
