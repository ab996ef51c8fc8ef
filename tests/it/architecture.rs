//! The shape of the code, kept: the library's top-level modules import each other without a
//! circle (data flows one way), and no source file grows past 500 lines.

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

/// Top-level module -> the top-level modules it names as `crate::x` (outside comments).
fn imports() -> BTreeMap<String, BTreeSet<String>> {
    let (src, files) = sources();
    let mut deps: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for f in files {
        let rel = f.strip_prefix(&src).unwrap();
        let top = rel
            .components()
            .next()
            .unwrap()
            .as_os_str()
            .to_string_lossy()
            .trim_end_matches(".rs")
            .to_string();
        if ["main", "cli", "commands", "lib"].contains(&top.as_str()) {
            continue; // the binary and the crate root
        }
        let entry = deps.entry(top.clone()).or_default();
        for line in std::fs::read_to_string(&f).unwrap().lines() {
            if line.trim_start().starts_with("//") {
                continue;
            }
            for (i, _) in line.match_indices("crate::") {
                let name: String = line[i + 7..]
                    .chars()
                    .take_while(|c| c.is_alphanumeric() || *c == '_')
                    .collect();
                if name != top && !name.is_empty() {
                    entry.insert(name);
                }
            }
        }
    }
    deps
}

#[test]
fn modules_import_each_other_without_a_circle() {
    let deps = imports();
    // Depth-first search for a back edge.
    fn visit(
        m: &str,
        deps: &BTreeMap<String, BTreeSet<String>>,
        state: &mut BTreeMap<String, u8>,
        path: &mut Vec<String>,
    ) {
        state.insert(m.into(), 1);
        path.push(m.into());
        for d in deps.get(m).into_iter().flatten() {
            match state.get(d) {
                Some(1) => panic!("import circle: {} -> {d}", path.join(" -> ")),
                Some(_) => {}
                None => visit(d, deps, state, path),
            }
        }
        path.pop();
        state.insert(m.into(), 2);
    }
    let mut state = BTreeMap::new();
    for m in deps.keys() {
        if !state.contains_key(m) {
            visit(m, &deps, &mut state, &mut Vec::new());
        }
    }
    // The reader knows nothing of labelling, projection or output.
    for m in ["label", "project", "format", "report", "convert"] {
        assert!(!deps["kitti"].contains(m), "kitti imports {m}");
    }
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
            let t = line.trim_start();
            let t = t
                .strip_prefix("pub(crate) ")
                .or(t.strip_prefix("pub "))
                .unwrap_or(t);
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
