//! `duocan kit bench`: what the fault bridge itself costs, measured side by side on the same
//! machine in one run: a frame from one socket to another on one interface (the bare path), and
//! the same through the bridge from one interface to another (the bridged path). Latency is
//! send-to-receive time of one frame at a time (median and 99th percentile); throughput is the
//! rate at which frames arrive with at most [`WINDOW`] in flight. The bridge's counters must
//! show no frame lost.

use crate::fail::Fail;
use crate::out::{Cell, Table};
use crate::{ports, Global};
use duocan::bridge::{Bridge, BridgeConfig};
use duocan::port::{Port, PortInput};
use duocan::runtime::Runtime;
use duocan::{Frame, Id};
use serde_json::json;
use std::time::{Duration, Instant};

/// Frames in flight in the throughput run.
pub const WINDOW: u32 = 16;

/// Latency (µs: median, p99) and throughput (frames/s) of one path.
struct Figures {
    median_us: f64,
    p99_us: f64,
    rate: f64,
}

async fn recv_frame<P: Port>(p: &mut P, timeout: Duration) -> Result<Frame, Fail> {
    loop {
        match tokio::time::timeout(timeout, p.recv()).await {
            Err(_) => return Err(Fail::protocol("bench: a frame did not arrive within 1 s")),
            Ok(Err(e)) => return Err(Fail::protocol(format!("bench: {e}"))),
            Ok(Ok(PortInput::Frame(f, _))) => return Ok(f),
            Ok(Ok(_)) => {}
        }
    }
}

fn numbered(i: u32) -> Frame {
    Frame::new(Id::Standard(0x181), &i.to_le_bytes()).unwrap_or_else(|_| {
        Frame::new(Id::Standard(0x181), &[]).expect("an empty frame is always valid")
    })
}

async fn measure<P: Port, Q: Port>(tx: &mut P, rx: &mut Q, n: u32) -> Result<Figures, Fail> {
    let second = Duration::from_secs(1);
    let mut lat = Vec::with_capacity(n as usize);
    for i in 0..n {
        let t = Instant::now();
        tx.send(&numbered(i))
            .await
            .map_err(|e| Fail::protocol(format!("bench: {e}")))?;
        let f = recv_frame(rx, second).await?;
        lat.push(t.elapsed().as_secs_f64() * 1e6);
        if f != numbered(i) {
            return Err(Fail::protocol(format!("bench: frame {i} arrived as {f:?}")));
        }
    }
    lat.sort_by(f64::total_cmp);
    let pick = |q: f64| lat[((lat.len() - 1) as f64 * q) as usize];
    // Throughput: keep WINDOW frames in flight.
    let t = Instant::now();
    let (mut sent, mut got) = (0u32, 0u32);
    while got < n {
        while sent < n && sent - got < WINDOW {
            tx.send(&numbered(sent))
                .await
                .map_err(|e| Fail::protocol(format!("bench: {e}")))?;
            sent += 1;
        }
        let f = recv_frame(rx, second).await?;
        if f != numbered(got) {
            return Err(Fail::protocol(format!(
                "bench: frame {got} arrived as {f:?} (lost or out of order)"
            )));
        }
        got += 1;
    }
    Ok(Figures {
        median_us: pick(0.5),
        p99_us: pick(0.99),
        rate: f64::from(n) / t.elapsed().as_secs_f64(),
    })
}

/// Runs `duocan kit bench`: the bare path on `bare`, the bridged one from `a` to `b`.
pub async fn run(g: &Global, bare: &str, a: &str, b: &str, n: u32) -> Result<(), Fail> {
    let mut tx = ports::open(bare, g.udp_interface)?;
    let mut rx = ports::open(bare, g.udp_interface)?;
    let plain = measure(&mut tx, &mut rx, n).await?;
    drop((tx, rx));

    let bridge =
        Bridge::new(BridgeConfig::new(&[&[a, b]])).map_err(|e| Fail::usage(e.to_string()))?;
    let h = Runtime::new(bridge)
        .name("bridge")
        .port(ports::open(a, g.udp_interface)?)
        .port(ports::open(b, g.udp_interface)?)
        .spawn()
        .map_err(|e| Fail::usage(e.to_string()))?;
    let mut tx = ports::open(a, g.udp_interface)?;
    let mut rx = ports::open(b, g.udp_interface)?;
    let bridged = measure(&mut tx, &mut rx, n).await;
    let counters = h
        .call(|b, _| [b.counters(0).copied(), b.counters(1).copied()])
        .await
        .map_err(|_| Fail::protocol("the bridge stopped"))?;
    h.shutdown().await;
    let bridged = bridged?;
    let lost: u64 = counters
        .iter()
        .flatten()
        .map(|c| c.overflow + c.tx_failed + c.dropped)
        .sum();
    let mut t = Table::new(&["path", "median µs", "p99 µs", "frames/s"]);
    for (name, f) in [("bare", &plain), ("bridged", &bridged)] {
        t.row(vec![
            name.into(),
            Cell::new(format!("{:.1}", f.median_us), f.median_us),
            Cell::new(format!("{:.1}", f.p99_us), f.p99_us),
            Cell::new(format!("{:.0}", f.rate), f.rate),
        ]);
    }
    t.print(g.json);
    let added = bridged.median_us - plain.median_us;
    crate::out::result(
        g.json,
        &format!(
            "the bridge adds {added:.1} µs (median) per frame and carries {:.0} frames/s \
             ({:.2}× the bare path), {n} frames each way, {lost} lost",
            bridged.rate,
            bridged.rate / plain.rate
        ),
        json!({"added_us": added, "bridged_rate": bridged.rate, "ratio": bridged.rate / plain.rate, "frames": n, "lost": lost}),
    );
    if lost > 0 {
        return Err(Fail::protocol(format!("the bridge lost {lost} frame(s)")));
    }
    Ok(())
}
