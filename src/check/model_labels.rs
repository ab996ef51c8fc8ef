//! Label files that are a model's output (`kitti2pgm infer --as-labels`), compared with what
//! the model wrote (`model_labels.json`): unedited ones are pre-labels nobody has corrected yet.

use super::read::DriveRead;
use super::{CheckName as C, Collector, Severity as S};
use crate::format::model_labels;
use crate::source::kitti::sequence;

/// The model labels of a sequence: a warning for the files still as the model wrote them, a
/// note for the edited and the missing ones. (An unfinished run's sequence is refused before,
/// as every reader refuses it.)
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
                model_labels::frame_list(names, 8)
            ),
        );
    }
}
