//! `--socket PATH`: the gateway on a local (Unix domain) stream socket, where `cocomm` looks by
//! default (CANopenNode's gateway serves one for it).
//!
//! The socket file is made readable and writable by its owner only: the gateway has no
//! authentication, and whoever may connect drives the bus. A socket file left behind by a
//! gateway that was killed is replaced; any other file at the path is left alone and refused.
//! The file is removed when the gateway stops (interrupted).

use super::{client, MAX_CLIENTS};
use crate::fail::Fail;
use duocan::net::Network;
use std::path::Path;
use std::sync::Arc;

/// Serves local-socket clients on `path` until interrupted.
pub async fn listen(net: &Network, timeout_ms: u64, path: &Path) -> Result<(), Fail> {
    let shown = path.display();
    let fail = |e: std::io::Error| Fail::usage(format!("--socket {shown}: {e}"));
    clear_stale(path).map_err(|why| Fail::usage(format!("--socket {shown}: {why}")))?;
    let listener = tokio::net::UnixListener::bind(path).map_err(fail)?;
    // Owner only, before anyone is accepted.
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(path, std::fs::Permissions::from_mode(0o600)).map_err(fail)?;
    eprintln!("duocan gateway: listening on {shown}");
    let slots = Arc::new(tokio::sync::Semaphore::new(MAX_CLIENTS));
    let r = loop {
        let stream = tokio::select! {
            r = listener.accept() => match r {
                Ok((s, _)) => s,
                Err(e) => {
                    eprintln!("duocan gateway: accept: {e}");
                    continue;
                }
            },
            _ = tokio::signal::ctrl_c() => break Ok(()),
        };
        client(net, timeout_ms, &slots, stream).await;
    };
    let _ = std::fs::remove_file(path);
    r
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
