use super::super::parse;
use super::Tls;
use std::path::{Path, PathBuf};

/// A fresh folder with a self-signed certificate for 127.0.0.1 (`cert.pem`, `key.pem`), the
/// key of another (`other.pem`) and a file that is no PEM (`junk.pem`).
fn folder(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("duocan-tls-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let made = rcgen::generate_simple_self_signed(vec!["127.0.0.1".into()]).unwrap();
    let other = rcgen::generate_simple_self_signed(vec!["127.0.0.1".into()]).unwrap();
    std::fs::write(dir.join("cert.pem"), made.cert.pem()).unwrap();
    std::fs::write(dir.join("key.pem"), made.signing_key.serialize_pem()).unwrap();
    std::fs::write(dir.join("other.pem"), other.signing_key.serialize_pem()).unwrap();
    std::fs::write(dir.join("junk.pem"), "certificate: yes\n").unwrap();
    dir
}

const NET: &str = "\n[[network]]\nname = \"a\"\nbuses = \"sim-pairs\"\nnode_id = 1\n";

/// The station file `s.toml` in `dir` with the `[station]` keys `keys`, read.
fn station(dir: &Path, keys: &str) -> Result<Option<Tls>, String> {
    let name = dir.join("s.toml");
    let text = format!("[station]\nhttp = \"127.0.0.1:0\"\n{keys}{NET}");
    parse(&text, &name.to_string_lossy()).map(|s| s.http.and_then(|h| h.tls))
}

#[test]
fn a_certificate_and_its_key_are_taken_from_the_files_folder() {
    let dir = folder("good");
    let tls = station(
        &dir,
        "http_tls_cert = \"cert.pem\"\nhttp_tls_key = \"key.pem\"\n",
    );
    let want = Tls {
        cert: dir.join("cert.pem"),
        key: dir.join("key.pem"),
    };
    assert_eq!(tls, Ok(Some(want.clone())));
    assert!(super::server_config(&want).is_ok());
    assert_eq!(station(&dir, ""), Ok(None));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn each_fault_names_the_file_line_and_key() {
    let dir = folder("bad");
    let at = |line_col: &str| format!("{}:{line_col}: ", dir.join("s.toml").display());
    let err = |keys: &str| station(&dir, keys).unwrap_err();

    let e = err("http_tls_cert = \"cert.pem\"\n");
    assert!(
        e.starts_with(&format!(
            "{}http_tls_cert: set http_tls_key too",
            at("3:17")
        )),
        "{e}"
    );
    let e = err("http_tls_key = \"key.pem\"\n");
    assert!(
        e.starts_with(&format!(
            "{}http_tls_key: set http_tls_cert too",
            at("3:16")
        )),
        "{e}"
    );
    let e = err("http_tls_cert = \"gone.pem\"\nhttp_tls_key = \"key.pem\"\n");
    assert!(
        e.starts_with(&format!("{}http_tls_cert: cannot read", at("3:17"))),
        "{e}"
    );
    assert!(e.contains("gone.pem"), "{e}");
    let e = err("http_tls_cert = \"junk.pem\"\nhttp_tls_key = \"key.pem\"\n");
    assert!(
        e.starts_with(&format!("{}http_tls_cert: ", at("3:17"))) && e.contains("no certificate"),
        "{e}"
    );
    let e = err("http_tls_cert = \"cert.pem\"\nhttp_tls_key = \"junk.pem\"\n");
    assert!(
        e.starts_with(&format!("{}http_tls_key: ", at("4:16"))) && e.contains("no private key"),
        "{e}"
    );
    // A certificate given as its key: PEM, but no key in it.
    let e = err("http_tls_cert = \"cert.pem\"\nhttp_tls_key = \"cert.pem\"\n");
    assert!(
        e.contains("http_tls_key: ") && e.contains("no private key"),
        "{e}"
    );
    let e = err("http_tls_cert = \"cert.pem\"\nhttp_tls_key = \"other.pem\"\n");
    assert!(
        e.starts_with(&format!("{}http_tls_key: ", at("4:16")))
            && e.contains("is not the private key of the certificate"),
        "{e}"
    );
    let e = err("http_tls_cert = \".\"\nhttp_tls_key = \"key.pem\"\n");
    assert!(
        e.contains("http_tls_cert: cannot read") && e.contains("not a file"),
        "{e}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn tls_without_an_address_is_an_address_forgotten() {
    let text = format!("[station]\nhttp_tls_cert = \"c.pem\"\nhttp_tls_key = \"k.pem\"{NET}");
    let e = parse(&text, "s.toml").unwrap_err();
    assert!(
        e.starts_with("s.toml:2:17: http_tls_cert: set http too"),
        "{e}"
    );
}
