//! The master's table of per-node slots ([`Slot`]), sized by
//! [`MasterConfig::max_slaves`](super::MasterConfig::max_slaves) and allocated once when the
//! master is built.
//!
//! A slot is about 250 bytes (the slave's configuration, its boot process, its timers): one for
//! each of the 127 node-IDs is 31 KB, most of a small master's heap when it runs a handful of
//! slaves. So the table holds `max_slaves` slots and an index from node-ID to slot:
//!
//! - at 127 (the default) every node-ID has its slot from the start, as a host's master always
//!   had: what the master notes of nodes that are not slaves (boot-ups, states commanded) is
//!   kept for them too;
//! - below, a node gets a slot when it becomes a slave (configured, added, or assigned through
//!   0x1F81) and keeps it; one beyond the table is an error
//!   ([`MasterError::TooManySlaves`](super::MasterError::TooManySlaves)), never growth. Nodes
//!   without a slot read as a blank one, and what the master would note of them is dropped:
//!   their [`SlaveView`](super::SlaveView) shows their state as heard, no boot-up count.

use super::events::MasterError;
use super::slaves::Slot;
use crate::frame::cob_id::NodeId;
use alloc::boxed::Box;
use alloc::vec::Vec;

/// The highest node-ID: one slot each at most.
pub(super) const ALL: usize = 127;
/// Marks a node-ID without a slot in the index.
const NONE: u8 = u8::MAX;

/// The slots and the index from node-ID to slot.
pub(super) struct SlotTable {
    /// Slot of node-ID n at `index[n - 1]`, or [`NONE`].
    index: [u8; ALL],
    /// Allocated once at `capacity`, never grown.
    slots: Vec<Slot>,
    capacity: usize,
    /// What absorbs the writes about a node without a slot (reset before each use); on the
    /// heap, so that the master, which is moved while it is built, stays small.
    scratch: Box<Slot>,
}

/// What a node without a slot reads.
static BLANK: Slot = Slot::new(NodeId::must(1));

impl SlotTable {
    /// A table of `capacity` slots (at most 127); at 127 every node-ID has its slot now.
    pub(super) fn new(capacity: usize) -> SlotTable {
        let capacity = capacity.min(ALL);
        let mut t = SlotTable {
            index: [NONE; ALL],
            slots: Vec::with_capacity(capacity),
            capacity,
            scratch: Box::new(Slot::new(NodeId::must(1))),
        };
        if capacity == ALL {
            for n in (1..=ALL as u8).filter_map(NodeId::new) {
                let _ = t.give(n);
            }
        }
        t
    }

    /// How many slots the table holds at most.
    pub(super) fn capacity(&self) -> usize {
        self.capacity
    }

    /// `n`'s slot, if it has one.
    #[inline]
    pub(super) fn get(&self, n: NodeId) -> Option<&Slot> {
        self.slots.get(self.index[n.raw() as usize - 1] as usize)
    }

    /// `n`'s slot, if it has one.
    #[inline]
    pub(super) fn get_mut(&mut self, n: NodeId) -> Option<&mut Slot> {
        self.slots
            .get_mut(self.index[n.raw() as usize - 1] as usize)
    }

    /// `n`'s slot, or the blank one.
    #[inline]
    pub(super) fn read(&self, n: NodeId) -> &Slot {
        self.get(n).unwrap_or(&BLANK)
    }

    /// `n`'s slot, given now if it has none; `None` when the table is full.
    pub(super) fn give(&mut self, n: NodeId) -> Option<&mut Slot> {
        let i = n.raw() as usize - 1;
        if self.index[i] == NONE {
            if self.slots.len() >= self.capacity {
                return None;
            }
            self.index[i] = self.slots.len() as u8;
            self.slots.push(Slot::new(n));
        }
        self.slots.get_mut(self.index[i] as usize)
    }

    /// `n`'s slot, given now if it has none; the error names `n` when the table is full.
    pub(super) fn claim(&mut self, n: NodeId) -> Result<&mut Slot, MasterError> {
        let capacity = self.capacity;
        self.give(n)
            .ok_or(MasterError::TooManySlaves { node: n, capacity })
    }

    /// `n`'s slot, or a blank one whose writes go nowhere if it has none.
    pub(super) fn write(&mut self, n: NodeId) -> &mut Slot {
        match self.index[n.raw() as usize - 1] {
            NONE => {
                *self.scratch = Slot::new(n);
                &mut self.scratch
            }
            i => &mut self.slots[i as usize],
        }
    }

    /// How many slots are given.
    pub(super) fn len(&self) -> usize {
        self.slots.len()
    }

    /// The node of the `i`-th slot given, and the slot.
    pub(super) fn at_mut(&mut self, i: usize) -> (NodeId, &mut Slot) {
        let s = &mut self.slots[i];
        (s.cfg.node, s)
    }

    /// Every slot given.
    pub(super) fn iter(&self) -> core::slice::Iter<'_, Slot> {
        self.slots.iter()
    }

    /// Every slot given.
    pub(super) fn iter_mut(&mut self) -> core::slice::IterMut<'_, Slot> {
        self.slots.iter_mut()
    }
}
