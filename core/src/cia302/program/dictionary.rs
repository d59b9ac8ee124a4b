//! [`ProgramDictionary`]: a node's dictionary with the program download objects in front of it,
//! each access to them turned into a call of the [`ProgramStore`].

use super::{
    control, FlashError, ProgramStore, FLASH_STATUS, PROGRAM_CONTROL, PROGRAM_DATA,
    PROGRAM_IDENTIFICATION,
};
use crate::od::abort::AbortCode;
use crate::od::parameters::{LoadReport, ParameterGroup, StorageError};
use crate::od::{Access, DataType, Entry, ObjectDef, ObjectDictionary, ObjectType};
use core::ops::RangeInclusive;

/// Where staging is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Staging {
    /// Not cleared since the last download or start: a download is refused.
    Dirty,
    /// Erased: a download may come.
    Cleared,
    /// A verified image waits for start.
    Staged,
}

/// The four program download objects, in this order, sub 0 then sub 1.
const INDICES: [u16; 4] = [
    PROGRAM_DATA,
    PROGRAM_CONTROL,
    PROGRAM_IDENTIFICATION,
    FLASH_STATUS,
];
/// Every sub 0: one program.
const ONE: [u8; 1] = [1];

/// A 0x1F51 write must be a command CiA 302-3 defines.
fn control_value(_: u16, _: u8, data: &[u8]) -> Result<(), AbortCode> {
    match data.first() {
        Some(&(control::STOP | control::START | control::RESET | control::CLEAR)) => Ok(()),
        _ => Err(AbortCode::VALUE_RANGE),
    }
}

/// A dictionary `D` with 0x1F50, 0x1F51, 0x1F56 and 0x1F57 served by a [`ProgramStore`] `S`
/// (the rule is in the [module docs](super)). Every other entry is `D`'s, storage included.
pub struct ProgramDictionary<D, S> {
    inner: D,
    store: S,
    defs: [ObjectDef; 8],
    staging: Staging,
    /// 0x1F51 sub 1 as read.
    control: [u8; 1],
    /// 0x1F56 sub 1.
    identification: [u8; 4],
    /// 0x1F57 sub 1.
    status: [u8; 4],
}

impl<D: ObjectDictionary, S: ProgramStore> ProgramDictionary<D, S> {
    /// `inner` with the program objects of `store`, whose program runs.
    pub fn new(inner: D, store: S) -> Self {
        let array = ObjectType::Array;
        let sub0 = |index, name| {
            ObjectDef::u8(index, 0, Access::Const, 1)
                .object_type(array)
                .named(name)
        };
        let defs = [
            sub0(PROGRAM_DATA, "Program data"),
            ObjectDef::bytes(PROGRAM_DATA, 1, DataType::Domain, store.capacity())
                .access(Access::Wo)
                .object_type(array)
                .named("Program data"),
            sub0(PROGRAM_CONTROL, "Program control"),
            ObjectDef::u8(PROGRAM_CONTROL, 1, Access::Rw, control::START)
                .object_type(array)
                .hook(control_value)
                .named("Program control"),
            sub0(PROGRAM_IDENTIFICATION, "Program software identification"),
            ObjectDef::u32(PROGRAM_IDENTIFICATION, 1, Access::Ro, 0)
                .object_type(array)
                .named("Program software identification"),
            sub0(FLASH_STATUS, "Flash status identification"),
            ObjectDef::u32(FLASH_STATUS, 1, Access::Ro, 0)
                .object_type(array)
                .named("Flash status identification"),
        ];
        let identification = store.identification().to_le_bytes();
        ProgramDictionary {
            inner,
            store,
            defs,
            staging: Staging::Dirty,
            control: [control::START],
            identification,
            status: [0; 4],
        }
    }

    /// The dictionary behind the program objects.
    pub fn inner(&self) -> &D {
        &self.inner
    }
    /// The dictionary behind the program objects, to change.
    pub fn inner_mut(&mut self) -> &mut D {
        &mut self.inner
    }
    /// The program store.
    pub fn store(&self) -> &S {
        &self.store
    }
    /// The program store, to change (a store whose program changed by other means: call
    /// nothing else, 0x1F56 follows at the next start).
    pub fn store_mut(&mut self) -> &mut S {
        &mut self.store
    }
    /// True while the program runs (0x1F51 reads 1).
    pub fn running(&self) -> bool {
        self.control[0] == control::START
    }

