//! CANopenNode's CiA 309-3 client, `cocomm`, for the tests that drive a gateway with it (the
//! tool's tests on the host, and the vcan tier's in the VM, which include this file).

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::OnceLock;

/// Where the CANopenNode build script is, from the including crate's folder (`cli/` or
/// `tiers/`, both one level below the repository).
const BUILD_SH: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../shared/peers/canopennode/build.sh"
);

/// The `cocomm` to run: `DUOCAN_COCOMM`, else one built once for this test run. Panics, saying
/// what is missing, when there is none.
pub fn cocomm() -> &'static Path {
    static BUILT: OnceLock<PathBuf> = OnceLock::new();
    BUILT.get_or_init(|| {
        if let Some(p) = std::env::var_os("DUOCAN_COCOMM") {
            let p = PathBuf::from(p);
            assert!(
                p.is_file(),
                "DUOCAN_COCOMM={} is not a file: point it at a built cocomm",
                p.display()
            );
            return p;
        }
        let script = Path::new(BUILD_SH);
        assert!(
            script.is_file(),
            "cannot build cocomm: {} is missing (CANopenNode's sources, kept beside the \
             repository); give DUOCAN_COCOMM=/path/to/cocomm instead",
            script.display()
        );
        // Built once into cargo's folder for test files, and reused by later runs.
        let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("canopennode");
        if dir.join("cocomm").is_file() {
            return dir.join("cocomm");
        }
        let out = Command::new("bash")
            .arg(script)
            .arg(&dir)
            .output()
            .expect("run CANopenNode's build.sh");
        let bin = dir.join("cocomm");
        assert!(
            out.status.success() && bin.is_file(),
            "building cocomm with {} failed ({}): {}{}",
            script.display(),
            out.status,
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        bin
    })
}

/// Runs cocomm with `args` and `stdin`; its standard output, standard error and exit code. A
/// cocomm that has not ended in a minute waits for an answer the gateway never sent: killed,
/// and the test fails saying so.
pub fn run_cocomm(args: &[std::ffi::OsString], stdin: &str) -> (String, String, i32) {
    use std::io::Read;
    let mut c = Command::new(cocomm())
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run cocomm");
    c.stdin.take().unwrap().write_all(stdin.as_bytes()).unwrap();
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(60);
    let status = loop {
        if let Some(st) = c.try_wait().unwrap() {
            break st;
        }
        if std::time::Instant::now() > deadline {
            let _ = c.kill();
            let _ = c.wait();
            let mut out = String::new();
            let _ = c.stdout.take().unwrap().read_to_string(&mut out);
            panic!("cocomm hung: an answer it waits for never came; it printed:\n{out}");
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    };
    let mut out = String::new();
    let mut err = String::new();
    c.stdout.take().unwrap().read_to_string(&mut out).unwrap();
    c.stderr.take().unwrap().read_to_string(&mut err).unwrap();
    (out, err, status.code().unwrap_or(-1))
}

/// Sends `script` through cocomm to the gateway on the local socket `socket` (`-o flat`: every
/// answer on standard output); its standard output and exit code. Anything on its standard
/// error fails the test.
pub fn cocomm_socket(socket: &Path, script: &str) -> (String, i32) {
    let mut args = vec![std::ffi::OsString::from("-s"), socket.into()];
    args.extend(["-o", "flat"].map(Into::into));
    let (out, err, code) = run_cocomm(&args, script);
    assert!(err.is_empty(), "cocomm: {err}");
    (out, code)
}

/// Checks cocomm's output `out` for a script of `cases` (request, the answer cocomm prints):
/// each answer, and that cocomm stayed in step (one answer a line: a missing one would hang it,
/// an extra one shift every answer after it).
pub fn check_answers(out: &str, cases: &[(&str, String)]) {
    let got: Vec<&str> = out.split("\r\n").collect();
    for (i, (req, want)) in cases.iter().enumerate() {
        assert_eq!(
            got.get(i).copied(),
            Some(want.as_str()),
            "answer to {req:?}\nall of it:\n{out}"
        );
    }
    assert_eq!(got.len(), cases.len() + 1, "{out:?}");
    assert_eq!(got.last(), Some(&""), "{out:?}");
}

/// The script of `cases`: one request a line.
pub fn script(cases: &[(&str, String)]) -> String {
    cases.iter().map(|(l, _)| format!("{l}\n")).collect()
}
