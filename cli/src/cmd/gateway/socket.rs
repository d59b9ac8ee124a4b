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

/// Listens on a local socket at `path` with the permission bits `mode`, which the file has
/// from the moment it appears at `path`; the error says why not.
///
/// `bind(2)` creates the file with the process's umask (often 0o022: connectable by everyone
/// who can reach the folder), so a `chmod` after it leaves an instant in which any local user
/// could connect, and a connection made then stays. Setting the umask around the bind is no
/// cure: the umask is the whole process's, and the station's other threads create files
/// (audit trail) meanwhile. So the socket is bound inside a private folder made beside `path`
/// (mode 0o700: no other user may even look up a name in it, and so cannot connect), given
/// `mode` there, and only then linked to `path` (`link(2)`, which never replaces a file that
/// appeared there meanwhile); the private folder and its name are removed at once. The folder
/// is beside `path` so that the link stays on one file system.
pub fn bind(path: &Path, mode: u32) -> Result<(tokio::net::UnixListener, SocketFile), String> {
    use std::os::unix::fs::PermissionsExt;
    clear_stale(path)?;
    let parent = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let private = private_dir(parent)?;
    let inside = private.join("s");
    if inside.as_os_str().len() > MAX_PATH {
        let _ = std::fs::remove_dir(&private);
        return Err(format!(
            "{} is too long for the private folder the socket is bound in first ({} bytes, at \
             most {MAX_PATH}): give a shorter path",
            path.display(),
            inside.as_os_str().len()
        ));
    }
    let bound = (|| -> Result<tokio::net::UnixListener, String> {
        let listener = tokio::net::UnixListener::bind(&inside).map_err(|e| e.to_string())?;
        std::fs::set_permissions(&inside, std::fs::Permissions::from_mode(mode))
            .map_err(|e| e.to_string())?;
        std::fs::hard_link(&inside, path).map_err(|e| match e.kind() {
            std::io::ErrorKind::AlreadyExists => {
                "a file appeared there while the socket was bound; give another path".to_string()
            }
            _ => e.to_string(),
        })?;
        Ok(listener)
    })();
    // The private name and folder go whatever happened: the socket lives on at `path`.
    let _ = std::fs::remove_file(&inside);
    let _ = std::fs::remove_dir(&private);
    Ok((bound?, SocketFile(path.to_path_buf())))
}

/// The longest socket path the system takes (`sun_path` holds 108 bytes with its NUL).
const MAX_PATH: usize = 107;

/// Makes a new folder in `parent` that only this user may enter (0o700, whatever the umask:
/// a umask only takes bits away), with a short name (the socket's path inside it is bounded).
fn private_dir(parent: &Path) -> Result<PathBuf, String> {
    use std::os::unix::fs::DirBuilderExt;
    let mut last = None;
    // A name taken (another gateway binding beside this one, or a folder a killed one left)
    // is passed over.
    for n in 0..64u32 {
        let dir = parent.join(format!(".gw{}{n}", std::process::id() % 1000));
        match std::fs::DirBuilder::new().mode(0o700).create(&dir) {
            Ok(()) => return Ok(dir),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => last = Some(e),
            Err(e) => {
                return Err(format!(
                    "cannot make a private folder in {}: {e}",
                    parent.display()
                ))
            }
        }
    }
    Err(format!(
        "cannot make a private folder in {}: {}",
        parent.display(),
        last.map_or_else(String::new, |e| e.to_string())
    ))
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

#[cfg(test)]
mod tests {
    use super::bind;
    use std::os::unix::fs::PermissionsExt;

    fn dir(name: &str) -> std::path::PathBuf {
        let d = std::env::temp_dir().join(format!("duocan-sock-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    /// The file has its mode as it appears, takes clients, leaves nothing else beside it, and
    /// goes when dropped; a path in use or taken by another file is refused.
    #[tokio::test]
    async fn the_socket_appears_with_its_mode_and_nothing_else() {
        for mode in [0o600, 0o660] {
            let d = dir(&format!("{mode:o}"));
            let path = d.join("gw.sock");
            let (listener, file) = bind(&path, mode).unwrap();
            let m = std::fs::symlink_metadata(&path)
                .unwrap()
                .permissions()
                .mode();
            assert_eq!(m & 0o777, mode, "{m:o}");
            let names: Vec<_> = std::fs::read_dir(&d)
                .unwrap()
                .map(|e| e.unwrap().file_name())
                .collect();
            assert_eq!(names, ["gw.sock"], "the private folder is left behind");
            let client = tokio::net::UnixStream::connect(&path).await.unwrap();
            let (_served, _) = listener.accept().await.unwrap();
            drop(client);
            let e = bind(&path, mode).unwrap_err();
            assert!(e.contains("already listens"), "{e}");
            drop(file);
            assert!(!path.exists());
            std::fs::write(&path, "x").unwrap();
            let e = bind(&path, mode).unwrap_err();
            assert!(e.contains("not a socket"), "{e}");
            let _ = std::fs::remove_dir_all(&d);
        }
    }

    /// The folder the socket is bound in is this user's alone, whatever the umask.
    #[test]
    fn the_private_folder_is_the_users_alone() {
        let d = dir("private");
        let p = super::private_dir(&d).unwrap();
        let m = std::fs::metadata(&p).unwrap().permissions().mode();
        assert_eq!(m & 0o777, 0o700, "{m:o}");
        // A second one beside it has a name of its own.
        let q = super::private_dir(&d).unwrap();
        assert_ne!(p, q);
        let _ = std::fs::remove_dir_all(&d);
    }

    /// A path the system takes whose private folder's path it would not: refused, naming
    /// why, and nothing left behind.
    #[tokio::test]
    async fn a_path_too_long_for_the_private_folder_is_refused_and_leaves_nothing() {
        let d = dir("long");
        // A folder whose path is 105 bytes long, and a socket named `a` in it: 107 bytes.
        let deep = d.join("y".repeat(105 - d.as_os_str().len() - 1));
        std::fs::create_dir_all(&deep).unwrap();
        let path = deep.join("a");
        assert_eq!(path.as_os_str().len(), 107);
        let e = bind(&path, 0o600).unwrap_err();
        assert!(e.contains("too long for the private folder"), "{e}");
        assert_eq!(std::fs::read_dir(&deep).unwrap().count(), 0);
        let _ = std::fs::remove_dir_all(&d);
    }
}