    /// The position of (index, sub) among the program objects.
    fn slot(index: u16, sub: u8) -> Option<Result<usize, AbortCode>> {
        let k = INDICES.iter().position(|i| *i == index)?;
        Some(match sub {
            0 | 1 => Ok(2 * k + sub as usize),
            _ => Err(AbortCode::NO_SUB_INDEX),
        })
    }

    fn set_status(&mut self, error: Option<FlashError>) {
        let code = error.map_or(0, |e| e.code() as u32);
        self.status = (code << 1).to_le_bytes();
    }

    /// A store refusal: kept in 0x1F57, reported as "cannot store".
    fn refused(&mut self, e: FlashError) -> AbortCode {
        self.set_status(Some(e));
        AbortCode::CANNOT_STORE
    }

    fn download(&mut self, image: &[u8]) -> Result<(), AbortCode> {
        if self.running() {
            return Err(AbortCode::DEVICE_STATE);
        }
        // Whatever happens now, staging must be cleared again before the next download, and
        // an image staged before is dropped: which one the client wants is not known.
        if core::mem::replace(&mut self.staging, Staging::Dirty) != Staging::Cleared {
            return Err(self.refused(FlashError::NotCleared));
        }
        self.store.stage(image).map_err(|e| self.refused(e))?;
        self.staging = Staging::Staged;
        self.set_status(None);
        Ok(())
    }

    fn command(&mut self, cmd: u8) -> Result<(), AbortCode> {
        match cmd {
            control::STOP => {
                self.store.stop();
                self.control = [control::STOP];
            }
            control::START => {
                if core::mem::replace(&mut self.staging, Staging::Dirty) == Staging::Staged {
                    self.store.activate().map_err(|e| self.refused(e))?;
                    self.identification = self.store.identification().to_le_bytes();
                }
                self.store.run();
                self.control = [control::START];
            }
            control::RESET => {
                self.staging = Staging::Dirty;
                self.store.stop();
                self.store.run();
                self.control = [control::START];
            }
            control::CLEAR => {
                if self.running() {
                    return Err(AbortCode::DEVICE_STATE);
                }
                self.staging = Staging::Dirty;
                self.store.clear().map_err(|e| self.refused(e))?;
                self.staging = Staging::Cleared;
                self.set_status(None);
            }
            _ => return Err(AbortCode::VALUE_RANGE),
        }
        Ok(())
    }
}

impl<D: ObjectDictionary, S: ProgramStore> ObjectDictionary for ProgramDictionary<D, S> {
    fn get(&self, index: u16, sub: u8) -> Result<Entry<'_>, AbortCode> {
        let Some(k) = Self::slot(index, sub) else {
            return self.inner.get(index, sub);
        };
        let k = k?;
        let data: &[u8] = match k {
            1 => &[],
            3 => &self.control,
            5 => &self.identification,
            7 => &self.status,
            _ => &ONE,
        };
        Ok(Entry::of(&self.defs[k], data))
    }

    fn store(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        match Self::slot(index, sub) {
            None => self.inner.store(index, sub, data),
            Some(Ok(1)) => self.download(data),
            Some(Ok(3)) => self.command(data.first().copied().unwrap_or(u8::MAX)),
            Some(Ok(_)) => Err(AbortCode::READ_ONLY),
            Some(Err(code)) => Err(code),
        }
    }

    fn reset_range(&mut self, range: RangeInclusive<u16>) {
        // The program objects follow the store, not the power-on values.
        self.inner.reset_range(range);
    }

    fn capture_power_on(&mut self) -> Result<(), StorageError> {
        self.inner.capture_power_on()
    }

    fn node_id(&self) -> u8 {
        self.inner.node_id()
    }

    fn for_each(&self, f: &mut dyn FnMut(Entry<'_>)) {
        self.inner.for_each(f);
        for (k, def) in self.defs.iter().enumerate() {
            if let Ok(e) = self.get(def.index, def.sub) {
                debug_assert_eq!(k % 2, def.sub as usize);
                f(e);
            }
        }
    }

    fn len(&self) -> usize {
        self.inner.len() + self.defs.len()
    }

    fn storage_capabilities(&self) -> u32 {
        self.inner.storage_capabilities()
    }

    fn store_parameters(&mut self, group: ParameterGroup) -> Result<(), StorageError> {
        self.inner.store_parameters(group)
    }

    fn restore_defaults(&mut self, group: ParameterGroup) -> Result<(), StorageError> {
        self.inner.restore_defaults(group)
    }

    fn load_parameters(&mut self, range: RangeInclusive<u16>) -> Result<LoadReport, StorageError> {
        self.inner.load_parameters(range)
    }
}
