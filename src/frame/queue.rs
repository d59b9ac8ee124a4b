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
}
