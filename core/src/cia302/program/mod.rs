//! Program download, the node's side (CiA 302-3): a duocan node whose program can be replaced
//! over the bus. 0x1F50 program data, 0x1F51 program control, 0x1F56 program software
//! identification and 0x1F57 flash status, wired to a [`ProgramStore`] the application
//! implements (its flash, its boot loader).
//!
//! # The rule
//!
//! The store has a running program and a staging area. A download goes to staging only, and
//! only when the program is stopped and staging was cleared; the store verifies what it
//! staged. Start makes a verified staged image the program in control ([`ProgramStore::activate`])
//! and runs it; with nothing verified staged (no download, a download refused, aborted or cut
//! off) start runs the old program again. So a failed or aborted download never leaves the node
//! without the program it had.
//!
//! | 0x1F51 write | when | what happens |
//! |---|---|---|
//! | 0 stop | always | the program stops |
//! | 1 start | always | a verified staged image becomes the program; the program runs |
//! | 2 reset | always | staging is dropped; the program in control runs from its start |
//! | 3 clear | stopped | staging is erased, ready for a download |
//!
//! A command the present state forbids is refused with 0x08000022, an unknown one with
//! 0x06090030; a refusal of the store is 0x08000020. 0x1F51 reads 0 (stopped) or 1 (running). 0x1F57 bit 0 is set
//! while a download is written; bits 1–7 hold the last [`FlashError`] code (0: none).
//!
//! # Memory
//!
//! The core keeps a few words of state, never an image. The SDO server collects a download
//! into its transfer buffer (an aborted or cut-off transfer never reaches the dictionary) and
//! hands the whole image to [`ProgramStore::stage`] in one call, so the largest image is the
//! server's transfer limit ([`crate::sdo::SdoServerConfig::max_transfer`], 64 KiB by default)
//! and the store's [`ProgramStore::capacity`], whichever is smaller; an image above it is
//! refused with 0x06070012 before the store sees it.
//!
//! ```
//! use duocan_core::cia302::program::{FlashError, ProgramDictionary, ProgramStore};
//! use duocan_core::od::{comm, ObjectDictionary};
//!
//! /// A store in RAM: the running program's identification, and a staged checksum.
//! #[derive(Default)]
//! struct Ram { running: u32, staged: Option<u32> }
//! impl ProgramStore for Ram {
//!     fn capacity(&self) -> u32 { 1024 }
//!     fn stop(&mut self) {}
//!     fn run(&mut self) {}
//!     fn clear(&mut self) -> Result<(), FlashError> { self.staged = None; Ok(()) }
//!     fn stage(&mut self, image: &[u8]) -> Result<(), FlashError> {
//!         self.staged = Some(image.iter().map(|b| *b as u32).sum());
//!         Ok(())
//!     }
//!     fn activate(&mut self) -> Result<(), FlashError> {
//!         self.running = self.staged.take().ok_or(FlashError::NoValidProgram)?;
//!         Ok(())
//!     }
//!     fn identification(&self) -> u32 { self.running }
//! }
//!
//! let mut od = ProgramDictionary::new(comm::standard_dictionary(5, Default::default()), Ram::default());
//! od.write(0x1F51, 1, &[0]).unwrap(); // stop
//! od.write(0x1F51, 1, &[3]).unwrap(); // clear
//! od.write(0x1F50, 1, &[1, 2, 3]).unwrap(); // download
//! assert_eq!(od.get_u32(0x1F56, 1), Some(0)); // not yet in control
//! od.write(0x1F51, 1, &[1]).unwrap(); // start
//! assert_eq!(od.get_u32(0x1F56, 1), Some(6));
//! assert_eq!(od.get_u32(0x1F51, 1), Some(1));
//! ```

mod dictionary;
mod ram;

pub use dictionary::ProgramDictionary;
pub use ram::{image_id, RamStore};

use core::fmt;

/// Program data: sub 1, the image (DOMAIN, write only).
pub const PROGRAM_DATA: u16 = 0x1F50;
/// Program control: sub 1, the command (write) or the state (read).
pub const PROGRAM_CONTROL: u16 = 0x1F51;
/// Program software identification: sub 1, the identification of the program in control.
pub const PROGRAM_IDENTIFICATION: u16 = 0x1F56;
/// Flash status identification: sub 1, bit 0 in progress, bits 1–7 the last error code.
pub const FLASH_STATUS: u16 = 0x1F57;

/// 0x1F51 values.
pub mod control {
    /// Write: stop the program; read: stopped.
    pub const STOP: u8 = 0;
    /// Write: start the program (a verified staged image first); read: running.
    pub const START: u8 = 1;
    /// Write: drop staging and run the program from its start.
    pub const RESET: u8 = 2;
    /// Write: erase staging (the program must be stopped).
    pub const CLEAR: u8 = 3;
}

/// Why the store refused an image or a command: the CiA 302-3 flash status codes (0x1F57 bits
/// 1–7).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum FlashError {
    /// There is no valid program (start with nothing to run).
    NoValidProgram,
    /// The image's format is not one the device knows.
    DataFormatUnknown,
    /// The image is damaged (its check failed).
    DataFormatError,
    /// The staging area was not cleared before the download.
    NotCleared,
    /// Writing the flash failed.
    WriteError,
    /// The image addresses memory the device does not have.
    AddressError,
    /// The flash is write protected.
    Secured,
    /// A manufacturer-specific code (64–127).
    Manufacturer(u8),
}

impl FlashError {
    /// The 0x1F57 code (bits 1–7).
    #[must_use]
    pub const fn code(self) -> u8 {
        match self {
            FlashError::NoValidProgram => 1,
            FlashError::DataFormatUnknown => 2,
            FlashError::DataFormatError => 3,
            FlashError::NotCleared => 4,
            FlashError::WriteError => 5,
            FlashError::AddressError => 6,
            FlashError::Secured => 7,
            FlashError::Manufacturer(c) => c & 0x7F,
        }
    }
}

impl fmt::Display for FlashError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let what = match self {
            FlashError::NoValidProgram => "no valid program",
            FlashError::DataFormatUnknown => "data format unknown",
            FlashError::DataFormatError => "data format error or checksum mismatch",
            FlashError::NotCleared => "flash not cleared before the download",
            FlashError::WriteError => "flash write error",
            FlashError::AddressError => "address outside the flash",
            FlashError::Secured => "flash secured",
            FlashError::Manufacturer(c) => return write!(f, "manufacturer-specific error {c}"),
        };
        write!(f, "{what} (flash status code {})", self.code())
    }
}

impl core::error::Error for FlashError {}

/// The device's program memory, as the application implements it: a running program and a
/// staging area. Every call is synchronous; a store whose flash is slow finishes the work
/// before it returns (the SDO answer waits for it).
pub trait ProgramStore {
    /// The largest image staging holds, in bytes.
    fn capacity(&self) -> u32;
    /// Stops the running program (the device keeps its CANopen communication).
    fn stop(&mut self);
    /// Runs the program in control from its start.
    fn run(&mut self);
    /// Erases the staging area.
    fn clear(&mut self) -> Result<(), FlashError>;
    /// Writes a whole image to the cleared staging area and verifies it there. An error leaves
    /// nothing staged.
    fn stage(&mut self, image: &[u8]) -> Result<(), FlashError>;
    /// Makes the verified staged image the program in control (the old one is replaced only
    /// now). Called only after a successful [`ProgramStore::stage`].
    fn activate(&mut self) -> Result<(), FlashError>;
    /// The software identification of the program in control (0x1F56 sub 1).
    fn identification(&self) -> u32;
}
