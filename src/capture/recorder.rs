//! Recording what a device sees: every port, and the logical bus above the dual-bus layer.
//!
//! A [`Tap`] is told of each frame with where and when it was seen. The runtime feeds it every
//! frame a port received or sent (`Runtime::tap`, feature `tokio`); wrapping the
//! machine of a [`Station`](crate::Station) in [`Tapped`] feeds it the logical bus (what the
//! stack above the dual-bus layer receives and sends). [`Recorder`] is the tap that writes
//! candump logs and pcap files; clone its `Arc` into both places.

use super::candump::CandumpWriter;
use super::pcap::PcapWriter;
use crate::frame::instant::Instant;
use crate::frame::Frame;
use crate::machine::Machine;
use std::io::{self, Write};
use std::sync::{Arc, Mutex};
use std::time::{SystemTime, UNIX_EPOCH};

/// Where a frame was seen.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TapPoint {
    /// On port `n` (a physical bus).
    Port(usize),
    /// On the logical bus (above the dual-bus layer).
    Logical,
}

/// Which way the frame went, seen from the device.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TapDirection {
    /// Received.
    Rx,
    /// Sent.
    Tx,
}

/// Something told of every frame at a tap point.
pub trait Tap: Send + Sync {
    /// A frame was seen at `point` going `dir`, at `at` (the driver's clock).
    fn frame(&self, at: Instant, point: TapPoint, dir: TapDirection, frame: &Frame);
}

/// Which frames a sink records.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Filter {
    /// Everything from every tap point.
    All,
    /// Only this tap point.
    Point(TapPoint),
}

impl Filter {
    fn matches(&self, p: TapPoint) -> bool {
        match self {
            Filter::All => true,
            Filter::Point(q) => *q == p,
        }
    }
}

enum Writer {
    Candump(CandumpWriter<Box<dyn Write + Send>>),
    Pcap(PcapWriter<Box<dyn Write + Send>>),
}

struct Sink {
    filter: Filter,
    writer: Writer,
}

struct Inner {
    sinks: Vec<Sink>,
    errors: u64,
}

/// Writes tapped frames to candump logs and pcap files.
pub struct Recorder {
    epoch_us: u64,
    names: Vec<String>,
    logical: String,
    inner: Mutex<Inner>,
}

impl Recorder {
    /// A recorder whose instant zero is now on the wall clock.
    #[must_use]
    pub fn new() -> Self {
        let now = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map(|d| d.as_micros() as u64)
            .unwrap_or(0);
        Self::with_epoch(now)
    }
    /// A recorder whose instant zero is `epoch_us` µs after the Unix epoch (fixed, for
    /// reproducible captures of simulated runs).
    #[must_use]
    pub fn with_epoch(epoch_us: u64) -> Self {
        Recorder {
            epoch_us,
            names: Vec::new(),
            logical: "logical".into(),
            inner: Mutex::new(Inner {
                sinks: Vec::new(),
                errors: 0,
            }),
        }
    }
    /// Interface names for the candump log, by port index (default `can0`, `can1`, …).
    #[must_use]
    pub fn port_names<S: Into<String>>(mut self, names: impl IntoIterator<Item = S>) -> Self {
        self.names = names.into_iter().map(Into::into).collect();
        self
    }
    /// Interface name of the logical bus in the candump log (default `logical`).
    #[must_use]
    pub fn logical_name(mut self, name: impl Into<String>) -> Self {
        self.logical = name.into();
        self
    }
    /// Adds a candump log of the frames `filter` selects.
    #[must_use]
    pub fn candump(self, filter: Filter, out: impl Write + Send + 'static) -> Self {
        self.add(Sink {
            filter,
            writer: Writer::Candump(CandumpWriter::new(Box::new(out))),
        })
    }
    /// Adds a pcap file of the frames `filter` selects (use one tap point per file).
    pub fn pcap(self, filter: Filter, out: impl Write + Send + 'static) -> io::Result<Self> {
        let w = PcapWriter::new(Box::new(out) as Box<dyn Write + Send>)?;
        Ok(self.add(Sink {
            filter,
            writer: Writer::Pcap(w),
        }))
    }
    fn add(self, sink: Sink) -> Self {
        if let Ok(mut i) = self.inner.lock() {
            i.sinks.push(sink);
        }
        self
    }
    /// Flushes every sink.
    pub fn flush(&self) -> io::Result<()> {
        let Ok(mut i) = self.inner.lock() else {
            return Ok(());
        };
        for s in &mut i.sinks {
            match &mut s.writer {
                Writer::Candump(w) => w.flush()?,
                Writer::Pcap(w) => w.flush()?,
            }
        }
        Ok(())
    }
    /// Writes that failed (the recorder never stops the device; it counts).
    pub fn errors(&self) -> u64 {
        self.inner.lock().map(|i| i.errors).unwrap_or(0)
    }
    fn name(&self, p: TapPoint) -> String {
        match p {
            TapPoint::Port(n) => self
                .names
                .get(n)
                .cloned()
                .unwrap_or_else(|| format!("can{n}")),
            TapPoint::Logical => self.logical.clone(),
        }
    }
}

