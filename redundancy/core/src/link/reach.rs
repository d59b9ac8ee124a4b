//! Per-node, per-bus reachability: "node 0x12 heard on bus 2 only" is a fault worth reporting
//! even when the application sees no interruption.
//!
//! A node is heard on a bus when a frame identifying it as the sender (heartbeat, boot-up,
//! EMCY, TPDO, SDO response: see [`crate::link::classify::FrameClassifier::sender`]) arrived on that
//! port within the timeout. A change is reported at once when a bus starts hearing a node again,
//! and exactly at last frame + timeout when it stops. A node heard for the first time (or again
//! after being heard nowhere) is reported one settle time later, so that the twin on the other
//! bus has arrived and the report says "both" instead of flapping.

use crate::link::events::{LinkEvent, LinkEventKind};
use crate::link::outbox::Outbox;
use duocan_core::{Duration, Instant, NodeId};

const NEVER: u64 = u64::MAX;
const NODES: usize = 128;

/// A node's state: not heard yet, heard and waiting for its first report (due at its entry of
/// `due`, kept apart so that this is two bytes), or reported with the ports it is heard on.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Status {
    Unknown,
    Pending,
    Reported { mask: u8 },
}

/// The reachability table.
#[derive(Clone, Debug)]
pub struct Reach {
    timeout: u64,
    settle: u64,
    last: [[u64; 2]; NODES],
    status: [Status; NODES],
    /// When a pending node is reported (meaningless for the others).
    due: [u64; NODES],
    next_check: Option<u64>,
}

impl Reach {
    /// A table reporting a bus lost for a node after `timeout` without a frame of it, and new
    /// nodes `settle` after they are first heard.
    #[must_use]
    pub fn new(timeout: Duration, settle: Duration) -> Self {
        Reach {
            timeout: timeout.as_micros(),
            settle: settle.as_micros(),
            last: [[NEVER; 2]; NODES],
            status: [Status::Unknown; NODES],
            due: [NEVER; NODES],
            next_check: None,
        }
    }

    /// Changes the settle time (the layer keeps it at the merge window, which follows a
    /// lagging bus: the time the other copy may take).
    pub(crate) fn set_settle(&mut self, settle: Duration) {
        self.settle = settle.as_micros();
    }

    /// The caller's clock stepped back `by` (the clock contract, see [`crate::link`]): the
    /// times each node was last heard and the deadlines move back with it.
    #[cold]
    pub(crate) fn step_back(&mut self, by: Duration) {
        let by = by.as_micros();
        let back = |t: &mut u64| {
            if *t != NEVER {
                *t = t.saturating_sub(by);
            }
        };
        // Two loops, not `flatten`: its iterator adapter costs the bare-metal images flash.
        for node in self.last.iter_mut() {
            for t in node.iter_mut() {
                back(t);
            }
        }
        for (s, due) in self.status.iter().zip(self.due.iter_mut()) {
            if *s == Status::Pending {
                back(due);
            }
        }
        if let Some(t) = self.next_check.as_mut() {
            back(t);
        }
    }

    /// Ports `node` is currently reported heard on, `None` if not reported yet.
    pub fn heard(&self, node: NodeId) -> Option<[bool; 2]> {
        match self.status[node.raw() as usize] {
            Status::Reported { mask } => Some([mask & 1 != 0, mask & 2 != 0]),
            _ => None,
        }
    }

    /// Last frame of `node` on port `p`.
    pub fn last_heard(&self, node: NodeId, p: usize) -> Option<Instant> {
        let t = self.last[node.raw() as usize][p.min(1)];
        (t != NEVER).then_some(Instant::from_micros(t))
    }

