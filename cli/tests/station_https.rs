//! The station's HTTP over TLS (`http_tls_cert`, `http_tls_key`): a client that trusts the
//! station's certificate reads its status, also while another client connects and stays
//! silent; plain HTTP on that port gets nothing; a key that is not the certificate's is
//! refused by `station check`.

mod common;
#[path = "station_http/log.rs"]
mod log;
use log::{file, next_before, stderr_lines};
use std::io::{Read, Write};
use std::path::Path;
use std::process::Command;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// A folder holding a self-signed certificate for 127.0.0.1 (`cert.pem`, `key.pem`, its DER
/// returned) and another certificate's key (`other.pem`).
fn certificates(dir: &Path) -> Vec<u8> {
    let made = rcgen::generate_simple_self_signed(vec!["127.0.0.1".into()]).unwrap();
    let other = rcgen::generate_simple_self_signed(vec!["127.0.0.1".into()]).unwrap();
    std::fs::write(dir.join("cert.pem"), made.cert.pem()).unwrap();
    std::fs::write(dir.join("key.pem"), made.signing_key.serialize_pem()).unwrap();
    std::fs::write(dir.join("other.pem"), other.signing_key.serialize_pem()).unwrap();
    made.cert.der().to_vec()
}

/// `GET path` over TLS on `addr`, trusting the certificate `der` alone: the status code and
/// the body.
fn get_tls(addr: &str, path: &str, token: &str, der: &[u8]) -> (u16, String) {
    let mut roots = rustls::RootCertStore::empty();
    roots
        .add(rustls::pki_types::CertificateDer::from(der.to_vec()))
        .unwrap();
    #[allow(deprecated)] // ring: the station's provider too (see its config module)
    let provider = Arc::new(rustls::crypto::ring::default_provider());
    let config = rustls::ClientConfig::builder_with_provider(provider)
        .with_safe_default_protocol_versions()
        .unwrap()
        .with_root_certificates(roots)
        .with_no_client_auth();
    let name = rustls::pki_types::ServerName::try_from("127.0.0.1").unwrap();
    let conn = rustls::ClientConnection::new(Arc::new(config), name).unwrap();
    let tcp = std::net::TcpStream::connect(addr).expect("connect");
    tcp.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
    let mut s = rustls::StreamOwned::new(conn, tcp);
    write!(
        s,
        "GET {path} HTTP/1.1\r\nHost: {addr}\r\nAuthorization: Bearer {token}\r\nConnection: close\r\n\r\n"
    )
    .expect("write over TLS");
    let mut bytes = Vec::new();
    // A server that closes without close_notify ends the read with an error after the data.
    let _ = s.read_to_end(&mut bytes);
    let text = String::from_utf8_lossy(&bytes).into_owned();
    let code = text
        .split(' ')
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or(0);
    let body = text.split_once("\r\n\r\n").map_or("", |(_, b)| b);
    (code, body.to_string())
}

/// What a plain-HTTP client reads from `addr` (nothing or an error when the port speaks TLS).
fn get_plain(addr: &str) -> String {
    let mut s = std::net::TcpStream::connect(addr).expect("connect");
    s.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
    let _ = write!(
        s,
        "GET /api/networks HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n"
    );
    let mut bytes = Vec::new();
    let _ = s.read_to_end(&mut bytes);
    String::from_utf8_lossy(&bytes).into_owned()
}

#[test]
fn the_station_serves_https_with_its_certificate() {
    let _one = common::one_station();
    let dir = std::env::temp_dir().join(format!("duocan-station-https-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let der = certificates(&dir);
    let token = "test-token-0123456789";
    let two = std::fs::read_to_string(file("tests/station_files/two.toml")).unwrap();
    let head = format!("[station]\nhttp = \"127.0.0.1:0\"\nhttp_token = \"{token}\"\n");
    // A key that is not the certificate's: `check` says which key of which line.
    let wrong = dir.join("wrong.toml");
    std::fs::write(
        &wrong,
        format!("{head}http_tls_cert = \"cert.pem\"\nhttp_tls_key = \"other.pem\"\n\n{two}"),
    )
    .unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_duocan"))
        .args(["station", "check", wrong.to_str().unwrap()])
        .output()
        .expect("run duocan");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{err}");
    assert!(
        err.contains(&format!("{}:5:16: http_tls_key: ", wrong.display()))
            && err.contains("is not the private key of the certificate"),
        "{err}"
    );

    let station = dir.join("tls.toml");
    std::fs::write(
        &station,
        format!("{head}http_tls_cert = \"cert.pem\"\nhttp_tls_key = \"key.pem\"\n\n{two}"),
    )
    .unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_duocan"))
        .args(["station", "check", station.to_str().unwrap()])
        .output()
        .expect("run duocan");
    let said = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{said}");
    assert!(said.contains("https: 127.0.0.1:0"), "{said}");

    let mut child = common::station_run(station.to_str().unwrap())
        .spawn()
        .expect("run duocan");
    let rx = stderr_lines(&mut child);
    let end = Instant::now() + Duration::from_secs(120);
    let mut addr = None;
    let mut seen = vec![];
    while let Some(line) = next_before(&rx, end) {
        seen.push(line.clone());
        if let Some(a) = line.split("https listening on ").nth(1) {
            addr = Some(a.trim().to_string());
            break;
        }
    }
    let Some(addr) = addr else {
        let _ = child.kill();
        panic!("no https address in 120 s:\n{}", seen.join("\n"));
    };
    // A client that connects and says nothing holds no one else up: handshakes run side by side.
    let silent = std::net::TcpStream::connect(&addr).expect("connect");
    let plain = get_plain(&addr);
    let (code, json) = get_tls(&addr, "/api/networks", token, &der);
    drop(silent);
    let (unauth, _) = get_tls(&addr, "/api/networks", "test-token-0123456788", &der);
    let _ = child.kill();
    let _ = child.wait();
    let _ = std::fs::remove_dir_all(&dir);
    assert!(
        !plain.starts_with("HTTP/"),
        "plain HTTP was answered: {plain}"
    );
    assert_eq!((code, unauth), (200, 401), "{json}");
    let v: serde_json::Value = serde_json::from_str(&json).expect("json");
    let names: Vec<_> = v
        .as_array()
        .expect("a list")
        .iter()
        .map(|n| n["name"].as_str().unwrap_or("").to_string())
        .collect();
    assert_eq!(names, ["east", "west"], "{json}");
}
