//! A master and slaves wired together by hand: every frame a machine writes reaches every other
//! machine at the instant it was written, and is logged.

use duocan::cia305::{LssAddress, LssMaster, LssMasterEvent, LssSlave, LssSlaveEvent};
use duocan::frame::instant::earliest;
use duocan::od::parameters::MemoryStorage;
use duocan::{Frame, Instant, Machine};

pub type Slave = LssSlave<MemoryStorage<16>>;

/// A slave with a 16-byte medium.
pub fn slave(address: LssAddress, node: u8) -> Slave {
    LssSlave::new(address, node).with_storage(MemoryStorage::new())
}

pub fn addr(vendor: u32, product: u32, revision: u32, serial: u32) -> LssAddress {
    LssAddress {
        vendor,
        product,
        revision,
        serial,
    }
}

/// The master, the slaves, the log of `(µs, frame)` and the slaves' events by slave.
pub struct Wire {
    pub master: LssMaster,
    pub slaves: Vec<Slave>,
    pub log: Vec<(u64, Frame)>,
    pub events: Vec<LssMasterEvent>,
    pub slave_events: Vec<(usize, LssSlaveEvent)>,
    pub now: Instant,
}

impl Wire {
    pub fn new(master: LssMaster, slaves: Vec<Slave>) -> Self {
        Wire {
            master,
            slaves,
            log: Vec::new(),
            events: Vec::new(),
            slave_events: Vec::new(),
            now: Instant::ZERO,
        }
    }

    /// Moves every frame written to every other machine, at `now`.
    pub fn exchange(&mut self) {
        self.exchange_with(&mut |_| None);
    }

    /// [`Wire::exchange`], but right after the master writes a request, and before any slave
    /// answers it, the master gets the frame `inject` makes of it (by its data bytes), if any,
    /// at the same instant (a stray: not logged).
    pub fn exchange_with(&mut self, inject: &mut dyn FnMut(&[u8]) -> Option<Frame>) {
        loop {
            let mut moved = false;
            while let Some(f) = self.master.poll_transmit() {
                moved = true;
                self.log.push((self.now.as_micros(), f));
                for s in &mut self.slaves {
                    s.handle_frame(self.now, &f);
                }
                if let Some(stray) = inject(f.data()) {
                    self.master.handle_frame(self.now, &stray);
                }
            }
            for i in 0..self.slaves.len() {
                while let Some(f) = self.slaves[i].poll_transmit() {
                    moved = true;
                    self.log.push((self.now.as_micros(), f));
                    self.master.handle_frame(self.now, &f);
                    for (j, s) in self.slaves.iter_mut().enumerate() {
                        if j != i {
                            s.handle_frame(self.now, &f);
                        }
                    }
                }
            }
            self.drain();
            if !moved {
                return;
            }
        }
    }

    fn drain(&mut self) {
        self.events
            .extend(std::iter::from_fn(|| self.master.poll_event()));
        for (i, s) in self.slaves.iter_mut().enumerate() {
            while let Some(e) = s.poll_event() {
                self.slave_events.push((i, e));
            }
        }
    }

    /// The next deadline of any machine.
    pub fn deadline(&self) -> Option<Instant> {
        self.slaves.iter().fold(self.master.poll_timeout(), |d, s| {
            earliest(d, s.poll_timeout())
        })
    }

    /// Runs until no machine has anything left to do (at most `limit` deadlines).
    pub fn run(&mut self, limit: usize) {
        self.run_with(limit, |_| None);
    }

    /// [`Wire::run`], with strays where `inject` makes them ([`Wire::exchange_with`]).
    pub fn run_with(&mut self, limit: usize, mut inject: impl FnMut(&[u8]) -> Option<Frame>) {
        self.exchange_with(&mut inject);
        for _ in 0..limit {
            let Some(at) = self.deadline() else { return };
            self.now = self.now.max(at);
            self.master.handle_timeout(self.now);
            for s in &mut self.slaves {
                s.handle_timeout(self.now);
            }
            self.exchange_with(&mut inject);
        }
        panic!("still running after {limit} deadlines");
    }

    /// The data bytes of the logged frames.
    pub fn data(&self) -> Vec<(u32, Vec<u8>)> {
        self.log
            .iter()
            .map(|(_, f)| (f.id().raw(), f.data().to_vec()))
            .collect()
    }

    /// The master's events since the last call, by kind.
    pub fn take_events(&mut self) -> Vec<duocan::cia305::LssMasterEventKind> {
        self.events.drain(..).map(|e| e.kind).collect()
    }
}

/// A request frame of the master.
pub fn req(data: [u8; 8]) -> Frame {
    Frame::from_array(duocan::Id::Standard(0x7E5), data)
}

/// An answer frame of a slave.
pub fn ans(data: [u8; 8]) -> Frame {
    Frame::from_array(duocan::Id::Standard(0x7E4), data)
}

/// Feeds `frames` to a lone slave at `now` and returns what it answered.
pub fn feed<S: duocan::od::parameters::ParameterStorage>(
    s: &mut LssSlave<S>,
    now: Instant,
    frames: &[Frame],
) -> Vec<[u8; 8]> {
    let mut out = Vec::new();
    for f in frames {
        s.handle_frame(now, f);
        while let Some(a) = s.poll_transmit() {
            assert_eq!(a.id().raw(), 0x7E4);
            out.push(a.data().try_into().unwrap());
        }
    }
    out
}
