//! The `http_tls_cert` and `http_tls_key` keys of the `[station]` table: the station serves
//! HTTPS (TLS 1.2 and 1.3, rustls with the `ring` provider) with this certificate chain and
//! its private key, both PEM files, relative to the station file's folder.
//!
//! Both or neither; `station check` reads both files and proves that the key is the
//! certificate's, so that a station that was checked does not fail on its first client.

use super::{Source, StationTable};
use rustls::pki_types::pem::PemObject;
use rustls::pki_types::{CertificateDer, PrivateKeyDer};
use rustls::ServerConfig;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The certificate and key the station serves HTTPS with.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Tls {
    /// The certificate chain's PEM file, the station's own certificate first.
    pub cert: PathBuf,
    /// The private key's PEM file (PKCS#8, PKCS#1 or SEC1).
    pub key: PathBuf,
}

/// The key whose file is at fault, and why.
pub type TlsFault = (&'static str, String);

/// The TLS settings of table `t`, checked down to the files' contents.
pub(super) fn tls(src: &Source<'_>, t: &StationTable) -> Result<Option<Tls>, String> {
    let (cert, key) = match (&t.http_tls_cert, &t.http_tls_key) {
        (None, None) => return Ok(None),
        (Some(c), None) => {
            return Err(src.span(c.span(), "http_tls_cert", "set http_tls_key too"));
        }
        (None, Some(k)) => {
            return Err(src.span(k.span(), "http_tls_key", "set http_tls_cert too"));
        }
        (Some(c), Some(k)) => (c, k),
    };
    if t.http.is_none() {
        return Err(src.span(cert.span(), "http_tls_cert", "set http too"));
    }
    let base = Path::new(src.name).parent().unwrap_or(Path::new(""));
    let tls = Tls {
        cert: base.join(cert.get_ref().trim()),
        key: base.join(key.get_ref().trim()),
    };
    server_config(&tls).map_err(|(which, why)| {
        let span = if which == "http_tls_key" {
            key.span()
        } else {
            cert.span()
        };
        src.span(span, which, why)
    })?;
    Ok(Some(tls))
}

/// The server's TLS configuration from the files of `tls`; an error names the key of the file
/// at fault.
pub fn server_config(tls: &Tls) -> Result<Arc<ServerConfig>, TlsFault> {
    // ring rather than aws-lc-rs, which builds C with cmake and nasm: rustls marks it
    // deprecated for want of post-quantum key exchange, which the station's browsers and
    // scripts on the plant's network do not need yet.
    #[allow(deprecated)]
    let provider = Arc::new(rustls::crypto::ring::default_provider());
    let certs = read(&tls.cert, "http_tls_cert")?;
    let certs: Vec<CertificateDer<'static>> = CertificateDer::pem_slice_iter(&certs)
        .collect::<Result<_, _>>()
        .map_err(|e| ("http_tls_cert", not_pem(&tls.cert, e)))?;
    if certs.is_empty() {
        let why = format!(
            "{}: no certificate (\"-----BEGIN CERTIFICATE-----\") in it",
            tls.cert.display()
        );
        return Err(("http_tls_cert", why));
    }
    let key = read(&tls.key, "http_tls_key")?;
    let key = PrivateKeyDer::from_pem_slice(&key).map_err(|e| match e {
        rustls::pki_types::pem::Error::NoItemsFound => {
            let why = format!(
                "{}: no private key (PEM: PKCS#8, PKCS#1 or SEC1) in it",
                tls.key.display()
            );
            ("http_tls_key", why)
        }
        e => ("http_tls_key", not_pem(&tls.key, e)),
    })?;
    // Checked one by one first so that the error names the file at fault; the builder makes
    // the same checks again.
    let signer = provider
        .key_provider
        .load_private_key(key.clone_key())
        .map_err(|e| {
            let why = format!("{}: not a usable private key: {e}", tls.key.display());
            ("http_tls_key", why)
        })?;
    let pair = rustls::sign::CertifiedKey::new(certs.clone(), signer);
    match pair.keys_match() {
        Ok(()) | Err(rustls::Error::InconsistentKeys(rustls::InconsistentKeys::Unknown)) => {}
        Err(rustls::Error::InconsistentKeys(_)) => {
            let why = format!(
                "{} is not the private key of the certificate in {}",
                tls.key.display(),
                tls.cert.display()
            );
            return Err(("http_tls_key", why));
        }
        Err(e) => {
            let why = format!("{}: not a usable certificate: {e}", tls.cert.display());
            return Err(("http_tls_cert", why));
        }
    }
    let mut config = ServerConfig::builder_with_provider(provider)
        .with_safe_default_protocol_versions()
        .and_then(|b| b.with_no_client_auth().with_single_cert(certs, key))
        .map_err(|e| ("http_tls_cert", format!("{}: {e}", tls.cert.display())))?;
    // The station speaks HTTP/1.1 alone.
    config.alpn_protocols = vec![b"http/1.1".to_vec()];
    Ok(Arc::new(config))
}

/// The bytes of the file at `path`, bounded: a certificate chain or a key is a few KB.
fn read(path: &Path, key: &'static str) -> Result<Vec<u8>, TlsFault> {
    const MAX: u64 = 1 << 20;
    let fail = |e: &dyn std::fmt::Display| (key, format!("cannot read {}: {e}", path.display()));
    let meta = std::fs::metadata(path).map_err(|e| fail(&e))?;
    if !meta.is_file() {
        return Err(fail(&"not a file"));
    }
    if meta.len() > MAX {
        return Err(fail(&"over 1 MiB: not a PEM certificate or key"));
    }
    std::fs::read(path).map_err(|e| fail(&e))
}

fn not_pem(path: &Path, e: rustls::pki_types::pem::Error) -> String {
    format!("{}: not a PEM file: {e}", path.display())
}

#[cfg(test)]
#[path = "tls_tests.rs"]
mod tests;
