//! The stored image in a file (`std`): written atomically, so that a crash or a full disk in the
//! middle of a store leaves the previous image.

use super::ParameterStorage;
use std::ffi::OsString;
use std::fmt;
use std::fs::{self, File, OpenOptions};
use std::io::{self, Read, Write};
use std::path::{Path, PathBuf};

/// A [`ParameterStorage`] in one file. A store writes `<path>.tmp`, syncs it to the disk,
/// renames it over `<path>` and syncs the directory: the rename is atomic, so `<path>` holds
/// either the old image or the new one, whatever fails when.
#[derive(Clone, Debug)]
pub struct FileStorage {
    path: PathBuf,
    temp: PathBuf,
}

impl FileStorage {
    /// Stores in `path` (its directory must exist; the file is created on the first store).
    pub fn new(path: impl Into<PathBuf>) -> Self {
        let path = path.into();
        let mut temp = OsString::from(path.as_os_str());
        temp.push(".tmp");
        FileStorage {
            path,
            temp: PathBuf::from(temp),
        }
    }
    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }
    /// The temporary file a store writes first.
    pub fn temp_path(&self) -> &Path {
        &self.temp
    }

    fn fail(&self, op: FileStorageOp, path: &Path, e: io::Error) -> FileStorageError {
        FileStorageError {
            op,
            path: path.to_path_buf(),
            source: Some(e),
        }
    }

    /// Makes the rename itself durable: on POSIX systems a rename lives in the directory.
    fn sync_dir(&self) -> Result<(), FileStorageError> {
        #[cfg(unix)]
        {
            let dir = match self.path.parent() {
                Some(d) if !d.as_os_str().is_empty() => d,
                _ => Path::new("."),
            };
            File::open(dir)
                .and_then(|d| d.sync_all())
                .map_err(|e| self.fail(FileStorageOp::SyncDirectory, dir, e))?;
        }
        Ok(())
    }

    fn write_temp(&self, image: &[u8]) -> Result<(), FileStorageError> {
        let mut f = OpenOptions::new()
            .write(true)
            .create(true)
            .truncate(true)
            .open(&self.temp)
            .map_err(|e| self.fail(FileStorageOp::Create, &self.temp, e))?;
        f.write_all(image)
            .map_err(|e| self.fail(FileStorageOp::Write, &self.temp, e))?;
        f.sync_all()
            .map_err(|e| self.fail(FileStorageOp::Sync, &self.temp, e))
    }
}

impl ParameterStorage for FileStorage {
    type Error = FileStorageError;

    fn load(&mut self, buf: &mut [u8]) -> Result<Option<usize>, FileStorageError> {
        let mut f = match File::open(&self.path) {
            Ok(f) => f,
            Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(None),
            Err(e) => return Err(self.fail(FileStorageOp::Read, &self.path, e)),
        };
        // Bounded: never more than the buffer, whatever the file says.
        let mut n = 0;
        loop {
            if n == buf.len() {
                let mut one = [0u8; 1];
                match f.read(&mut one) {
                    Ok(0) => break,
                    Ok(_) => {
                        return Err(FileStorageError {
                            op: FileStorageOp::TooLarge {
                                capacity: buf.len(),
                            },
                            path: self.path.clone(),
                            source: None,
                        })
                    }
                    Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                    Err(e) => return Err(self.fail(FileStorageOp::Read, &self.path, e)),
                }
            }
            match f.read(&mut buf[n..]) {
                Ok(0) => break,
                Ok(k) => n += k,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(self.fail(FileStorageOp::Read, &self.path, e)),
            }
        }
        Ok(Some(n))
    }

    fn store(&mut self, image: &[u8]) -> Result<(), FileStorageError> {
        if let Err(e) = self.write_temp(image) {
            // The old file was never touched; do not leave a partial temporary file behind.
            let _ = fs::remove_file(&self.temp);
            return Err(e);
        }
        if let Err(e) = fs::rename(&self.temp, &self.path) {
            let _ = fs::remove_file(&self.temp);
            return Err(self.fail(FileStorageOp::Rename, &self.path, e));
        }
        self.sync_dir()
    }

    fn erase(&mut self) -> Result<(), FileStorageError> {
        match fs::remove_file(&self.path) {
            Ok(()) => {}
            Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(()),
            Err(e) => return Err(self.fail(FileStorageOp::Remove, &self.path, e)),
        }
        self.sync_dir()
    }
}

/// What a [`FileStorage`] was doing when it failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum FileStorageOp {
    /// Reading the stored image.
    Read,
    /// The file is larger than the buffer it is read into.
    TooLarge {
        /// Bytes of the buffer.
        capacity: usize,
    },
    /// Creating the temporary file.
    Create,
    /// Writing the temporary file.
    Write,
    /// Syncing the temporary file to the disk.
    Sync,
    /// Renaming the temporary file over the stored one.
    Rename,
    /// Syncing the directory after the rename.
    SyncDirectory,
    /// Removing the stored file.
    Remove,
}

/// A [`FileStorage`] operation failed: which one, on which path, and the system's reason.
#[derive(Debug)]
pub struct FileStorageError {
    /// What was being done.
    pub op: FileStorageOp,
    /// The path it was done on.
    pub path: PathBuf,
    source: Option<io::Error>,
}

impl fmt::Display for FileStorageError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let p = self.path.display();
        let what = match self.op {
            FileStorageOp::TooLarge { capacity } => {
                return write!(
                    f,
                    "parameter file {p} is larger than the {capacity}-byte image buffer"
                )
            }
            FileStorageOp::Read => "cannot read",
            FileStorageOp::Create => "cannot create",
            FileStorageOp::Write => "cannot write",
            FileStorageOp::Sync => "cannot sync",
            FileStorageOp::Rename => "cannot rename the new image to",
            FileStorageOp::SyncDirectory => "cannot sync the directory",
            FileStorageOp::Remove => "cannot remove",
        };
        write!(f, "parameter storage: {what} {p}")?;
        if let Some(e) = &self.source {
            write!(f, ": {e}")?;
        }
        Ok(())
    }
}

impl std::error::Error for FileStorageError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        self.source.as_ref().map(|e| e as _)
    }
}
