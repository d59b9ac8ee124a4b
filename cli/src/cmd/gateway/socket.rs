//! The gateway on a local (Unix domain) stream socket, where `cocomm` looks by default
//! (CANopenNode's gateway serves one for it).
//!
//! The socket file is made readable and writable by its owner only (or as the station's file
//! says): the gateway has no authentication, and whoever may connect drives the bus. A socket
//! file left behind by a gateway that was killed is replaced; any other file at the path is
//! left alone and refused. The file is removed when the gateway stops ([`SocketFile`]).

use std::path::{Path, PathBuf};

/// The socket file a gateway listens on: removed when dropped, so that it goes on every way
/// the gateway stops but a kill (and then the next start replaces it).
#[derive(Debug)]
pub struct SocketFile(PathBuf);

impl Drop for SocketFile {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}

/// Listens on a local socket at `path` with the permission bits `mode` (set before any client
/// is accepted); the error says why not.
pub fn bind(path: &Path, mode: u32) -> Result<(tokio::net::UnixListener, SocketFile), String> {
    clear_stale(path)?;
    let listener = tokio::net::UnixListener::bind(path).map_err(|e| e.to_string())?;
    let file = SocketFile(path.to_path_buf());
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(path, std::fs::Permissions::from_mode(mode))
        .map_err(|e| e.to_string())?;
    Ok((listener, file))
}

/// Removes a socket file nobody listens on (a gateway's that was killed); refuses a socket in
/// use and anything that is not a socket.
fn clear_stale(path: &Path) -> Result<(), String> {
    use std::os::unix::fs::FileTypeExt;
    let meta = match std::fs::symlink_metadata(path) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(e.to_string()),
    };
    if !meta.file_type().is_socket() {
        return Err("a file that is not a socket is there; give another path".into());
    }
    match std::os::unix::net::UnixStream::connect(path) {
        Ok(_) => Err("a gateway (or another program) already listens there".into()),
        Err(_) => std::fs::remove_file(path).map_err(|e| e.to_string()),
    }
}
