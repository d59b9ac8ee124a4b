//! A dictionary with a medium behind 0x1010/0x1011.

use super::image;
use super::{bytes, capability, LoadReport, ParameterGroup, ParameterStorage, StorageError};
use crate::od::abort::AbortCode;
use crate::od::{Entry, ObjectDictionary};
use core::ops::RangeInclusive;

/// Any dictionary `D` with a [`ParameterStorage`] medium `S` and an `IMAGE`-byte buffer the
/// stored image passes through (no allocation: [`image_capacity`](super::image_capacity) of the
/// dictionary's capacities always suffices).
///
/// It is the dictionary in every respect and adds what 0x1010/0x1011 need: a node built on it
/// stores on `"save"`, restores on `"load"`, and reloads the stored values at power-on and at
/// each reset.
///
/// ```
/// use duocan_core::od::parameters::{image_capacity, MemoryStorage, StoredDictionary};
/// use duocan_core::od::{comm, ObjectDef, ObjectDictionary, StaticDictionary};
/// use duocan_core::{Instant, Machine, Node, NodeConfig, NodeId};
///
/// static COMM: [ObjectDef; comm::COMM_LEN] = comm::communication();
/// static STORE: [ObjectDef; comm::STORAGE_LEN] = comm::parameter_storage();
/// type Od = StaticDictionary<32, 256>;
/// // The buffer an image of this dictionary always fits in.
/// const IMAGE: usize = image_capacity(32, 256);
///
/// let mut od = Od::new();
/// od.load(5, &[&COMM, &STORE]).unwrap();
/// let od = StoredDictionary::<_, _, IMAGE>::new(od, MemoryStorage::<IMAGE>::new());
/// let mut node = Node::new(NodeConfig::slave(NodeId::must(5)), od);
/// // The application's configuration before boot is the power-on image.
/// node.set(Instant::ZERO, comm::HEARTBEAT_PRODUCER, 0, 1000u16).unwrap();
/// node.boot(Instant::ZERO);
/// // 0x1010 sub 1 reads "stores on command".
/// assert_eq!(node.od().get_value::<u32>(comm::STORE_PARAMETERS, 1), Ok(1));
/// ```
pub struct StoredDictionary<D, S: ParameterStorage, const IMAGE: usize> {
    od: D,
    storage: S,
    buf: [u8; IMAGE],
    last_error: Option<S::Error>,
}

impl<D, S: ParameterStorage, const IMAGE: usize> StoredDictionary<D, S, IMAGE> {
    /// `od` with `storage` behind it. Nothing is read until the node boots.
    pub fn new(od: D, storage: S) -> Self {
        StoredDictionary {
            od,
            storage,
            buf: [0; IMAGE],
            last_error: None,
        }
    }
    /// The dictionary itself.
    pub fn inner(&self) -> &D {
        &self.od
    }
    /// The dictionary itself, for structural changes (a dynamic dictionary's inserts).
    pub fn inner_mut(&mut self) -> &mut D {
        &mut self.od
    }
    /// The medium.
    pub fn storage(&self) -> &S {
        &self.storage
    }
    /// The medium, mutably.
    pub fn storage_mut(&mut self) -> &mut S {
        &mut self.storage
    }
    /// The medium's error behind the last [`StorageError::Medium`].
    pub fn last_error(&self) -> Option<&S::Error> {
        self.last_error.as_ref()
    }
    /// The dictionary and the medium.
    pub fn into_parts(self) -> (D, S) {
        (self.od, self.storage)
    }

    fn medium(&mut self, e: S::Error) -> StorageError {
        self.last_error = Some(e);
        StorageError::Medium
    }

    /// Reads and checks the stored image into the buffer; its length, or `None`.
    fn read_image(&mut self) -> Result<Option<usize>, StorageError> {
        match self.storage.load(&mut self.buf) {
            Err(e) => Err(self.medium(e)),
            Ok(None) => Ok(None),
            Ok(Some(n)) if n > IMAGE => Err(StorageError::TooLarge {
                needed: bytes(n),
                capacity: bytes(IMAGE),
            }),
            Ok(Some(n)) => {
                image::validate(&self.buf[..n]).map_err(StorageError::Corrupt)?;
                Ok(Some(n))
            }
        }
    }

    /// Replaces the stored image with the buffer's first `len` bytes, or erases it.
    fn write_image(&mut self, len: Option<usize>) -> Result<(), StorageError> {
        let r = match len {
            Some(n) => self.storage.store(&self.buf[..n]),
            None => self.storage.erase(),
        };
        r.map_err(|e| self.medium(e))
    }
}

impl<D: ObjectDictionary, S: ParameterStorage, const IMAGE: usize> ObjectDictionary
    for StoredDictionary<D, S, IMAGE>
{
    #[inline]
    fn get(&self, index: u16, sub: u8) -> Result<Entry<'_>, AbortCode> {
        self.od.get(index, sub)
    }
    fn store(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        self.od.store(index, sub, data)
    }
    fn reset_range(&mut self, range: RangeInclusive<u16>) {
        self.od.reset_range(range)
    }
    fn capture_power_on(&mut self) -> Result<(), StorageError> {
        self.od.capture_power_on()
    }
    fn node_id(&self) -> u8 {
        self.od.node_id()
    }
    fn for_each(&self, f: &mut dyn FnMut(Entry<'_>)) {
        self.od.for_each(f)
    }
    fn len(&self) -> usize {
        self.od.len()
    }

    fn storage_capabilities(&self) -> u32 {
        capability::ON_COMMAND
    }

    fn store_parameters(&mut self, group: ParameterGroup) -> Result<(), StorageError> {
        let len = match self.read_image() {
            Ok(len) => len.unwrap_or(0),
            // An image that cannot be read is not applied at boot either: start a new one.
            Err(StorageError::Corrupt(_)) => 0,
            Err(e) => return Err(e),
        };
        let len = image::rebuild(&self.od, group, &mut self.buf, len)?;
        self.write_image(Some(len))
    }

    fn restore_defaults(&mut self, group: ParameterGroup) -> Result<(), StorageError> {
        let len = match self.read_image() {
            Ok(Some(len)) if group != ParameterGroup::All => len,
            Ok(None) => return Ok(()),
            // Everything goes, and an unreadable image holds nothing worth keeping.
            Ok(Some(_)) | Err(StorageError::Corrupt(_)) => return self.write_image(None),
            Err(e) => return Err(e),
        };
        let rest = image::remove(&mut self.buf, len, group);
        self.write_image(rest)
    }

    fn load_parameters(&mut self, range: RangeInclusive<u16>) -> Result<LoadReport, StorageError> {
        match self.read_image()? {
            None => Ok(LoadReport::default()),
            Some(len) => Ok(image::apply(&mut self.od, &self.buf[..len], range)),
        }
    }
}
