//! A zero-latency bus between one SDO client and a few nodes, with optional frame loss: drives
//! SDO transfers without bus timing (the simulated bus covers timing).
#![allow(dead_code)]

use duocan::od::{comm, Access, DataType, DynamicDictionary, Limit, ObjectDef};
use duocan::sdo::{SdoClient, SdoEvent};
use duocan::{AbortCode, Frame, Instant, Machine, Node, NodeConfig, NodeId};

pub type TestNode = Node<DynamicDictionary>;

/// DOMAIN, rw, 64 KiB + 16.
pub const DOMAIN: u16 = 0x2000;
/// VISIBLE_STRING, rw, 20 bytes.
pub const STRING: u16 = 0x2001;
/// UNSIGNED32 rw with limits 10..=1000 at sub 0; sub 1 ro, sub 2 wo, sub 3 const.
pub const VALUES: u16 = 0x2002;
/// UNSIGNED16 rw with a hook that refuses odd values with 0x08000021.
pub const HOOKED: u16 = 0x2003;
/// UNSIGNED64 rw.
pub const WIDE: u16 = 0x2004;
/// DOMAIN, rw, 100 bytes.
pub const SMALL_DOMAIN: u16 = 0x2005;
/// UNSIGNED32 rw whose hook refuses every value but 0 with the value as abort code.
pub const VETO: u16 = 0x2006;

pub const DOMAIN_CAP: u32 = 64 * 1024 + 16;

/// The application refuses a write with whatever code the value names.
fn veto_with_code(_: u16, _: u8, d: &[u8]) -> Result<(), AbortCode> {
    match u32::from_le_bytes([d[0], d[1], d[2], d[3]]) {
        0 => Ok(()),
        code => Err(AbortCode(code)),
    }
}

fn even_only(_: u16, _: u8, d: &[u8]) -> Result<(), AbortCode> {
    if d[0].is_multiple_of(2) {
        Ok(())
    } else {
        Err(AbortCode::LOCAL_CONTROL)
    }
}

/// A slave with the standard dictionary and the test entries above.
pub fn server(id: u8) -> TestNode {
    let mut od = comm::standard_dictionary(id, comm::Identity::default());
    od.insert_all(&[
        ObjectDef::bytes(DOMAIN, 0, DataType::Domain, DOMAIN_CAP),
        ObjectDef::bytes(STRING, 0, DataType::VisibleString, 20),
        ObjectDef::u8(VALUES, 0, Access::Const, 3),
        ObjectDef::u32(VALUES, 1, Access::Ro, 7),
        ObjectDef::u32(VALUES, 2, Access::Wo, 0),
        ObjectDef::u32(VALUES, 3, Access::Rw, 100)
            .limits(Limit::Unsigned(10), Limit::Unsigned(1000)),
        ObjectDef::u16(HOOKED, 0, Access::Rw, 0).hook(even_only),
        ObjectDef::new(WIDE, 0, DataType::Unsigned64),
        ObjectDef::bytes(SMALL_DOMAIN, 0, DataType::Domain, 100),
        ObjectDef::u32(VETO, 0, Access::Rw, 0).hook(veto_with_code),
    ])
    .unwrap();
    Node::new(NodeConfig::slave(NodeId::new(id).unwrap()), od)
}

/// [`server`] booted, its boot-up taken off the bus: ready for requests frame by frame.
pub fn booted_server(id: u8) -> TestNode {
    let mut n = server(id);
    n.boot(Instant::ZERO);
    while n.poll_transmit().is_some() {}
    n
}

pub type Lose = Box<dyn FnMut(&Frame) -> bool>;
pub type Check = Box<dyn FnMut(&SdoClient, &[TestNode])>;

pub struct Net {
    pub now: Instant,
    pub client: SdoClient,
    pub nodes: Vec<TestNode>,
    /// Every frame put on the bus (lost ones included), with the sender: `None` = client.
    pub log: Vec<(Instant, Option<usize>, Frame)>,
    pub events: Vec<SdoEvent>,
    pub lose: Option<Lose>,
    /// After every delivered frame: checks that must hold at all times.
    pub check: Option<Check>,
}

impl Net {
    pub fn new(ids: &[u8]) -> Self {
        let mut net = Net {
            now: Instant::ZERO,
            client: SdoClient::new(duocan::sdo::DEFAULT_LIMIT + 16),
            nodes: ids.iter().map(|i| server(*i)).collect(),
            log: vec![],
            events: vec![],
            lose: None,
            check: None,
        };
        for n in &mut net.nodes {
            n.boot(Instant::ZERO);
        }
        net.flush();
        net.log.clear();
        net
    }

    fn lost(&mut self, f: &Frame) -> bool {
        self.lose.as_mut().is_some_and(|l| l(f))
    }

    /// Delivers everything pending at `now` until quiet.
    pub fn flush(&mut self) {
        loop {
            let mut moved = false;
            while let Some(f) = self.client.poll_transmit() {
                moved = true;
                self.log.push((self.now, None, f));
                if self.lost(&f) {
                    continue;
                }
                for n in &mut self.nodes {
                    n.handle_frame(self.now, &f);
                }
                self.checks();
            }
            for i in 0..self.nodes.len() {
                while let Some(f) = self.nodes[i].poll_transmit() {
                    moved = true;
                    self.log.push((self.now, Some(i), f));
                    if self.lost(&f) {
                        continue;
                    }
                    self.client.handle_frame(self.now, &f);
                    for j in 0..self.nodes.len() {
                        if j != i {
                            self.nodes[j].handle_frame(self.now, &f);
                        }
                    }
                    self.checks();
                }
                while self.nodes[i].poll_event().is_some() {}
            }
            while let Some(e) = self.client.poll_event() {
                self.events.push(e);
            }
            if !moved {
                break;
            }
        }
    }

    fn checks(&mut self) {
        if let Some(c) = self.check.as_mut() {
            c(&self.client, &self.nodes);
        }
    }

    fn next_deadline(&self) -> Option<Instant> {
        self.nodes
            .iter()
            .filter_map(|n| n.poll_timeout())
            .chain(self.client.poll_timeout())
            .min()
    }

    /// Runs timers up to `t`.
    pub fn run_until(&mut self, t: Instant) {
        self.flush();
        while let Some(d) = self.next_deadline().filter(|d| *d <= t) {
            self.now = self.now.max(d);
            let now = self.now;
            if self.client.poll_timeout().is_some_and(|x| x <= now) {
                self.client.handle_timeout(now);
            }
            for n in &mut self.nodes {
                if n.poll_timeout().is_some_and(|x| x <= now) {
                    n.handle_timeout(now);
                }
            }
            self.flush();
        }
        self.now = self.now.max(t);
    }

    /// Runs until the client has no transfer left (timers included); returns the new events.
    pub fn finish(&mut self) -> Vec<SdoEvent> {
        let start = self.events.len();
        self.flush();
        let mut guard = 0;
        while self.client.in_flight() > 0 {
            let d = self
                .next_deadline()
                .expect("a transfer is running, so some timer must be armed");
            self.run_until(d);
            guard += 1;
            assert!(guard < 1_000_000, "no progress");
        }
        self.events[start..].to_vec()
    }

    /// Frames after the `from`-th, as (sender, bytes).
    pub fn frames_since(&self, from: usize) -> Vec<(Option<usize>, Vec<u8>)> {
        self.log[from..]
            .iter()
            .map(|(_, s, f)| (*s, f.data().to_vec()))
            .collect()
    }
}
