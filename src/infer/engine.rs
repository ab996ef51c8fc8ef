//! INFER: the engine, ONNX Runtime, loaded at run time from its shared library.
//!
//! kitti2pgm links no ONNX Runtime: it opens the library that the `onnxruntime` Python package
//! ships (`onnxruntime/capi/libonnxruntime.so.*`, installed by `tools/install.sh` with the
//! trainer's export extra), so that nothing is downloaded at build time and the CLI and the
//! trainer run the very same runtime. Where it is looked for, first found wins:
//!
//! 1. the path given (`kitti2pgm infer --onnxruntime PATH`: the library file or its folder);
//! 2. `KITTI2PGM_ONNXRUNTIME`, then `ORT_DYLIB_PATH` (the `ort` crate's own variable);
//! 3. the `onnxruntime` package of `python3` on `PATH` (asked where it is installed).
//!
//! A GPU build runs the same models through ONNX Runtime's CUDA provider: the `onnxruntime-gpu`
//! package's library, found the same way (docs/infer.md).

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use crate::error::{Error, Result};

/// The environment variable that names ONNX Runtime's library (or its folder).
pub const LIBRARY_VAR: &str = "KITTI2PGM_ONNXRUNTIME";

/// The loaded runtime: one per process (ONNX Runtime's library is loaded once).
static RUNTIME: OnceLock<std::result::Result<Runtime, String>> = OnceLock::new();

/// ONNX Runtime, loaded.
pub struct Runtime {
    /// Its environment (sessions are made in it).
    pub(super) env: ort::environment::Environment,
    /// The library file it was loaded from.
    pub library: PathBuf,
}

impl std::fmt::Debug for Runtime {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Runtime")
            .field("library", &self.library)
            .finish()
    }
}

/// The library file in `path` (the file itself, or the newest-looking library in a folder).
fn library_in(path: &Path) -> Option<PathBuf> {
    if path.is_file() {
        return Some(path.to_path_buf());
    }
    let mut found: Vec<PathBuf> = std::fs::read_dir(path)
        .ok()?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.file_name().and_then(|n| n.to_str()).is_some_and(|n| {
                (n.starts_with("libonnxruntime.so") || n == "libonnxruntime.dylib")
                    || n == "onnxruntime.dll"
                    || (n.starts_with("libonnxruntime.") && n.ends_with(".dylib"))
            })
        })
        .collect();
    // libonnxruntime.so.1.32.0 before libonnxruntime.so: the versioned file is the real one.
    found.sort_by_key(|p| std::cmp::Reverse(p.as_os_str().len()));
    found.into_iter().next()
}

/// Where the `onnxruntime` package of `python3` keeps its library, if it is installed.
fn python_library() -> Option<PathBuf> {
    let out = std::process::Command::new("python3")
        .args([
            "-c",
            "import importlib.util as u, os; s = u.find_spec('onnxruntime'); \
             print(os.path.join(os.path.dirname(s.origin), 'capi') if s else '')",
        ])
        .stderr(std::process::Stdio::null())
        .output()
        .ok()?;
    let dir = String::from_utf8(out.stdout).ok()?;
    let dir = dir.trim();
    (!dir.is_empty())
        .then(|| library_in(Path::new(dir)))
        .flatten()
}

/// The library to load: `given`, else the environment variables, else Python's package; the
/// error says every place looked at.
pub fn find_library(given: Option<&Path>) -> Result<PathBuf> {
    if let Some(p) = given {
        return library_in(p).ok_or_else(|| {
            Error::Config(format!(
                "{}: no ONNX Runtime library there (libonnxruntime.so*, .dylib or onnxruntime.dll)",
                p.display()
            ))
        });
    }
    for var in [LIBRARY_VAR, "ORT_DYLIB_PATH"] {
        if let Some(v) = std::env::var_os(var).filter(|v| !v.is_empty()) {
            let p = PathBuf::from(v);
            return library_in(&p).ok_or_else(|| {
                Error::Config(format!(
                    "{var}={}: no ONNX Runtime library there",
                    p.display()
                ))
            });
        }
    }
    python_library().ok_or_else(|| {
        Error::Config(format!(
            "ONNX Runtime not found: install it with tools/install.sh (the onnxruntime Python \
             package), or name its library with --onnxruntime or {LIBRARY_VAR}"
        ))
    })
}

/// The process's runtime, loaded from [`find_library`]`(given)` on first use; later calls get
/// the same one (a different `given` then is refused).
pub fn runtime(given: Option<&Path>) -> Result<&'static Runtime> {
    let loaded = RUNTIME.get_or_init(|| {
        let library = find_library(given).map_err(|e| e.to_string())?;
        let env = ort::init_from(&library)
            .map_err(|e| format!("{}: not a usable ONNX Runtime: {e}", library.display()))?
            .with_name("kitti2pgm")
            .build()
            .map_err(|e| format!("{}: {e}", library.display()))?;
        Ok(Runtime { env, library })
    });
    let rt = loaded.as_ref().map_err(|e| Error::Config(e.clone()))?;
    if let Some(g) = given {
        if library_in(g).as_deref() != Some(rt.library.as_path()) {
            return Err(Error::Config(format!(
                "ONNX Runtime is already loaded from {}; {} cannot be loaded beside it",
                rt.library.display(),
                g.display()
            )));
        }
    }
    Ok(rt)
}
