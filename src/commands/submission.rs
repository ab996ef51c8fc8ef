//! `kitti2pgm submission`: the CLI over [`kitti2pgm::report::submission`].

use kitti2pgm::label::ClassMap;
use kitti2pgm::report::submission::{check_submission, write_zip};

use crate::cli::SubmissionArgs;
use crate::Outcome;

pub fn run(a: SubmissionArgs) -> anyhow::Result<Outcome> {
    if let Some(zip) = &a.zip {
        use kitti2pgm::fs::Role;
        let inputs = [
            (Role::Predictions, a.pred.as_path()),
            (Role::Dataset, a.gt.as_path()),
        ];
        kitti2pgm::fs::refuse_overlap(zip, &inputs)?;
    }
    let map = ClassMap::named_or_file(&a.class_map)?;
    let seqs = (!a.sequences.is_empty()).then_some(&a.sequences[..]);
    let c = check_submission(&a.pred, &a.gt, seqs, &map)?;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&c)?);
    } else {
        println!(
            "sequences {}: {} of {} predictions valid, {} problems",
            c.sequences.join(" "),
            c.valid,
            c.expected,
            c.problems.len()
        );
        for p in &c.problems {
            println!("  {}: {}", p.path.display(), p.problem);
        }
    }
    if !c.is_valid() {
        return Ok(Outcome::Failed(format!(
            "{}: not a valid submission ({} problems)",
            a.pred.display(),
            c.problems.len()
        )));
    }
    if let Some(zip) = &a.zip {
        let description = match &a.description {
            Some(d) if std::path::Path::new(d).is_file() => {
                kitti2pgm::fs::read_text(d.as_ref(), kitti2pgm::fs::Limit::Text)?
            }
            Some(d) => d.clone(),
            None => format!(
                "Predictions of sequences {} written by kitti2pgm {}.\n",
                c.sequences.join(", "),
                env!("CARGO_PKG_VERSION")
            ),
        };
        write_zip(&a.pred, &c, zip, &description)?;
        if !a.json {
            println!("packed into {}", zip.display());
        }
    }
    Ok(Outcome::Ok)
}
