//! The shape of the code, kept: the library's modules import each other without a circle, at
//! every depth (data flows one way; siblings in a folder too), no source file grows past 500
//! lines and no function past 80.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

fn sources() -> (PathBuf, Vec<PathBuf>) {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    files.sort();
    (src, files)
}

/// The module path of a source file: `check/inventory.rs` -> `[check, inventory]`,
/// `check/mod.rs` -> `[check]`, `lib.rs` -> `[]`.
fn module_of(rel: &Path) -> Vec<String> {
    let mut parts: Vec<String> = rel
        .components()
        .map(|c| {
            c.as_os_str()
                .to_string_lossy()
                .trim_end_matches(".rs")
                .to_string()
        })
        .collect();
    if matches!(parts.last().map(String::as_str), Some("mod" | "lib")) {
        parts.pop();
    }
    parts
}

/// The paths a line names through `crate::`, `super::` or `self::` (braced groups of `use`
/// expanded), resolved against `module`, as segment lists.
fn named_paths(line: &str, module: &[String]) -> Vec<Vec<String>> {
    fn ident(s: &str) -> (&str, &str) {
        let end = s
            .find(|c: char| !(c.is_alphanumeric() || c == '_'))
            .unwrap_or(s.len());
        (&s[..end], &s[end..])
    }
    /// Reads a path (and its braced group) at the start of `s`, after `base`.
    fn path(s: &str, base: Vec<String>, out: &mut Vec<Vec<String>>) {
        let mut cur = base;
        let mut rest = s;
        loop {
            if let Some(group) = rest.strip_prefix('{') {
                let mut depth = 1;
                let mut start = 0;
                for (i, c) in group.char_indices() {
                    match c {
                        '{' => depth += 1,
                        '}' | ',' if depth == 1 => {
                            path(group[start..i].trim(), cur.clone(), out);
                            start = i + 1;
                            if c == '}' {
                                return;
                            }
                        }
                        '}' => depth -= 1,
                        _ => {}
                    }
                }
                return;
            }
            let (name, after) = ident(rest);
            if name.is_empty() || name == "self" {
                break;
            }
            if name == "super" {
                cur.pop();
            } else {
                cur.push(name.to_string());
            }
            match after.strip_prefix("::") {
                Some(r) => rest = r,
                None => break,
            }
        }
        out.push(cur);
    }
    let mut out = Vec::new();
    for (i, _) in line.match_indices("crate::") {
        if i > 0 && line[..i].ends_with(|c: char| c.is_alphanumeric() || c == '_' || c == '$') {
            continue;
        }
        path(&line[i + 7..], Vec::new(), &mut out);
    }
    for start in ["super::", "self::"] {
        for (i, _) in line.match_indices(start) {
            if i > 0 && line[..i].ends_with(|c: char| c.is_alphanumeric() || c == '_' || c == ':') {
                continue;
            }
            // `super` is the parent of a file's module; a `mod.rs` is its folder's module.
            let mut base = module.to_vec();
            let rest = if start == "super::" {
                base.pop();
                &line[i + 7..]
            } else {
                &line[i + 6..]
            };
            path(rest, base, &mut out);
        }
    }
    out
}

/// Import edges between sibling modules at every depth: `parent -> (a -> {b})` when something
/// in `parent::a` names something in `parent::b` (outside comments). Parent and child naming
/// each other (a `mod.rs` re-exporting its children) is not an edge.
fn imports() -> BTreeMap<Vec<String>, BTreeMap<String, BTreeSet<String>>> {
    let (src, files) = sources();
    let modules: BTreeSet<Vec<String>> = files
        .iter()
        .map(|f| module_of(f.strip_prefix(&src).unwrap()))
        .collect();
    let mut groups: BTreeMap<Vec<String>, BTreeMap<String, BTreeSet<String>>> = BTreeMap::new();
    for f in &files {
        let module = module_of(f.strip_prefix(&src).unwrap());
        if ["main", "cli", "commands"].contains(&module.first().map_or("", String::as_str)) {
            continue; // the binary
        }
        // The file as one line without its comments, so that a `use` group spread over lines
        // is read whole.
        let text: String = std::fs::read_to_string(f)
            .unwrap()
            .lines()
            .map(|l| l.split("//").next().unwrap_or(""))
            .collect::<Vec<_>>()
            .join(" ");
        {
            let line = text.as_str();
            for target in named_paths(line, &module) {
                // The longest prefix that is a module.
                let Some(target) = (0..=target.len())
                    .rev()
                    .map(|n| target[..n].to_vec())
                    .find(|p| modules.contains(p))
                else {
                    continue;
                };
                let common = module
                    .iter()
                    .zip(&target)
                    .take_while(|(a, b)| a == b)
                    .count();
                if common < module.len() && common < target.len() {
                    groups
                        .entry(module[..common].to_vec())
                        .or_default()
                        .entry(module[common].clone())
                        .or_default()
                        .insert(target[common].clone());
                }
            }
        }
    }
    groups
}

