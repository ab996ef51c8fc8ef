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

/// How `output` meets `input`, if it does.
pub fn overlap(output: &Path, input: &Path) -> Option<Overlap> {
    let (o, i) = (resolved(output), resolved(input));
    if o == i {
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
