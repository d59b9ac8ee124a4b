//! A zero-latency wire for driving sans-IO machines in tests without bus timing: every frame a
//! machine sends reaches every other machine at the same instant.
#![allow(dead_code)]

use duocan::od::{comm, DynamicDictionary};
use duocan::{Frame, Instant, Machine, Node, NodeConfig, NodeEvent, NodeId};

pub type TestNode = Node<DynamicDictionary>;

/// A standard dictionary node.
pub fn node(id: u8, master: bool) -> TestNode {
    let nid = NodeId::new(id).expect("valid node-ID");
    let od = comm::standard_dictionary(
        id,
        comm::Identity {
            vendor: 0x1234,
            product: id as u32,
            ..Default::default()
        },
    );
    let cfg = if master {
        NodeConfig::master(nid)
    } else {
        NodeConfig::slave(nid)
    };
    Node::new(cfg, od)
}

pub struct Wire {
    pub now: Instant,
    pub nodes: Vec<TestNode>,
    pub alive: Vec<bool>,
    /// Every frame with its time and sender index.
    pub log: Vec<(Instant, usize, Frame)>,
    pub events: Vec<Vec<NodeEvent>>,
}

impl Wire {
    pub fn new(nodes: Vec<TestNode>) -> Self {
        let n = nodes.len();
        Wire {
            now: Instant::ZERO,
            nodes,
            alive: vec![true; n],
            log: vec![],
            events: vec![vec![]; n],
        }
    }

    pub fn boot_all(&mut self) {
        for i in 0..self.nodes.len() {
            self.nodes[i].boot(self.now);
        }
        self.flush();
    }

    /// Delivers everything pending at `now` until quiet.
    pub fn flush(&mut self) {
        loop {
            let mut moved = false;
            for i in 0..self.nodes.len() {
                while let Some(e) = self.nodes[i].poll_event() {
                    self.events[i].push(e);
                }
                if !self.alive[i] {
                    while self.nodes[i].poll_transmit().is_some() {}
                    continue;
                }
                while let Some(f) = self.nodes[i].poll_transmit() {
                    moved = true;
                    self.log.push((self.now, i, f));
                    for j in 0..self.nodes.len() {
                        if j != i && self.alive[j] {
                            self.nodes[j].handle_frame(self.now, &f);
                        }
                    }
                }
            }
            if !moved {
                break;
            }
        }
    }

    pub fn deliver(&mut self, f: Frame) {
        self.log.push((self.now, usize::MAX, f));
        for j in 0..self.nodes.len() {
            if self.alive[j] {
                self.nodes[j].handle_frame(self.now, &f);
            }
        }
        self.flush();
    }

    pub fn run_until(&mut self, t: Instant) {
        self.flush();
        loop {
            let next = (0..self.nodes.len())
                .filter(|i| self.alive[*i])
                .filter_map(|i| self.nodes[i].poll_timeout())
                .min();
            match next {
                Some(d) if d <= t => {
                    self.now = self.now.max(d);
                    for i in 0..self.nodes.len() {
                        if self.alive[i]
                            && self.nodes[i].poll_timeout().is_some_and(|x| x <= self.now)
                        {
                            self.nodes[i].handle_timeout(self.now);
                        }
                    }
                    self.flush();
                }
                _ => break,
            }
        }
        self.now = t;
    }

    /// Frames sent by node `i` (index) on identifier `raw` (standard).
    pub fn sent(&self, i: usize, raw: u16) -> Vec<(Instant, Frame)> {
        self.log
            .iter()
            .filter(|(_, s, f)| *s == i && f.id() == duocan::Id::Standard(raw))
            .map(|(t, _, f)| (*t, *f))
            .collect()
    }
}
