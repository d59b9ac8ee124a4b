//! Where a fixed-capacity table lives: inline in its owner, sized by a const generic (no
//! allocator), or on the heap, sized once when its owner is built.
//!
//! A protocol machine that holds per-object state (the PDO engine's TPDOs and RPDOs, the SDO
//! client's sessions) is generic over a [`Storage`]. With [`Inline`] (the default) the tables are
//! arrays of the const capacity, exactly as if they were written out: no indirection, no
//! allocator, a size known at compile time (what a `no_std` device asserts its RAM with). With
//! [`Heap`] (`alloc`) the capacity is a run-time value given at construction: a master configured
//! for a hundred RPDOs allocates a hundred, once. Either way the tables never grow: a table's
//! length and a queue's capacity are fixed from construction on, and what does not fit is
//! refused or dropped and counted, as with [`Bounded`].

use super::queue::{Bounded, Fifo};
use core::ops::{Deref, DerefMut};

mod sealed {
    pub trait Sealed {}
}

/// A kind of storage for fixed-capacity tables and queues: [`Inline`] or [`Heap`].
///
/// `N` in the associated types is the inline capacity; heap storage ignores it and uses the
/// length given at construction.
pub trait Storage: sealed::Sealed {
    /// The slots of a [`Table`] of `T`.
    type Slots<T, const N: usize>: AsRef<[T]> + AsMut<[T]>;
    /// A vector of at most a fixed number of `T`.
    type Vec<T, const N: usize>: BoundedVec<T>;
    /// A bounded FIFO of `T`.
    type Fifo<T, const N: usize>: Fifo<T>;
    /// `len` slots made by `fill` (inline: `N` slots; `len` must be `N`).
    fn slots<T, const N: usize>(len: usize, fill: impl FnMut() -> T) -> Self::Slots<T, N>;
    /// An empty FIFO holding at most `capacity` items (inline: `N`; `capacity` must be `N`).
    fn fifo<T, const N: usize>(capacity: usize) -> Self::Fifo<T, N>;
    /// An empty vector holding at most `capacity` items (inline: `N`; `capacity` must be `N`).
    fn vec<T, const N: usize>(capacity: usize) -> Self::Vec<T, N>;
}

/// A vector that holds at most the items it was built for: pushing beyond is refused, never
/// growth.
pub trait BoundedVec<T>: Deref<Target = [T]> + DerefMut {
    /// Appends; gives the item back when full.
    fn try_push(&mut self, item: T) -> Result<(), T>;
    /// Removes every item.
    fn clear(&mut self);
}

impl<T, const N: usize> BoundedVec<T> for heapless::Vec<T, N> {
    #[inline]
    fn try_push(&mut self, item: T) -> Result<(), T> {
        self.push(item)
    }
    #[inline]
    fn clear(&mut self) {
        heapless::Vec::clear(self);
    }
}

/// Bounded by the capacity allocated when it was built ([`Storage::vec`]).
#[cfg(feature = "alloc")]
impl<T> BoundedVec<T> for alloc::vec::Vec<T> {
    #[inline]
    fn try_push(&mut self, item: T) -> Result<(), T> {
        // Checked before the push, so the vector never reallocates.
        if self.len() < self.capacity() {
            self.push(item);
            Ok(())
        } else {
            Err(item)
        }
    }
    #[inline]
    fn clear(&mut self) {
        alloc::vec::Vec::clear(self);
    }
}

/// Tables as arrays inside their owner, sized by its const generics: no allocator, no
/// indirection.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Inline;

impl sealed::Sealed for Inline {}

impl Storage for Inline {
    type Slots<T, const N: usize> = [T; N];
    type Fifo<T, const N: usize> = Bounded<T, N>;
    type Vec<T, const N: usize> = heapless::Vec<T, N>;
    fn slots<T, const N: usize>(len: usize, mut fill: impl FnMut() -> T) -> [T; N] {
        debug_assert_eq!(len, N, "an inline table has its const length");
        core::array::from_fn(|_| fill())
    }
    fn fifo<T, const N: usize>(capacity: usize) -> Bounded<T, N> {
        debug_assert_eq!(capacity, N, "an inline queue has its const capacity");
        Bounded::new()
    }
    fn vec<T, const N: usize>(capacity: usize) -> heapless::Vec<T, N> {
        debug_assert_eq!(capacity, N, "an inline vector has its const capacity");
        heapless::Vec::new()
    }
}

/// Tables allocated once on the heap when their owner is built, with the length it was given
/// (`alloc`). They never grow.
#[cfg(feature = "alloc")]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Heap;

#[cfg(feature = "alloc")]
impl sealed::Sealed for Heap {}

#[cfg(feature = "alloc")]
impl Storage for Heap {
    type Slots<T, const N: usize> = alloc::boxed::Box<[T]>;
    type Fifo<T, const N: usize> = super::queue::BoundedHeap<T>;
    type Vec<T, const N: usize> = alloc::vec::Vec<T>;
    fn slots<T, const N: usize>(len: usize, mut fill: impl FnMut() -> T) -> Self::Slots<T, N> {
        (0..len).map(|_| fill()).collect()
    }
    fn fifo<T, const N: usize>(capacity: usize) -> Self::Fifo<T, N> {
        super::queue::BoundedHeap::new(capacity)
    }
    fn vec<T, const N: usize>(capacity: usize) -> Self::Vec<T, N> {
        alloc::vec::Vec::with_capacity(capacity)
    }
}

/// A table of a fixed number of `T` in storage `S`: `N` inline, or as many as it was built with
/// on the heap. It is a slice whose length never changes.
pub struct Table<T, const N: usize, S: Storage = Inline>(S::Slots<T, N>);

impl<T, const N: usize, S: Storage> Table<T, N, S> {
    /// `len` items made by `fill` (inline storage: `len` must be `N`).
    #[must_use]
    pub fn new(len: usize, fill: impl FnMut() -> T) -> Self {
        Table(S::slots(len, fill))
    }
}

impl<T, const N: usize, S: Storage> Deref for Table<T, N, S> {
    type Target = [T];
    #[inline]
    fn deref(&self) -> &[T] {
        self.0.as_ref()
    }
}

impl<T, const N: usize, S: Storage> DerefMut for Table<T, N, S> {
    #[inline]
    fn deref_mut(&mut self) -> &mut [T] {
        self.0.as_mut()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inline_tables_have_their_const_length() {
        let t: Table<u8, 3> = Table::new(3, || 7);
        assert_eq!(*t, [7, 7, 7]);
        assert_eq!(size_of::<Table<u32, 3>>(), size_of::<[u32; 3]>());
        let q = Inline::fifo::<u8, 3>(3);
        assert_eq!(Fifo::capacity(&q), 3);
    }

    #[cfg(feature = "alloc")]
    #[test]
    fn heap_tables_have_the_length_asked_for() {
        let t: Table<u8, 3, Heap> = Table::new(5, || 7);
        assert_eq!(t.len(), 5);
        let mut q = Heap::fifo::<u8, 3>(2);
        assert!(q.push(1) && q.push(2));
        assert!(!q.push(3));
        assert_eq!((q.len(), q.dropped(), Fifo::capacity(&q)), (2, 1, 2));
        let mut v = Heap::vec::<u8, 3>(2);
        let room = v.capacity();
        for i in 0..10 {
            let _ = v.try_push(i);
        }
        assert_eq!((v.len(), v.capacity()), (room, room));
        assert_eq!(v.try_push(10), Err(10));
    }
}
