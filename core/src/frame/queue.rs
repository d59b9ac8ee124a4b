//! A fixed-capacity FIFO that counts what it had to drop instead of growing.

use heapless::Deque;

/// A bounded FIFO. Overflow drops the new item and counts it: memory never grows, and the count
/// tells the application (and the tests) that it happened.
#[derive(Debug)]
pub struct Bounded<T, const N: usize> {
    items: Deque<T, N>,
    dropped: u32,
}

impl<T, const N: usize> Default for Bounded<T, N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T, const N: usize> Bounded<T, N> {
    /// An empty queue.
    #[must_use]
    pub const fn new() -> Self {
        Bounded {
            items: Deque::new(),
            dropped: 0,
        }
    }
    /// Appends; returns false (and counts a drop) when full.
    pub fn push(&mut self, item: T) -> bool {
        match self.items.push_back(item) {
            Ok(()) => true,
            Err(_) => {
                self.dropped = self.dropped.saturating_add(1);
                false
            }
        }
    }
    /// Removes the oldest item.
    pub fn pop(&mut self) -> Option<T> {
        self.items.pop_front()
    }
    /// The oldest item, not removed.
    pub fn peek(&self) -> Option<&T> {
        self.items.front()
    }
    /// Items waiting.
    pub fn len(&self) -> usize {
        self.items.len()
    }
    /// True when nothing waits.
    pub fn is_empty(&self) -> bool {
        self.items.is_empty()
    }
    /// Items dropped on overflow since creation.
    pub fn dropped(&self) -> u32 {
        self.dropped
    }
    /// Discards every waiting item (not counted as drops).
    pub fn clear(&mut self) {
        self.items.clear();
    }
    /// The capacity.
    pub const fn capacity(&self) -> usize {
        N
    }
    /// Iterates oldest first.
    pub fn iter(&self) -> impl Iterator<Item = &T> {
        self.items.iter()
    }
    /// Keeps only the items for which `keep` is true.
    pub fn retain(&mut self, mut keep: impl FnMut(&T) -> bool) {
        let n = self.items.len();
        for _ in 0..n {
            if let Some(x) = self.items.pop_front() {
                if keep(&x) {
                    // Cannot fail: one slot was just freed.
                    let _ = self.items.push_back(x);
                }
            }
        }
    }
}

/// A bounded FIFO whichever storage it lives in ([`Bounded`] inline, [`BoundedHeap`] on the
/// heap): what code generic over a [`Storage`](super::storage::Storage) uses.
pub trait Fifo<T> {
    /// Appends; returns false (and counts a drop) when full.
    fn push(&mut self, item: T) -> bool;
    /// Removes the oldest item.
    fn pop(&mut self) -> Option<T>;
    /// Items waiting.
    fn len(&self) -> usize;
    /// True when nothing waits.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Items dropped on overflow since creation.
    fn dropped(&self) -> u32;
    /// The capacity.
    fn capacity(&self) -> usize;
}

impl<T, const N: usize> Fifo<T> for Bounded<T, N> {
    fn push(&mut self, item: T) -> bool {
        Bounded::push(self, item)
    }
    fn pop(&mut self) -> Option<T> {
        Bounded::pop(self)
    }
    fn len(&self) -> usize {
        Bounded::len(self)
    }
    fn dropped(&self) -> u32 {
        Bounded::dropped(self)
    }
    fn capacity(&self) -> usize {
        N
    }
}

/// A bounded FIFO whose capacity is chosen when it is built (`alloc`): allocated once, never
/// grown; overflow drops the new item and counts it, as with [`Bounded`].
#[cfg(feature = "alloc")]
#[derive(Debug)]
pub struct BoundedHeap<T> {
    items: alloc::collections::VecDeque<T>,
    capacity: usize,
    dropped: u32,
}

#[cfg(feature = "alloc")]
impl<T> BoundedHeap<T> {
    /// An empty queue for `capacity` items, allocated now.
    #[must_use]
    pub fn new(capacity: usize) -> Self {
        BoundedHeap {
            items: alloc::collections::VecDeque::with_capacity(capacity),
            capacity,
            dropped: 0,
        }
    }
    /// The room allocated, in items (at least the capacity; it does not change).
    pub fn allocated(&self) -> usize {
        self.items.capacity()
    }
}

#[cfg(feature = "alloc")]
impl<T> Fifo<T> for BoundedHeap<T> {
    fn push(&mut self, item: T) -> bool {
        // Checked before the push, so the deque never reallocates.
        if self.items.len() >= self.capacity {
            self.dropped = self.dropped.saturating_add(1);
            return false;
        }
        self.items.push_back(item);
        true
    }
    fn pop(&mut self) -> Option<T> {
        self.items.pop_front()
    }
    fn len(&self) -> usize {
        self.items.len()
    }
    fn dropped(&self) -> u32 {
        self.dropped
    }
    fn capacity(&self) -> usize {
        self.capacity
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overflow_is_counted_not_grown() {
        let mut q: Bounded<u32, 2> = Bounded::new();
        assert!(q.push(1));
        assert!(q.push(2));
        assert!(!q.push(3));
        assert_eq!(q.dropped(), 1);
        assert_eq!(q.len(), 2);
        q.retain(|x| *x != 1);
        assert_eq!(q.pop(), Some(2));
        assert_eq!(q.pop(), None);
    }

    #[cfg(feature = "alloc")]
    #[test]
    fn heap_queue_overflow_is_counted_and_the_allocation_stays() {
        let mut q: BoundedHeap<u32> = BoundedHeap::new(3);
        let room = q.allocated();
        for i in 0..10 {
            q.push(i);
        }
        assert_eq!((q.len(), q.dropped(), room), (3, 7, q.allocated()));
        assert_eq!(q.pop(), Some(0));
    }
}
