//! SDO traffic: the active master reads the slaves' dictionaries by SDO all the time, over the
//! redundant link like every other frame, and every transfer it starts is followed to its end.
//!
//! Every [`PERIOD`] the active master starts a job on the next slave (boards and observer in
//! turn): mostly an expedited upload of a board constant, repeated back to back one to three
//! times (the same request and the same answer again, within the layers' skew window: the
//! merge's repeat handling at work), every [`SEGMENTED_EVERY`]th a segmented upload of a
//! 21-byte string. The frames are the oracle's like any others (exactly once at every device);
//! the [`Ledger`] keeps each transfer's start and end for the run's check: each ends, completed
//! or aborted with a reason, within [`SDO_BOUND`], and none times out while a bus connected
//! the master and the server for the whole transfer ([`crate::run`] judges it against the
//! fault timeline).

use crate::plant::{Clocked, MasterStation};
use duocan::machine::{PortRequest, StationEvent};
use duocan::sdo::{SdoErrorKind, SdoOptions, TransferMode};
use duocan::{AbortCode, Device, Duration, Frame, Instant, NodeId};
use duocan_redundancy::supervisor::flying_master::MasterRole;
use duocan_redundancy::SupervisorEvent;
use std::cell::RefCell;
use std::ops::{Deref, DerefMut};
use std::rc::Rc;

/// A new job this often while the master is active.
pub const PERIOD: Duration = Duration::from_millis(50);
/// Every this many jobs, a segmented upload.
pub const SEGMENTED_EVERY: u32 = 8;
/// The constant read expedited (a board's), and the string read segmented.
pub const EXPEDITED: (u16, u8) = (0x2000, 1);
pub const SEGMENTED: (u16, u8) = (0x2001, 0);
pub const STRING: &[u8] = b"duocan campaign board";
/// The producer heartbeat time's object (written by [`crate::faults::Fault::ProducerTime`]).
pub const PRODUCER_TIME: u16 = 0x1017;
/// Each answer is waited for this long.
pub const TIMEOUT: Duration = Duration::from_millis(500);
/// A transfer ends within this: a transfer to a slave being booted waits for the boot's
/// (its configuration, a few SDO round trips, each up to a timeout), then its own answers
/// (a segmented upload: four, each up to a timeout).
pub const SDO_BOUND: Duration = Duration::from_millis(6_000);

/// How a transfer ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum End {
    /// Completed, the data right.
    Done,
    /// Completed with other data than the server holds.
    WrongData,
    /// No answer of its own within the timeout.
    Timeout,
    /// Aborted for another reason (the server's or the client's abort code).
    Aborted(Option<AbortCode>),
}

/// One transfer a master started.
#[derive(Clone, Copy, Debug)]
pub struct Transfer {
    /// The master's node-ID, and its life (rebuilds) when it started it.
    pub master: u8,
    pub life: u32,
    pub server: u8,
    pub segmented: bool,
    /// Simulated time.
    pub start: Instant,
    pub end: Option<(Instant, End)>,
}

/// Every transfer the masters started, not yet judged; the counts of those judged.
#[derive(Default, Debug)]
pub struct Ledger {
    pub open: Vec<Transfer>,
    pub completed: u64,
    pub timeouts: u64,
    pub aborted: u64,
    /// Transfers gone with their master (it died or rebooted meanwhile).
    pub lost: u64,
    /// Requests the client refused (busy: a transfer of its own boot process to that slave).
    pub refused: u64,
    /// Per master node-ID (index `id − 1`): its life, counted up at each rebuild.
    pub lives: [u32; 2],
    /// Producer times downloaded and confirmed, not yet told to the oracle: (board, when).
    pub producer_writes: Vec<(u8, Instant)>,
}

/// A master's station with its SDO application: starts the jobs, notes their results.
pub struct Sdo {
    pub dev: Clocked<MasterStation>,
    id: u8,
    life: u32,
    ledger: Rc<RefCell<Ledger>>,
    /// Slaves read, in turn.
    slaves: Vec<u8>,
    jobs: u32,
    next: Instant,
    /// The transfer running (its request), and reads of the same object still to do.
    running: Option<duocan::sdo::RequestId>,
    repeats: u32,
    now: Instant,
    /// A download of a producer heartbeat time (node, ms) to do next, while active
    /// ([`crate::faults::Fault::ProducerTime`]).
    pub producer: Option<(u8, u16)>,
    /// Producer times downloaded and confirmed.
    pub producer_done: u32,
}

impl Sdo {
    pub fn new(
        dev: Clocked<MasterStation>,
        id: u8,
        slaves: Vec<u8>,
        at: Instant,
        ledger: &Rc<RefCell<Ledger>>,
    ) -> Self {
        let life = ledger.borrow().lives[(id - 1) as usize];
        Sdo {
            dev,
            id,
            life,
            ledger: ledger.clone(),
            slaves,
            jobs: 0,
            next: at + PERIOD,
            running: None,
            repeats: 0,
            now: at,
            producer: None,
            producer_done: 0,
        }
    }

