//! Shared helpers: fixture paths, a temp dir per test, the binary.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// `fixtures/raw`: always present.
pub fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/raw")
}

/// `../shared/kitti`, when this checkout sits beside it.
pub fn shared() -> Option<PathBuf> {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/kitti");
    p.join("raw").is_dir().then_some(p)
}

/// The richest raw root available: the shared 30 scans, else the fixtures' 3.
pub fn raw_root() -> PathBuf {
    shared().map(|s| s.join("raw")).unwrap_or_else(fixtures)
}

/// `fixtures/<name>` (raw, semantickitti, kitti_object).
pub fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fixtures")
        .join(name)
}

/// A writable copy of `fixtures/<name>` under `dir`.
pub fn copy_of(name: &str, dir: &Path) -> PathBuf {
    let to = dir.join(name);
    copy_tree(&fixture(name), &to);
    to
}

/// Runs the binary, killing it after `limit`: (exit code, stderr), or `None` when it had to be
/// killed (a hang).
pub fn run_limited(args: &[&str], limit: std::time::Duration) -> Option<(i32, String)> {
    let mut child = Command::new(env!("CARGO_BIN_EXE_kitti2pgm"))
        .args(args)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("run kitti2pgm");
    let start = std::time::Instant::now();
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            let mut e = String::new();
            std::io::Read::read_to_string(child.stderr.as_mut().unwrap(), &mut e).unwrap();
            return Some((status.code().unwrap_or(-1), e));
        }
        if start.elapsed() > limit {
            child.kill().unwrap();
            child.wait().unwrap();
            return None;
        }
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
}

/// The fixture drive folder of drive `n`.
pub fn fixture_drive(n: u32) -> PathBuf {
    fixtures().join(format!("2011_09_26/2011_09_26_drive_{n:04}_sync"))
}

/// A fresh temporary folder.
pub fn tmp() -> tempfile::TempDir {
    tempfile::tempdir().expect("temp dir")
}

/// Copies `src` into `dst` recursively.
pub fn copy_tree(src: &Path, dst: &Path) {
    std::fs::create_dir_all(dst).unwrap();
    for e in std::fs::read_dir(src).unwrap() {
        let e = e.unwrap();
        let to = dst.join(e.file_name());
        if e.file_type().unwrap().is_dir() {
            copy_tree(&e.path(), &to);
        } else {
            std::fs::copy(e.path(), &to).unwrap();
        }
    }
}

/// A writable copy of the fixtures (to break files in).
pub fn fixture_copy(dir: &Path) -> PathBuf {
    let root = dir.join("raw");
    copy_tree(&fixtures(), &root);
    root
}

/// Runs the binary.
pub fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_kitti2pgm"))
        .args(args)
        .output()
        .expect("run kitti2pgm")
}

/// Runs the binary and returns (exit code, stdout, stderr).
pub fn run_text(args: &[&str]) -> (i32, String, String) {
    let o = run(args);
    (
        o.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// `path` as a `&str`.
pub fn s(path: &Path) -> &str {
    path.to_str().unwrap()
}

/// Every file under `dir` as (path relative to `dir`, bytes), sorted by path.
pub fn tree_bytes(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.push((
                    p.strip_prefix(dir).unwrap().display().to_string(),
                    std::fs::read(&p).unwrap(),
                ));
            }
        }
    }
    out.sort();
    out
}

/// The default conversion of the fixtures into `out` (SqueezeSeg's map, `.npy` and `.label`),
/// through the library: what `kitti2pgm convert fixtures/raw --out OUT` writes, without a process.
pub fn convert_fixtures_in_process(out: &Path) -> kitti2pgm::format::summary::ConvertSummary {
    use kitti2pgm::convert::{convert, ConvertOptions};
    use kitti2pgm::plan::{FrameSelection, Plan};
    let plan = Plan::build_as(&fixtures(), FrameSelection::Annotated, None).unwrap();
    let opts = ConvertOptions {
        map_origin: Some(
            kitti2pgm::project::MapChoice::default()
                .origin(Some(kitti2pgm::source::kitti::DatasetKind::Raw)),
        ),
        ..ConvertOptions::new(out)
    };
    let summary = convert(&plan, &opts, &|_| {}).unwrap();
    assert!(!summary.has_failures(), "{:?}", summary.failures);
    summary
}

/// Converts the fixtures into `out` with `extra` options; panics with stderr on failure. The
/// default conversion (no options) runs in process.
pub fn convert_fixtures(out: &Path, extra: &[&str]) {
    if extra.is_empty() {
        convert_fixtures_in_process(out);
        return;
    }
    let raw = fixtures();
    let mut args = vec!["convert", s(&raw), "--out", s(out), "--no-progress"];
    args.extend_from_slice(extra);
    let (code, _, stderr) = run_text(&args);
    assert_eq!(code, 0, "{args:?}: {stderr}");
}

/// Runs `convert ROOT --out OUT --json EXTRA...`; returns (exit code, summary JSON or null,
/// stderr).
pub fn convert_json(root: &Path, out: &Path, extra: &[&str]) -> (i32, serde_json::Value, String) {
    let mut args = vec![
        "convert",
        s(root),
        "--out",
        s(out),
        "--json",
        "--no-progress",
    ];
    args.extend_from_slice(extra);
    let (code, stdout, stderr) = run_text(&args);
    let j = serde_json::from_str(&stdout).unwrap_or(serde_json::Value::Null);
    (code, j, stderr)
}

/// `../shared/<sub>`, for the tests marked `#[ignore = "needs ../shared"]`: `tools/run-tests.sh`
/// runs them (`--include-ignored`) where `../shared` is present, and there a missing file fails
/// the test instead of passing it silently.
pub fn needs_shared(sub: &str) -> PathBuf {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../shared")
        .join(sub);
    assert!(
        p.exists(),
        "{} is missing: this test needs ../shared beside the checkout",
        p.display()
    );
    p
}

/// Runs `args` (a command with `--json`, added here when missing), which must fail with the
/// library error `kind` (`Error::kind`: `output_over_input`, `config`, `not_a_file`...); returns
/// the error record it prints (`kind`, `message`, `hint`, `exit`). Tests judge a failure by its
/// kind and exit status, not by the words of its message.
pub fn fails_with(args: &[&str], kind: &str) -> serde_json::Value {
    let mut a = args.to_vec();
    if !a.contains(&"--json") {
        a.push("--json");
    }
    let (code, stdout, stderr) = run_text(&a);
    let v: serde_json::Value = serde_json::from_str(&stdout)
        .unwrap_or_else(|e| panic!("{args:?}: no JSON error record ({e}): {stdout} {stderr}"));
    let err = v["error"].clone();
    assert_eq!(err["kind"], kind, "{args:?}: {stderr}");
    assert_eq!(
        err["exit"], code,
        "{args:?}: the record's exit status is the process's"
    );
    assert!(!err["message"].as_str().unwrap_or("").is_empty(), "{err}");
    err
}