impl Default for Recorder {
    fn default() -> Self {
        Self::new()
    }
}

impl Tap for Recorder {
    fn frame(&self, at: Instant, point: TapPoint, _dir: TapDirection, frame: &Frame) {
        let ts = self.epoch_us.saturating_add(at.as_micros());
        let name = self.name(point);
        let Ok(mut i) = self.inner.lock() else {
            return;
        };
        let mut failed = 0;
        for s in i.sinks.iter_mut().filter(|s| s.filter.matches(point)) {
            let r = match &mut s.writer {
                Writer::Candump(w) => w.write(ts, &name, frame),
                Writer::Pcap(w) => w.write(ts, frame),
            };
            if r.is_err() {
                failed += 1;
            }
        }
        i.errors += failed;
    }
}

/// A machine whose logical bus is tapped: frames it receives and sends are told to the tap.
pub struct Tapped<M> {
    /// The machine.
    pub inner: M,
    tap: Arc<dyn Tap>,
    now: Instant,
}

impl<M> Tapped<M> {
    /// Wraps `inner`.
    #[must_use]
    pub fn new(inner: M, tap: Arc<dyn Tap>) -> Self {
        Tapped {
            inner,
            tap,
            now: Instant::ZERO,
        }
    }
}

impl<M: Machine> Machine for Tapped<M> {
    type Event = M::Event;
    type LinkCommand = M::LinkCommand;
    fn handle_frame(&mut self, now: Instant, frame: &Frame) {
        self.now = now;
        self.tap
            .frame(now, TapPoint::Logical, TapDirection::Rx, frame);
        self.inner.handle_frame(now, frame);
    }
    fn handle_timeout(&mut self, now: Instant) {
        self.now = now;
        self.inner.handle_timeout(now);
    }
    fn poll_transmit(&mut self) -> Option<Frame> {
        let f = self.inner.poll_transmit()?;
        self.tap
            .frame(self.now, TapPoint::Logical, TapDirection::Tx, &f);
        Some(f)
    }
    fn poll_timeout(&self) -> Option<Instant> {
        self.inner.poll_timeout()
    }
    fn poll_event(&mut self) -> Option<M::Event> {
        self.inner.poll_event()
    }
    fn handle_link_request(&mut self, now: Instant, req: crate::machine::LinkRequest) {
        self.inner.handle_link_request(now, req);
    }
    fn poll_link_command(&mut self) -> Option<M::LinkCommand> {
        self.inner.poll_link_command()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::capture::{candump, pcap::PcapReader, Record};
    use crate::frame::Id;

    #[derive(Clone, Default)]
    struct Shared(Arc<Mutex<Vec<u8>>>);
    impl Write for Shared {
        fn write(&mut self, b: &[u8]) -> io::Result<usize> {
            self.0.lock().unwrap().extend_from_slice(b);
            Ok(b.len())
        }
        fn flush(&mut self) -> io::Result<()> {
            Ok(())
        }
    }

    #[test]
    fn records_ports_and_logical_bus_separately() {
        let log = Shared::default();
        let pc = Shared::default();
        let rec = Recorder::with_epoch(1_700_000_000_000_000)
            .port_names(["vcan0", "vcan1"])
            .candump(Filter::All, log.clone())
            .pcap(Filter::Point(TapPoint::Port(1)), pc.clone())
            .unwrap();
        let f = Frame::from_array(Id::Standard(0x701), [5]);
        rec.frame(
            Instant::from_micros(1),
            TapPoint::Port(0),
            TapDirection::Rx,
            &f,
        );
        rec.frame(
            Instant::from_micros(2),
            TapPoint::Port(1),
            TapDirection::Rx,
            &f,
        );
        rec.frame(
            Instant::from_micros(3),
            TapPoint::Logical,
            TapDirection::Rx,
            &f,
        );
        let text = String::from_utf8(log.0.lock().unwrap().clone()).unwrap();
        let lines: Vec<_> = text.lines().collect();
        assert_eq!(
            lines,
            [
                "(1700000000.000001) vcan0 701#05",
                "(1700000000.000002) vcan1 701#05",
                "(1700000000.000003) logical 701#05"
            ]
        );
        let bytes = pc.0.lock().unwrap().clone();
        let pk: Vec<_> = PcapReader::new(&bytes[..]).unwrap().collect();
        assert_eq!(pk.len(), 1);
        assert_eq!(pk[0].as_ref().unwrap().timestamp_us, 1_700_000_000_000_002);
        assert_eq!(pk[0].as_ref().unwrap().record, Record::Frame(f));
        assert!(candump::parse_line(lines[2]).is_ok());
        assert_eq!(rec.errors(), 0);
    }
}
