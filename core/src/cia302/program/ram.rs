//! A program store that keeps no image: for simulated devices, tests, and a first look at
//! program download before a device's flash driver exists.

use super::{FlashError, ProgramStore};

/// What a [`RamStore`] reports as the identification (0x1F56 sub 1) of `image` once it runs:
/// its 32-bit FNV-1a hash, so that a different image reads differently.
#[must_use]
pub fn image_id(image: &[u8]) -> u32 {
    image.iter().fold(0x811C_9DC5, |h: u32, b| {
        (h ^ u32::from(*b)).wrapping_mul(0x0100_0193)
    })
}

/// A program store in RAM that keeps the identification of what it staged ([`image_id`]),
/// not the image: a few words whatever the image's size. An image can be made to pass a check
/// first ([`RamStore::verifying`]), as a device checks a header or a signature.
///
/// ```
/// use duocan_core::cia302::program::{image_id, FlashError, ProgramDictionary, RamStore};
/// use duocan_core::od::{comm, ObjectDictionary};
///
/// // Images that start with 0xFF are damaged, for this store.
/// let store = RamStore::new(1024).verifying(|image| match image.first() {
///     Some(0xFF) => Err(FlashError::DataFormatError),
///     _ => Ok(()),
/// });
/// let mut od = ProgramDictionary::new(comm::standard_dictionary(5, Default::default()), store);
/// od.write(0x1F51, 1, &[0]).unwrap(); // stop
/// od.write(0x1F51, 1, &[3]).unwrap(); // clear
/// assert!(od.write(0x1F50, 1, &[0xFF, 1]).is_err()); // refused: 0x1F57 says why
/// assert_eq!(od.get_u32(0x1F57, 1), Some(u32::from(FlashError::DataFormatError.code()) << 1));
/// od.write(0x1F51, 1, &[3]).unwrap(); // clear again
/// od.write(0x1F50, 1, &[1, 2, 3]).unwrap();
/// od.write(0x1F51, 1, &[1]).unwrap(); // start
/// assert_eq!(od.get_u32(0x1F56, 1), Some(image_id(&[1, 2, 3])));
/// ```
#[derive(Clone, Copy, Debug)]
pub struct RamStore {
    capacity: u32,
    running: u32,
    staged: Option<u32>,
    check: fn(&[u8]) -> Result<(), FlashError>,
}

impl RamStore {
    /// A store taking images up to `capacity` bytes, running a program identified as 0.
    #[must_use]
    pub fn new(capacity: u32) -> Self {
        RamStore {
            capacity,
            running: 0,
            staged: None,
            check: |_| Ok(()),
        }
    }

    /// The same store, staging only images that pass `check` (its error is the flash status).
    #[must_use]
    pub fn verifying(self, check: fn(&[u8]) -> Result<(), FlashError>) -> Self {
        RamStore { check, ..self }
    }
}

impl ProgramStore for RamStore {
    fn capacity(&self) -> u32 {
        self.capacity
    }
    fn stop(&mut self) {}
    fn run(&mut self) {}
    fn clear(&mut self) -> Result<(), FlashError> {
        self.staged = None;
        Ok(())
    }
    fn stage(&mut self, image: &[u8]) -> Result<(), FlashError> {
        (self.check)(image)?;
        self.staged = Some(image_id(image));
        Ok(())
    }
    fn activate(&mut self) -> Result<(), FlashError> {
        self.running = self.staged.take().ok_or(FlashError::NoValidProgram)?;
        Ok(())
    }
    fn identification(&self) -> u32 {
        self.running
    }
}
