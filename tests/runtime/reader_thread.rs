//! A port read by a thread of its own (`Port::reader`, as SocketCAN ports are): every frame in
//! order, answers written by the thread, frames the device sends on a command written by the
//! task in their own order, a failed port re-opened with a new thread only after the old one
//! stopped, a re-initialisation the device asks for done the same way, and the thread gone
//! after a shutdown.

use super::rig::{queue, Probe};
use duocan::machine::PortStatus;
use duocan::port::{
    Port, PortCounters, PortError, PortErrorKind, PortInput, PortReader, READER_WAIT,
};
use duocan::runtime::{Handle, Runtime, RuntimeEvent};
use duocan::{Frame, Id};
use std::collections::VecDeque;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc::{channel, Receiver, RecvTimeoutError, Sender};
use std::sync::{Arc, Mutex};
use std::time::Duration;

const PING: u16 = 0x100;
const PONG: u16 = 0x101;
const MARK: u16 = 0x200;

/// What the test sees of the port: frames written (and by whom), readers made and alive.
#[derive(Default)]
struct Seen {
    written: Mutex<Vec<(Frame, &'static str)>>,
    readers: AtomicUsize,
    alive: AtomicUsize,
    /// Most readers alive at once.
    most: AtomicUsize,
    reopened: AtomicUsize,
    /// Flushes of a batching reader that sent something.
    flushes: AtomicUsize,
}

/// Inputs for the port: a frame, or a failure of the port.
type Feed = Result<Frame, ()>;

struct ThreadedPort {
    counters: PortCounters,
    feed: Arc<Mutex<Receiver<Feed>>>,
    seen: Arc<Seen>,
    lent: bool,
    batched: bool,
}

struct Reader {
    feed: Arc<Mutex<Receiver<Feed>>>,
    seen: Arc<Seen>,
    /// Reads what is queued in one go and keeps what is written until a flush, as the
    /// SocketCAN port's `recvmmsg` and `sendmmsg` do.
    batched: bool,
    ready: VecDeque<Frame>,
    kept: Vec<Frame>,
}

impl Drop for Reader {
    fn drop(&mut self) {
        self.seen.alive.fetch_sub(1, Ordering::SeqCst);
    }
}

impl PortReader for Reader {
    fn read(&mut self) -> Result<Option<PortInput>, PortError> {
        if let Some(f) = self.ready.pop_front() {
            return Ok(Some(PortInput::Frame(f, None)));
        }
        let feed = self.feed.lock().unwrap();
        let first = match feed.recv_timeout(READER_WAIT) {
            Ok(Ok(f)) => f,
            Ok(Err(())) => {
                return Err(PortError::new("thr0", PortErrorKind::InterfaceDown, "read"))
            }
            Err(RecvTimeoutError::Timeout | RecvTimeoutError::Disconnected) => return Ok(None),
        };
        // A failure queued behind is left for the next read, as a batch ends at an error.
        while self.batched && self.ready.len() < 16 {
            match feed.try_recv() {
                Ok(Ok(f)) => self.ready.push_back(f),
                Ok(Err(())) => {
                    drop(feed);
                    self.feed = Arc::new(Mutex::new(failed_feed()));
                    break;
                }
                Err(_) => break,
            }
        }
        Ok(Some(PortInput::Frame(first, None)))
    }
    fn read_ready(&mut self) -> Option<PortInput> {
        self.ready.pop_front().map(|f| PortInput::Frame(f, None))
    }
    fn write(&mut self, f: &Frame) -> Result<bool, PortError> {
        if self.batched {
            self.kept.push(*f);
        } else {
            self.seen.written.lock().unwrap().push((*f, "thread"));
        }
        Ok(true)
    }
    fn flush(&mut self) -> Result<bool, PortError> {
        if !self.kept.is_empty() {
            let mut w = self.seen.written.lock().unwrap();
            w.extend(self.kept.drain(..).map(|f| (f, "thread")));
            self.seen.flushes.fetch_add(1, Ordering::SeqCst);
        }
        Ok(true)
    }
}

/// A feed that has only a failure in it.
fn failed_feed() -> Receiver<Feed> {
    let (tx, rx) = channel();
    tx.send(Err(())).unwrap();
    rx
}

impl Port for ThreadedPort {
    fn name(&self) -> &str {
        "thr0"
    }
    fn counters(&self) -> PortCounters {
        self.counters.clone()
    }
    async fn recv(&mut self) -> Result<PortInput, PortError> {
        panic!("a port read by its thread is not read through recv")
    }
    async fn send(&mut self, f: &Frame) -> Result<(), PortError> {
        self.seen.written.lock().unwrap().push((*f, "task"));
        Ok(())
    }
    async fn reopen(&mut self) -> Result<(), PortError> {
        self.seen.reopened.fetch_add(1, Ordering::SeqCst);
        self.lent = false;
        Ok(())
    }
    fn reader(&mut self) -> Option<Box<dyn PortReader>> {
        if std::mem::replace(&mut self.lent, true) {
            return None;
        }
        self.seen.readers.fetch_add(1, Ordering::SeqCst);
        let alive = self.seen.alive.fetch_add(1, Ordering::SeqCst) + 1;
        self.seen.most.fetch_max(alive, Ordering::SeqCst);
        Some(Box::new(Reader {
            feed: self.feed.clone(),
            seen: self.seen.clone(),
            batched: self.batched,
            ready: VecDeque::new(),
            kept: Vec::new(),
        }))
    }
}

fn start() -> (Handle<Probe>, Sender<Feed>, Arc<Seen>) {
    start_with(false)
}

fn start_with(batched: bool) -> (Handle<Probe>, Sender<Feed>, Arc<Seen>) {
    let (tx, rx) = channel();
    let seen = Arc::new(Seen::default());
    let port = ThreadedPort {
        counters: PortCounters::new(),
        feed: Arc::new(Mutex::new(rx)),
        seen: seen.clone(),
        lent: false,
        batched,
    };
    let handle = Runtime::new(Probe::echo(PING, PONG))
        .port(port)
        .spawn()
        .unwrap();
    (handle, tx, seen)
}

fn ping(i: u32) -> Frame {
    Frame::new(Id::Standard(PING), &i.to_le_bytes()).unwrap()
}

/// A frame the device sends on a command: the task writes it.
fn mark(i: u32) -> Frame {
    Frame::new(Id::Standard(MARK), &i.to_le_bytes()).unwrap()
}

/// Waits (5 s at most) until `n` frames were written; returns them.
async fn written(seen: &Seen, n: usize) -> Vec<(Frame, &'static str)> {
    for _ in 0..500 {
        if seen.written.lock().unwrap().len() >= n {
            break;
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    seen.written.lock().unwrap().clone()
}

/// The numbers carried by the written frames of `id`, in the order written.
fn numbers(w: &[(Frame, &'static str)], id: u16) -> Vec<u32> {
    w.iter()
        .filter(|(f, _)| f.id() == Id::Standard(id))
        .map(|(f, _)| u32::from_le_bytes(f.data()[..4].try_into().unwrap()))
        .collect()
}

/// The port was re-opened once, read by a new thread that started after the old one stopped.
fn re_opened_once_one_reader_at_a_time(seen: &Seen) {
    assert_eq!(seen.reopened.load(Ordering::SeqCst), 1);
    assert_eq!(seen.readers.load(Ordering::SeqCst), 2);
    assert_eq!(
        seen.most.load(Ordering::SeqCst),
        1,
        "never two readers at once"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_frame_is_answered_in_order_by_the_reader_thread() {
    let (handle, feed, seen) = start();
    answered_in_order(&handle, &feed, &seen).await;
}

/// A port that reads several frames per system call and sends their answers together: the
/// same frames in the same order, the task's marks never inside a batch's answers, and the
/// answers sent in fewer flushes than frames.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_batching_port_answers_every_frame_in_order() {
    let (handle, feed, seen) = start_with(true);
    answered_in_order(&handle, &feed, &seen).await;
    let flushes = seen.flushes.load(Ordering::SeqCst);
    assert!(
        (1..2000).contains(&flushes),
        "{flushes} flushes for 2000 answers"
    );
}

async fn answered_in_order(handle: &Handle<Probe>, feed: &Sender<Feed>, seen: &Seen) {
    for i in 0..2000u32 {
        feed.send(Ok(ping(i))).unwrap();
        if i % 100 == 0 {
            // A frame the device sends on a command: the task writes it.
            queue(handle, [mark(i)]).await;
        }
    }
    let w = written(seen, 2020).await;
    assert_eq!(w.len(), 2020, "every ping answered, every mark sent, once");
    assert_eq!(numbers(&w, PONG), (0..2000).collect::<Vec<_>>());
    assert_eq!(
        numbers(&w, MARK),
        (0..2000).step_by(100).collect::<Vec<_>>()
    );
    let by_thread = w.iter().filter(|(_, by)| *by == "thread").count();
    assert!(
        by_thread >= 1900,
        "answers go out from the thread that read: {by_thread} of 2020"
    );
    handle.shutdown().await;
}

/// A failed port with a batching reader: the frames read before the failure are answered, and
/// the re-opened port's thread answers the next.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_batching_port_fails_and_comes_back() {
    let (handle, feed, seen) = start_with(true);
    for i in 0..5 {
        feed.send(Ok(ping(i))).unwrap();
    }
    feed.send(Err(())).unwrap();
    assert_eq!(numbers(&written(&seen, 5).await, PONG), [0, 1, 2, 3, 4]);
    for _ in 0..500 {
        if seen.reopened.load(Ordering::SeqCst) == 1 {
            break;
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    feed.send(Ok(ping(5))).unwrap();
    assert_eq!(numbers(&written(&seen, 6).await, PONG), [0, 1, 2, 3, 4, 5]);
    re_opened_once_one_reader_at_a_time(&seen);
    handle.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_failed_port_gets_a_new_thread_after_the_old_one_stopped() {
    let (handle, feed, seen) = start();
    let mut events = handle.subscribe();
    feed.send(Ok(ping(1))).unwrap();
    assert_eq!(numbers(&written(&seen, 1).await, PONG), [1]);
    feed.send(Err(())).unwrap();
    let mut statuses = Vec::new();
    while statuses.len() < 2 {
        match tokio::time::timeout(Duration::from_secs(5), events.recv()).await {
            Ok(Ok(RuntimeEvent::Port { status, .. })) => statuses.push(status),
            Ok(_) => {}
            Err(_) => panic!("no port status after the failure: {statuses:?}"),
        }
    }
    assert!(matches!(statuses[0], PortStatus::Down(_)), "{statuses:?}");
    assert_eq!(statuses[1], PortStatus::Up);
    feed.send(Ok(ping(2))).unwrap();
    assert_eq!(numbers(&written(&seen, 2).await, PONG), [1, 2]);
    re_opened_once_one_reader_at_a_time(&seen);
    handle.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_re_initialisation_stops_the_thread_before_the_port_is_re_opened() {
    let (handle, feed, seen) = start();
    feed.send(Ok(ping(1))).unwrap();
    written(&seen, 1).await;
    // The re-init, then a mark queued behind it: the mark goes out on the re-opened port.
    handle.call(|d, _| d.reinit = true).await.unwrap();
    queue(&handle, [mark(7)]).await;
    let w = written(&seen, 2).await;
    assert_eq!(numbers(&w, MARK), [7]);
    feed.send(Ok(ping(2))).unwrap();
    assert_eq!(numbers(&written(&seen, 3).await, PONG), [1, 2]);
    re_opened_once_one_reader_at_a_time(&seen);
    handle.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_reader_thread_stops_with_the_runtime() {
    let (handle, feed, seen) = start();
    feed.send(Ok(ping(1))).unwrap();
    written(&seen, 1).await;
    assert_eq!(seen.alive.load(Ordering::SeqCst), 1);
    handle.shutdown().await;
    // It looks every READER_WAIT whether the runtime still runs.
    for _ in 0..100 {
        if seen.alive.load(Ordering::SeqCst) == 0 {
            break;
        }
        tokio::time::sleep(READER_WAIT / 5).await;
    }
    assert_eq!(seen.alive.load(Ordering::SeqCst), 0, "the thread is gone");
    // What comes after is read by nobody.
    let _ = feed.send(Ok(ping(2)));
    tokio::time::sleep(READER_WAIT * 2).await;
    assert_eq!(numbers(&seen.written.lock().unwrap(), PONG), [1]);
}