#[test]
fn modules_import_each_other_without_a_circle_at_any_depth() {
    // Depth-first search for a back edge among the siblings of each folder.
    fn visit(
        m: &str,
        deps: &BTreeMap<String, BTreeSet<String>>,
        state: &mut BTreeMap<String, u8>,
        path: &mut Vec<String>,
        parent: &str,
    ) {
        state.insert(m.into(), 1);
        path.push(m.into());
        for d in deps.get(m).into_iter().flatten() {
            match state.get(d) {
                Some(1) => panic!("import circle in {parent}: {} -> {d}", path.join(" -> ")),
                Some(_) => {}
                None => visit(d, deps, state, path, parent),
            }
        }
        path.pop();
        state.insert(m.into(), 2);
    }
    let groups = imports();
    for (parent, deps) in &groups {
        let name = if parent.is_empty() {
            "the crate".to_string()
        } else {
            parent.join("::")
        };
        let mut state = BTreeMap::new();
        for m in deps.keys() {
            if !state.contains_key(m) {
                visit(m, deps, &mut state, &mut Vec::new(), &name);
            }
        }
    }
    // The readers (KITTI's family among them, under `source/`) know nothing of the sensor
    // model, labelling, planning, projection or output.
    let top = &groups[&Vec::new()];
    assert!(
        !top.contains_key("kitti"),
        "KITTI's readers live in source/kitti"
    );
    for m in [
        "sensor", "label", "plan", "project", "params", "format", "report", "convert",
    ] {
        assert!(!top["source"].contains(m), "source imports {m}");
    }
    // Labelling reads no file: of the readers' module it names only the seam (the typed box,
    // the dataset kinds and their vocabularies), never a reader.
    let (src, files) = sources();
    for f in files.iter().filter(|f| f.starts_with(src.join("label"))) {
        for line in std::fs::read_to_string(f).unwrap().lines() {
            let code = line.trim_start();
            if code.starts_with("//") {
                continue;
            }
            for (at, _) in code.match_indices("crate::source::") {
                let rest = &code[at + "crate::source::".len()..];
                let name: String = rest
                    .chars()
                    .take_while(|c| c.is_alphanumeric() || *c == '_')
                    .collect();
                assert!(
                    ["boxes", "dataset", "DatasetKind"].contains(&name.as_str()),
                    "{}: label names the reader source::{name}",
                    f.display()
                );
            }
        }
    }
    // The scan is the readers' neutral type, named through no dataset family.
    for f in &files {
        let text = std::fs::read_to_string(f).unwrap();
        assert!(
            !text.contains("velodyne::Scan"),
            "{} names velodyne::Scan",
            f.display()
        );
    }
    // The analysis sees the edges inside the folders it guards (a `use super::{..}` group, a
    // `super::x::f` call).
    let edge = |folder: &str, from: &str, to: &str| {
        groups
            .get(&vec![folder.to_string()])
            .and_then(|g| g.get(from))
            .is_some_and(|d| d.contains(to))
    };
    assert!(edge("check", "inventory", "layouts"), "{groups:?}");
    assert!(edge("check", "scans", "calibration"), "{groups:?}");
    assert!(edge("report", "unproject", "truth"), "{groups:?}");
}

#[test]
fn no_source_file_over_500_lines() {
    let (_, files) = sources();
    for f in files {
        let n = std::fs::read_to_string(&f).unwrap().lines().count();
        assert!(n <= 500, "{}: {n} lines", f.display());
    }
}