    /// Every reported node with the ports it is heard on.
    pub fn iter(&self) -> impl Iterator<Item = (NodeId, [bool; 2])> + '_ {
        (1..NODES as u8).filter_map(|n| {
            let id = NodeId::new(n)?;
            Some((id, self.heard(id)?))
        })
    }

    /// A frame of `node` arrived on port `p`. On the frame path of every frame with a sender.
    #[inline]
    pub(crate) fn on_heard(&mut self, now: Instant, node: NodeId, p: usize, out: &mut Outbox) {
        let n = node.raw() as usize;
        // A frame at the end of time is not "never heard".
        let t = now.as_micros().min(NEVER - 1);
        self.last[n][p] = t;
        match self.status[n] {
            Status::Unknown | Status::Reported { mask: 0 } => {
                let due = t.saturating_add(self.settle);
                self.status[n] = Status::Pending;
                self.due[n] = due;
                self.wake(due);
            }
            Status::Pending => {}
            Status::Reported { mask } => {
                if mask & (1 << p) == 0 {
                    let mask = mask | (1 << p);
                    self.status[n] = Status::Reported { mask };
                    emit(out, now, node, mask);
                }
                self.wake(t.saturating_add(self.timeout));
            }
        }
    }

    fn wake(&mut self, t: u64) {
        self.next_check = Some(self.next_check.map_or(t, |c| c.min(t)));
    }

    fn mask_at(&self, n: usize, t: u64) -> u8 {
        let mut m = 0;
        for p in 0..2 {
            let l = self.last[n][p];
            if l != NEVER && t.saturating_sub(l) < self.timeout {
                m |= 1 << p;
            }
        }
        m
    }

    /// Earliest deadline (may be early: a sweep then finds nothing to do).
    #[must_use]
    pub fn poll_timeout(&self) -> Option<Instant> {
        self.next_check.map(Instant::from_micros)
    }

    /// Reports every change due at `now` (each at its own deadline) and recomputes the next
    /// deadline.
    pub(crate) fn handle_timeout(&mut self, now: Instant, out: &mut Outbox) {
        let t = now.as_micros();
        if self.next_check.is_none_or(|c| c > t) {
            return;
        }
        let mut next: Option<u64> = None;
        for n in 1..NODES {
            let Some(node) = NodeId::new(n as u8) else {
                continue;
            };
            match self.status[n] {
                Status::Unknown | Status::Reported { mask: 0 } => {}
                Status::Pending => {
                    let due = self.due[n];
                    if due <= t {
                        let mask = self.mask_at(n, due);
                        self.status[n] = Status::Reported { mask };
                        emit(out, Instant::from_micros(due), node, mask);
                        self.report_falls(n, node, t, out);
                    }
                }
                Status::Reported { .. } => self.report_falls(n, node, t, out),
            }
            let due = match self.status[n] {
                Status::Pending => Some(self.due[n]),
                Status::Reported { mask } => (0..2)
                    .filter(|p| mask & (1 << p) != 0)
                    .map(|p| self.last[n][p].saturating_add(self.timeout))
                    .min(),
                Status::Unknown => None,
            };
            if let Some(d) = due {
                next = Some(next.map_or(d, |x| x.min(d)));
            }
        }
        self.next_check = next;
    }

    /// Reports each bus lost for node `n` up to `t`, at the instant it was lost.
    fn report_falls(&mut self, n: usize, node: NodeId, t: u64, out: &mut Outbox) {
        while let Status::Reported { mask } = self.status[n] {
            let fall = (0..2)
                .filter(|p| mask & (1 << p) != 0)
                .map(|p| (self.last[n][p].saturating_add(self.timeout), p))
                .min();
            match fall {
                Some((at, p)) if at <= t => {
                    let mask = mask & !(1 << p);
                    self.status[n] = Status::Reported { mask };
                    emit(out, Instant::from_micros(at), node, mask);
                }
                _ => break,
            }
        }
    }
}

fn emit(out: &mut Outbox, at: Instant, node: NodeId, mask: u8) {
    out.event(LinkEvent {
        at,
        kind: LinkEventKind::Reach {
            node,
            heard: [mask & 1 != 0, mask & 2 != 0],
        },
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ms(x: u64) -> Instant {
        Instant::from_millis(x)
    }
    fn reach_events(out: &mut Outbox) -> Vec<(Instant, u8, [bool; 2])> {
        let mut v = vec![];
        while let Some(e) = out.events.pop() {
            if let LinkEventKind::Reach { node, heard } = e.kind {
                v.push((e.at, node.raw(), heard));
            }
        }
        v
    }
    fn run(r: &mut Reach, out: &mut Outbox, until: Instant) {
        while let Some(d) = r.poll_timeout().filter(|d| *d <= until) {
            r.handle_timeout(d, out);
        }
    }

    #[test]
    fn node_heard_on_one_bus_only_is_reported_at_the_timeout() {
        let mut r = Reach::new(Duration::from_millis(300), Duration::from_millis(10));
        let mut out = Outbox::new();
        let n = NodeId::must(0x12);
        for i in 0..100u64 {
            let t = ms(i * 10);
            run(&mut r, &mut out, t);
            r.on_heard(t, n, 1, &mut out);
            if i < 50 {
                r.on_heard(t + Duration::from_micros(100), n, 0, &mut out);
            }
        }
        run(&mut r, &mut out, ms(990));
        assert_eq!(
            reach_events(&mut out),
            [
                (ms(10), 0x12, [true, true]),
                (
                    ms(490) + Duration::from_micros(100) + Duration::from_millis(300),
                    0x12,
                    [false, true]
                ),
            ]
        );
        assert_eq!(r.heard(n), Some([false, true]));
        // Bus 1 hears it again: reported at once.
        r.on_heard(ms(1000), n, 0, &mut out);
        assert_eq!(reach_events(&mut out), [(ms(1000), 0x12, [true, true])]);
        // Silent everywhere: both falls reported at their instants, then a reboot settles.
        run(&mut r, &mut out, ms(5000));
        assert_eq!(
            reach_events(&mut out),
            [
                (ms(1290), 0x12, [true, false]),
                (ms(1300), 0x12, [false, false])
            ]
        );
        r.on_heard(ms(6000), n, 0, &mut out);
        r.on_heard(ms(6001), n, 1, &mut out);
        run(&mut r, &mut out, ms(6100));
        assert_eq!(reach_events(&mut out), [(ms(6010), 0x12, [true, true])]);
    }
}
