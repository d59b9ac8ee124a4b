//! Transfer buffers: where a segmented or block transfer collects its data before the dictionary
//! (server) or the application (client) sees it. Always bounded: a heap buffer grows on demand up
//! to its limit, an inline buffer is a fixed array.

/// A bounded byte buffer for one transfer.
pub trait TransferBuffer {
    /// An empty buffer that will hold at most `limit` bytes (an inline buffer also at most its
    /// capacity).
    fn with_limit(limit: usize) -> Self
    where
        Self: Sized;
    /// The most bytes it will hold.
    fn limit(&self) -> usize;
    /// Changes the limit (for the next transfer; existing data is kept up to the new limit).
    fn set_limit(&mut self, limit: usize);
    /// The data.
    fn as_slice(&self) -> &[u8];
    /// Forgets the data.
    fn clear(&mut self);
    /// Appends `data`; false (and nothing appended) if that would pass the limit.
    fn extend(&mut self, data: &[u8]) -> bool;
    /// Forgets the first `n` bytes (all of them if it holds fewer): a streamed transfer's
    /// window moving on. Moves the rest to the front; never allocates.
    fn consume(&mut self, n: usize);
    /// Announces that `n` bytes are coming (a heap buffer reserves them once instead of growing
    /// step by step). The caller has checked `n` against the limit.
    fn reserve(&mut self, n: usize) {
        let _ = n;
    }
    /// Bytes held.
    fn len(&self) -> usize {
        self.as_slice().len()
    }
    /// True when empty.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// A buffer of at most `N` bytes stored inline: no heap, fixed footprint (no_std nodes).
#[derive(Clone, Debug, Default)]
pub struct InlineBuffer<const N: usize> {
    data: heapless::Vec<u8, N>,
    limit: usize,
}

impl<const N: usize> TransferBuffer for InlineBuffer<N> {
    fn with_limit(limit: usize) -> Self {
        InlineBuffer {
            data: heapless::Vec::new(),
            limit: limit.min(N),
        }
    }
    fn limit(&self) -> usize {
        self.limit
    }
    fn set_limit(&mut self, limit: usize) {
        self.limit = limit.min(N);
        self.data.truncate(self.limit);
    }
    fn as_slice(&self) -> &[u8] {
        &self.data
    }
    fn clear(&mut self) {
        self.data.clear();
    }
    fn extend(&mut self, data: &[u8]) -> bool {
        if self.data.len() + data.len() > self.limit {
            return false;
        }
        self.data.extend_from_slice(data).is_ok()
    }
    fn consume(&mut self, n: usize) {
        let n = n.min(self.data.len());
        self.data.copy_within(n.., 0);
        self.data.truncate(self.data.len() - n);
    }
}

/// A heap buffer that grows on demand up to its limit and keeps its allocation between transfers.
#[cfg(feature = "alloc")]
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct HeapBuffer {
    data: alloc::vec::Vec<u8>,
    limit: usize,
}

#[cfg(feature = "alloc")]
impl HeapBuffer {
    /// The data, as a vector.
    pub fn into_vec(self) -> alloc::vec::Vec<u8> {
        self.data
    }
}

#[cfg(feature = "alloc")]
impl TransferBuffer for HeapBuffer {
    fn with_limit(limit: usize) -> Self {
        HeapBuffer {
            data: alloc::vec::Vec::new(),
            limit,
        }
    }
    fn limit(&self) -> usize {
        self.limit
    }
    fn set_limit(&mut self, limit: usize) {
        self.limit = limit;
        self.data.truncate(limit);
    }
    fn as_slice(&self) -> &[u8] {
        &self.data
    }
    fn clear(&mut self) {
        self.data.clear();
    }
    fn extend(&mut self, data: &[u8]) -> bool {
        if self.data.len() + data.len() > self.limit {
            return false;
        }
        self.data.extend_from_slice(data);
        true
    }
    fn consume(&mut self, n: usize) {
        self.data.drain(..n.min(self.data.len()));
    }
    fn reserve(&mut self, n: usize) {
        let n = n.min(self.limit);
        self.data.reserve(n.saturating_sub(self.data.len()));
    }
}

/// The buffer the stack uses by default: a [`HeapBuffer`] with `alloc`, otherwise an
/// [`InlineBuffer`] of [`INLINE_CAPACITY`] bytes.
#[cfg(feature = "alloc")]
pub type DefaultBuffer = HeapBuffer;
/// The buffer the stack uses by default: a `HeapBuffer` with `alloc`, otherwise an
/// [`InlineBuffer`] of [`INLINE_CAPACITY`] bytes.
#[cfg(not(feature = "alloc"))]
pub type DefaultBuffer = InlineBuffer<INLINE_CAPACITY>;

/// Capacity of the default inline buffer of no_std builds without `alloc`.
pub const INLINE_CAPACITY: usize = 1024;

/// Default transfer limit: the largest value one transfer may carry (64 KiB).
pub const DEFAULT_LIMIT: usize = 64 * 1024;

impl<const N: usize> core::ops::Deref for InlineBuffer<N> {
    type Target = [u8];
    fn deref(&self) -> &[u8] {
        &self.data
    }
}

#[cfg(feature = "alloc")]
impl core::ops::Deref for HeapBuffer {
    type Target = [u8];
    fn deref(&self) -> &[u8] {
        &self.data
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn exercise<B: TransferBuffer>(mut b: B) {
        assert_eq!(b.limit(), 10);
        assert!(b.extend(&[1; 7]));
        assert!(!b.extend(&[2; 4]), "past the limit");
        assert_eq!(b.len(), 7);
        assert!(b.extend(&[3; 3]));
        assert_eq!(b.as_slice(), &[1, 1, 1, 1, 1, 1, 1, 3, 3, 3]);
        b.consume(2);
        assert_eq!(b.as_slice(), &[1, 1, 1, 1, 1, 3, 3, 3]);
        b.consume(100);
        assert!(b.is_empty());
        assert!(b.extend(&[1; 10]));
        b.set_limit(5);
        assert_eq!(b.len(), 5);
        b.clear();
        assert!(b.is_empty());
    }

    #[test]
    fn buffers_never_pass_their_limit() {
        exercise(InlineBuffer::<16>::with_limit(10));
        assert_eq!(InlineBuffer::<16>::with_limit(100).limit(), 16);
        #[cfg(feature = "alloc")]
        exercise(HeapBuffer::with_limit(10));
    }
}
