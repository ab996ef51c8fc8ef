//! No output over an input: a command refuses an output path that is one of its inputs, lies
//! inside one, or holds one, before it writes anything (`unproject --out` equal to `--gt`
//! would replace the ground truth's labels; `submission --zip` inside the prediction folder
//! would pack its own half-written archive).

use std::path::{Component, Path, PathBuf};

use crate::error::{Error, Result};
pub use crate::error::{Overlap, Role};

/// `path` made absolute, links resolved as far as it exists, `.` and `..` folded.
pub fn resolved(path: &Path) -> PathBuf {
    let abs = if path.is_absolute() {
        path.to_path_buf()
    } else {
        std::env::current_dir().unwrap_or_default().join(path)
    };
    // The longest existing prefix, canonicalised; the rest appended as written.
    let mut existing = abs.as_path();
    let mut rest = Vec::new();
    loop {
        if let Ok(c) = existing.canonicalize() {
            let mut out = c;
            for part in rest.iter().rev() {
                out.push(part);
            }
            return fold(&out);
        }
        match (existing.parent(), existing.file_name()) {
            (Some(parent), Some(name)) => {
                rest.push(name.to_os_string());
                existing = parent;
            }
            _ => return fold(&abs),
        }
    }
}

fn fold(p: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for c in p.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                out.pop();
            }
            c => out.push(c),
        }
    }
    out
}

/// How `output` meets `input`, if it does: by their resolved paths, or as one file reached by
/// two paths (a hard link).
pub fn overlap(output: &Path, input: &Path) -> Option<Overlap> {
    let (o, i) = (resolved(output), resolved(input));
    if o == i || same_file(&o, &i) {
        Some(Overlap::Is)
    } else if o.starts_with(&i) {
        Some(Overlap::Inside)
    } else if i.starts_with(&o) {
        Some(Overlap::Holds)
    } else {
        None
    }
}

/// Refuses `output` when it is, lies inside or holds one of `inputs` ([`Error::OutputOverInput`],
/// a usage error).
pub fn refuse_overlap(output: &Path, inputs: &[(Role, &Path)]) -> Result<()> {
    for &(role, input) in inputs {
        if let Some(how) = overlap(output, input) {
            return Err(Error::OutputOverInput {
                output: output.into(),
                how,
                role,
                input: input.into(),
            });
        }
    }
    Ok(())
}

/// Whether two existing paths are one file (the same device and inode; never elsewhere).
fn same_file(a: &Path, b: &Path) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        if let (Ok(a), Ok(b)) = (std::fs::metadata(a), std::fs::metadata(b)) {
            return a.dev() == b.dev() && a.ino() == b.ino();
        }
    }
    let _ = (a, b);
    false
}

/// Refuses `output` when a folder it would lie in holds another link of one of `files` (inputs
/// of `role`): an unpacked nuScenes root's scans are hard links of the dataset's own
/// `samples/LIDAR_TOP` files, so an output inside that folder writes into the dataset though no
/// path says so. Only files with several links are looked for; the output's existing folders
/// are listed (their entries' inodes, without a `stat` each).
pub fn refuse_linked<'a>(
    output: &Path,
    role: Role,
    files: impl IntoIterator<Item = &'a Path>,
) -> Result<()> {
    #[cfg(unix)]
    {
        use std::collections::HashSet;
        use std::os::unix::fs::{DirEntryExt, MetadataExt};
        let linked: HashSet<(u64, u64)> = (files.into_iter())
            .filter_map(|f| std::fs::metadata(f).ok())
            .filter(|m| m.is_file() && m.nlink() > 1)
            .map(|m| (m.dev(), m.ino()))
            .collect();
        if linked.is_empty() {
            return Ok(());
        }
        let out = resolved(output);
        for dir in out.ancestors().filter(|d| d.is_dir()) {
            let Ok(dev) = std::fs::metadata(dir).map(|m| m.dev()) else {
                continue;
            };
            let Ok(entries) = std::fs::read_dir(dir) else {
                continue;
            };
            for e in entries.flatten() {
                if linked.contains(&(dev, e.ino())) {
                    return Err(Error::OutputOverInput {
                        output: output.into(),
                        how: Overlap::BesideLink,
                        role,
                        input: e.path(),
                    });
                }
            }
        }
    }
    #[cfg(not(unix))]
    let _ = (output, role, files.into_iter().count());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn outputs_meet_inputs_by_resolved_path() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::create_dir_all(d.join("gt/labels")).unwrap();
        assert_eq!(overlap(&d.join("gt"), &d.join("gt/./")), Some(Overlap::Is));
        assert_eq!(
            overlap(&d.join("gt/labels/new"), &d.join("gt")),
            Some(Overlap::Inside)
        );
        assert_eq!(overlap(d, &d.join("gt")), Some(Overlap::Holds));
        assert_eq!(
            overlap(&d.join("x/../gt"), &d.join("gt")),
            Some(Overlap::Is)
        );
        assert_eq!(overlap(&d.join("gt2"), &d.join("gt")), None);
        // One file by two paths, and a folder that holds a hard link of an input file.
        std::fs::create_dir_all(d.join("samples")).unwrap();
        std::fs::write(d.join("samples/a.bin"), b"x").unwrap();
        std::fs::hard_link(d.join("samples/a.bin"), d.join("gt/a.bin")).unwrap();
        assert_eq!(
            overlap(&d.join("samples/a.bin"), &d.join("gt/a.bin")),
            Some(Overlap::Is)
        );
        let linked = [d.join("gt/a.bin")];
        let e = refuse_linked(
            &d.join("samples/out"),
            Role::Dataset,
            linked.iter().map(|p| p.as_path()),
        );
        assert!(
            matches!(&e, Err(Error::OutputOverInput { how: Overlap::BesideLink, input, .. })
                if input.ends_with("samples/a.bin")),
            "{e:?}"
        );
        assert!(refuse_linked(
            &d.join("x/out"),
            Role::Dataset,
            linked.iter().map(|p| p.as_path())
        )
        .is_ok());
        #[cfg(unix)]
        {
            std::os::unix::fs::symlink(d.join("gt"), d.join("link")).unwrap();
            assert_eq!(overlap(&d.join("link"), &d.join("gt")), Some(Overlap::Is));
        }
        let e = refuse_overlap(&d.join("gt"), &[(Role::GroundTruth, &d.join("gt"))]);
        assert!(matches!(
            e,
            Err(Error::OutputOverInput {
                how: Overlap::Is,
                role: Role::GroundTruth,
                ..
            })
        ));
    }
}
