//! The streams the sticky merger keeps: one per node-ID, a fixed table of identifier streams,
//! and the encoding of an identifier into the table's key.

use super::{StreamKey, ID_STREAMS};

/// No port: a stream not bound yet.
pub(super) const UNBOUND: u8 = 2;

/// One stream in 8 bytes: its newest stamp (µs) on the port it is bound to in the low 62 bits
/// (146,000 years), that port (0, 1, or [`UNBOUND`]) in the top two. Small, because the layer
/// is moved around whole by value.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Stream(u64);

const STAMP: u64 = (1 << 62) - 1;

impl Stream {
    pub(super) const FREE: Stream = Stream::new(0, UNBOUND);

    pub(super) const fn new(last: u64, bound: u8) -> Self {
        Stream((last & STAMP) | ((bound as u64) << 62))
    }
    /// Newest stamp (µs) of the stream's frames on the bound port.
    pub(super) const fn last(self) -> u64 {
        self.0 & STAMP
    }
    /// 0, 1, or [`UNBOUND`].
    pub(super) const fn bound(self) -> u8 {
        (self.0 >> 62) as u8
    }
}

/// The key of an identifier stream: the identifier, the extended and the remote bits.
pub(super) fn id_key(key: StreamKey) -> u32 {
    match key {
        StreamKey::Id { id, remote } => {
            id.raw() | (u32::from(id.is_extended()) << 29) | (u32::from(remote) << 30)
        }
        // Node streams are not in this table; a key no identifier has.
        StreamKey::Node(n) => u32::MAX - u32::from(n.raw()),
    }
}

/// Identifier streams, unordered: looked up by a scan (the table is small, and only frames
/// without a known sender come here).
pub(super) struct IdTable {
    keys: [u32; ID_STREAMS],
    pub(super) streams: [Stream; ID_STREAMS],
    len: usize,
}

impl IdTable {
    pub(super) const fn new() -> Self {
        IdTable {
            keys: [0; ID_STREAMS],
            streams: [Stream::FREE; ID_STREAMS],
            len: 0,
        }
    }
    pub(super) fn len(&self) -> usize {
        self.len
    }
    pub(super) fn find(&self, key: u32) -> Option<usize> {
        self.keys[..self.len].iter().position(|k| *k == key)
    }
    /// A new unbound stream for `key`; `None` when the table is full.
    pub(super) fn insert(&mut self, key: u32) -> Option<usize> {
        if self.len == ID_STREAMS {
            return None;
        }
        let i = self.len;
        self.keys[i] = key;
        self.streams[i] = Stream::FREE;
        self.len += 1;
        Some(i)
    }
    /// The stream whose newest stamp is the oldest (an unbound one first).
    pub(super) fn oldest(&self) -> Option<usize> {
        (0..self.len).min_by_key(|i| {
            let s = self.streams[*i];
            (s.bound() != UNBOUND, s.last())
        })
    }
    /// Forgets entry `i` (the last entry takes its place).
    pub(super) fn remove(&mut self, i: usize) {
        self.len -= 1;
        self.keys[i] = self.keys[self.len];
        self.streams[i] = self.streams[self.len];
    }
    /// Every stream held, for a step back of the clock.
    pub(super) fn streams_mut(&mut self) -> &mut [Stream] {
        &mut self.streams[..self.len]
    }
    pub(super) fn get(&self, key: u32) -> Option<&Stream> {
        self.find(key).map(|i| &self.streams[i])
    }
}
