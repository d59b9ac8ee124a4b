//! A stored image in RAM: for tests, for the simulator (a board that keeps its stored
//! parameters across a simulated reset), and as the model a flash driver follows.

use super::ParameterStorage;
use core::fmt;

/// A [`ParameterStorage`] holding up to `N` bytes in RAM. Every operation is a copy, so it is
/// trivially all or nothing.
#[derive(Clone, Debug)]
pub struct MemoryStorage<const N: usize> {
    data: [u8; N],
    len: Option<usize>,
    stores: u32,
}

impl<const N: usize> Default for MemoryStorage<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> MemoryStorage<N> {
    /// Empty: nothing stored.
    #[must_use]
    pub const fn new() -> Self {
        MemoryStorage {
            data: [0; N],
            len: None,
            stores: 0,
        }
    }
    /// The stored image, if any.
    pub fn image(&self) -> Option<&[u8]> {
        self.len.map(|n| &self.data[..n])
    }
    /// Images written so far.
    pub fn stores(&self) -> u32 {
        self.stores
    }
}

/// The image does not fit a [`MemoryStorage`] (or the caller's buffer).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MemoryStorageError {
    /// Bytes of the image.
    pub needed: usize,
    /// Bytes of room.
    pub capacity: usize,
}

impl fmt::Display for MemoryStorageError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "a {}-byte parameter image does not fit {} bytes",
            self.needed, self.capacity
        )
    }
}

impl core::error::Error for MemoryStorageError {}

impl<const N: usize> ParameterStorage for MemoryStorage<N> {
    type Error = MemoryStorageError;

    fn load(&mut self, buf: &mut [u8]) -> Result<Option<usize>, MemoryStorageError> {
        let Some(n) = self.len else { return Ok(None) };
        let capacity = buf.len();
        let out = buf.get_mut(..n).ok_or(MemoryStorageError {
            needed: n,
            capacity,
        })?;
        out.copy_from_slice(&self.data[..n]);
        Ok(Some(n))
    }

    fn store(&mut self, image: &[u8]) -> Result<(), MemoryStorageError> {
        let room = self.data.get_mut(..image.len()).ok_or(MemoryStorageError {
            needed: image.len(),
            capacity: N,
        })?;
        room.copy_from_slice(image);
        self.len = Some(image.len());
        self.stores += 1;
        Ok(())
    }

    fn erase(&mut self) -> Result<(), MemoryStorageError> {
        self.len = None;
        Ok(())
    }
}
