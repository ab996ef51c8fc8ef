//! Label files that are a model's output (`kitti2pgm infer --as-labels`), compared with what
//! the model wrote (`model_labels.json`): unedited ones are pre-labels nobody has corrected yet.

use super::read::DriveRead;
use super::{CheckName as C, Collector, Severity as S};
use crate::format::model_labels;
use crate::source::kitti::sequence;

/// The model labels of a sequence: a warning for the files still as the model wrote them, a
/// note for the edited and the missing ones.
pub(crate) fn check(r: &DriveRead, c: &mut Collector) {
    let seq = &r.drive.dir;
    let labels = seq.join(sequence::LABELS);
    let marker = model_labels::path(seq);
    let record = match model_labels::read(seq) {
        Ok(Some(rec)) => rec,
        Ok(None) => return,
        Err(e) => return c.add(C::Read, S::Error, &marker, None, None, e.to_string()),
    };
    let state = match record.state(seq) {
        Ok(s) => s,
        Err(e) => return c.add(C::Read, S::Error, &labels, None, None, e.to_string()),
    };
    let of = record.frames.len();
    let model = format!("the model {} ({})", record.model.display(), record.digest);
    if !record.complete {
        c.add(
            C::ModelLabels,
            S::Error,
            &marker,
            None,
            None,
            format!("the infer --as-labels run of {model} did not finish: run it again with --overwrite"),
        );
    }
    for (names, severity, what) in [
        (
            &state.unedited,
            S::Warning,
            "are as the model wrote them, not yet corrected",
        ),
        (
            &state.edited,
            S::Note,
            "were edited since the model wrote them",
        ),
        (&state.missing, S::Note, "the model wrote are gone"),
    ] {
        if names.is_empty() {
            continue;
        }
        c.add(
            C::ModelLabels,
            severity,
            &labels,
            None,
            None,
            format!(
                "{} of {of} label files {what} ({model}, infer --as-labels): frames {}",
                names.len(),
                list(names)
            ),
        );
    }
}

/// The first few frame names.
fn list(names: &[String]) -> String {
    let mut s = names.iter().take(8).cloned().collect::<Vec<_>>().join(", ");
    if names.len() > 8 {
        s.push_str(&format!(" and {} more", names.len() - 8));
    }
    s
}