    /// Starts what is due at `now` (simulated time).
    fn start_due(&mut self, now: Instant) {
        self.now = now;
        if self.running.is_some() || now < self.next {
            return;
        }
        if self.dev.inner.machine.role() != MasterRole::Active {
            self.repeats = 0;
            self.next = now + PERIOD;
            return;
        }
        if let Some((server, ms)) = self.producer.take() {
            // The application gives a board a new heartbeat period through the master.
            let opts = SdoOptions::mode(TransferMode::Expedited).with_timeout(TIMEOUT);
            let t = self.dev.read(now);
            let r = self.dev.inner.machine.sdo_mut().download(
                t,
                NodeId::must(server),
                PRODUCER_TIME,
                0,
                &ms.to_le_bytes(),
                opts,
            );
            if let Ok(req) = r {
                self.running = Some(req);
                self.ledger.borrow_mut().open.push(Transfer {
                    master: self.id,
                    life: self.life,
                    server,
                    segmented: false,
                    start: now,
                    end: None,
                });
                return;
            }
        }
        let job = self.jobs;
        let server = self.slaves[job as usize % self.slaves.len()];
        let segmented = self.repeats == 0 && job % SEGMENTED_EVERY == SEGMENTED_EVERY - 1;
        let (index, sub) = if segmented { SEGMENTED } else { EXPEDITED };
        let mode = if segmented {
            TransferMode::Segmented
        } else {
            TransferMode::Expedited
        };
        let opts = SdoOptions::mode(mode).with_timeout(TIMEOUT);
        let t = self.dev.read(now);
        let r = self
            .dev
            .inner
            .machine
            .sdo_mut()
            .upload(t, NodeId::must(server), index, sub, opts);
        match r {
            Ok(req) => {
                self.running = Some(req);
                self.ledger.borrow_mut().open.push(Transfer {
                    master: self.id,
                    life: self.life,
                    server,
                    segmented,
                    start: now,
                    end: None,
                });
            }
            Err(_) => {
                self.ledger.borrow_mut().refused += 1;
                self.repeats = 0;
                self.next_job(now);
            }
        }
    }

    fn next_job(&mut self, now: Instant) {
        self.jobs += 1;
        self.next = now + PERIOD;
    }

    fn ended(&mut self, e: &duocan::sdo::SdoEvent) {
        if self.running != Some(e.request) {
            return;
        }
        self.running = None;
        let end = match &e.result {
            Ok(_) if e.index == PRODUCER_TIME => {
                self.producer_done += 1;
                let board = e.node.raw();
                self.ledger
                    .borrow_mut()
                    .producer_writes
                    .push((board, self.now));
                End::Done
            }
            Ok(_) => {
                let want: &[u8] = if e.index == SEGMENTED.0 {
                    STRING
                } else {
                    &[0xA5, 0x5A]
                };
                if e.data() == Some(want) {
                    End::Done
                } else {
                    End::WrongData
                }
            }
            Err(err) => match err.kind {
                // The client's timeout, and the same after an answer to another object (a
                // stale one) came meanwhile: no answer of its own in time either way.
                SdoErrorKind::Client(AbortCode::TIMEOUT | AbortCode::PARAMETER_INCOMPATIBLE) => {
                    End::Timeout
                }
                _ => End::Aborted(err.code()),
            },
        };
        let now = self.now;
        if let Some(t) = self
            .ledger
            .borrow_mut()
            .open
            .iter_mut()
            .rev()
            .find(|t| t.master == self.id && t.life == self.life && t.end.is_none())
        {
            t.end = Some((now, end));
        }
        // The same read again at once, or the next job after the period.
        if end == End::Done && self.repeats > 0 {
            self.repeats -= 1;
            self.next = now;
        } else {
            self.next_job(now);
            self.repeats = if self.jobs % SEGMENTED_EVERY == SEGMENTED_EVERY - 1 {
                0
            } else {
                self.jobs % 3
            };
        }
    }
}

impl Deref for Sdo {
    type Target = Clocked<MasterStation>;
    fn deref(&self) -> &Self::Target {
        &self.dev
    }
}
impl DerefMut for Sdo {
    fn deref_mut(&mut self) -> &mut Self::Target {
        &mut self.dev
    }
}

impl Device for Sdo {
    type Event = <Clocked<MasterStation> as Device>::Event;
    fn port_count(&self) -> usize {
        self.dev.port_count()
    }
    fn handle_rx(&mut self, now: Instant, port: usize, frame: &Frame) {
        self.now = now;
        self.dev.handle_rx(now, port, frame);
    }
    fn handle_rx_at(&mut self, now: Instant, port: usize, frame: &Frame, at: Instant) {
        self.now = now;
        self.dev.handle_rx_at(now, port, frame, at);
    }
    fn handle_port_status(&mut self, now: Instant, port: usize, status: duocan::PortStatus) {
        self.now = now;
        self.dev.handle_port_status(now, port, status);
    }
    fn handle_timeout(&mut self, now: Instant) {
        self.dev.handle_timeout(now);
        self.start_due(now);
    }
    fn poll_transmit(&mut self) -> Option<(usize, Frame)> {
        self.dev.poll_transmit()
    }
    fn poll_port_request(&mut self) -> Option<(usize, PortRequest)> {
        self.dev.poll_port_request()
    }
    fn poll_timeout(&self) -> Option<Instant> {
        let own = self.running.is_none().then_some(self.next.max(self.now));
        match (self.dev.poll_timeout(), own) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }
    fn poll_event(&mut self) -> Option<Self::Event> {
        let e = self.dev.poll_event()?;
        if let StationEvent::Machine(SupervisorEvent::Sdo(s)) = &e {
            self.ended(s);
        }
        Some(e)
    }
}