/// Lines of each function (`fn` line to its closing brace, as rustfmt lays it out): (lines,
/// file, name). Braces inside string and char literals are skipped.
fn function_lengths() -> Vec<(usize, String, String)> {
    let (src, files) = sources();
    let mut out = Vec::new();
    for f in files {
        let text = std::fs::read_to_string(&f).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        for (i, line) in lines.iter().enumerate() {
            // Any visibility (`pub`, `pub(crate)`, `pub(super)`, `pub(in path)`) and qualifiers
            // (`const`, `async`, `unsafe`, `extern "C"`) before `fn`.
            let mut t = line.trim_start();
            if let Some(r) = t.strip_prefix("pub") {
                t = match r.strip_prefix('(') {
                    Some(inner) => inner.split_once(')').map_or(r, |(_, after)| after),
                    None => r,
                }
                .trim_start();
            }
            loop {
                let before = t;
                for q in ["const ", "async ", "unsafe ", "extern \"C\" ", "extern "] {
                    t = t.strip_prefix(q).unwrap_or(t);
                }
                if t == before {
                    break;
                }
            }
            let Some(rest) = t.strip_prefix("fn ") else {
                continue;
            };
            let name: String = rest
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect();
            let (mut depth, mut opened) = (0i64, false);
            for (j, l) in lines.iter().enumerate().skip(i) {
                let (mut in_str, mut prev) = (false, ' ');
                for c in l.split("//").next().unwrap_or("").chars() {
                    match c {
                        '"' if prev != '\\' => in_str = !in_str,
                        '{' if !in_str && prev != '\'' => {
                            depth += 1;
                            opened = true;
                        }
                        '}' if !in_str && prev != '\'' => depth -= 1,
                        _ => {}
                    }
                    prev = c;
                }
                if (opened && depth <= 0) || (!opened && l.trim_end().ends_with(';')) {
                    let file = f.strip_prefix(&src).unwrap().display().to_string();
                    out.push((j - i + 1, file, name.clone()));
                    break;
                }
            }
        }
    }
    out.sort_by(|a, b| b.cmp(a));
    out
}

/// Functions fit on a screen: none over 80 lines (the longest are flat: label sources, a shard
/// writer, a bird's-eye picture).
#[test]
fn no_function_over_80_lines() {
    let long: Vec<_> = function_lengths()
        .into_iter()
        .filter(|(n, _, _)| *n > 80)
        .collect();
    assert!(long.is_empty(), "functions over 80 lines: {long:?}");
}

/// Each crate's instances as one build resolves them (`cargo tree -e features` of `args`):
/// "name version" -> the feature sets of its instances (a crate can be built twice, for the
/// build's machine, as a macro's or build script's dependency, and for the target).
fn resolved_features(args: &[&str]) -> BTreeMap<String, BTreeSet<String>> {
    let out = std::process::Command::new(env!("CARGO"))
        .args([
            "tree",
            "--locked",
            "--offline",
            "--prefix",
            "none",
            "-f",
            "{p} {f}",
        ])
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("cargo tree runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut found: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for line in String::from_utf8_lossy(&out.stdout).lines() {
        let words: Vec<&str> = line.split_whitespace().collect();
        let [name, version, rest @ ..] = words.as_slice() else {
            continue;
        };
        // A path package shows its path, a proc macro "(proc-macro)", a repeat "(*)".
        let mut features: Vec<&str> = (rest.iter())
            .filter(|w| !w.starts_with('('))
            .flat_map(|f| f.split(','))
            .collect();
        features.sort_unstable();
        features.dedup();
        found
            .entry(format!("{name} {version}"))
            .or_default()
            .insert(features.join(","));
    }
    found
}

/// One feature set for the whole build (issue 48): every crate the CLI's install compiles is
/// resolved with the same features by the Python module's build and by the tests, so that they
/// reuse it instead of compiling it again (Cargo.toml's unification list; `either` without
/// `use_std` recompiled rayon and parry3d for the tests). A crate the CLI builds with features
/// the other build does not ask for fails here, naming the crate and its feature sets. And each
/// of them finds its crates in tools/run-tests.sh's one build of all the workspace's packages
/// together (features resolved over them all: the benchmarks' criterion asking a shared crate for
/// more would make the install, maturin and `cargo test` compile it again).
#[test]
fn the_cli_the_module_and_the_tests_share_one_feature_set() {
    let install = resolved_features(&["-p", "kitti2pgm", "-e", "normal,build"]);
    let module = resolved_features(&["-p", "kitti2pgm-py", "-e", "normal,build"]);
    let tests = resolved_features(&["-p", "kitti2pgm", "-e", "normal,build,dev"]);
    let all = [
        "-p",
        "kitti2pgm",
        "-p",
        "kitti2pgm-py",
        "-p",
        "kitti2pgm-bench",
        "-e",
        "normal,build,dev",
    ];
    let one_build = resolved_features(&all);
    assert!(install.len() > 100, "{install:?}");
    for ((name, build), (what, other)) in [
        (("CLI", &install), ("the Python module", &module)),
        (("CLI", &install), ("the tests", &tests)),
        (("CLI", &install), ("the one build", &one_build)),
        (("module", &module), ("the one build", &one_build)),
        (("tests", &tests), ("the one build", &one_build)),
    ] {
        let differ: Vec<String> = (build.iter())
            .filter_map(|(k, f)| {
                let o = other.get(k)?;
                (!f.is_subset(o)).then(|| format!("{k}: {name} {f:?}, {what} {o:?}"))
            })
            .collect();
        assert!(differ.is_empty(), "features differ: {differ:#?}");
    }
}
