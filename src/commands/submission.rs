//! `kitti2pgm submission`: the CLI over [`kitti2pgm::report::submission`].

use std::path::PathBuf;

use clap::Args as ClapArgs;
use kitti2pgm::label::ClassMap;
use kitti2pgm::report::submission::{check_submission, write_zip};

use crate::Outcome;

/// `kitti2pgm submission`.
#[derive(Debug, ClapArgs)]
pub struct SubmissionArgs {
    /// The prediction folder: PRED/sequences/<NN>/predictions/<frame6>.label.
    #[arg(value_name = "PRED")]
    pub pred: PathBuf,
    /// The SemanticKITTI root whose scans the predictions are of (sequences/<NN>/velodyne/).
    #[arg(long, value_name = "ROOT")]
    pub gt: PathBuf,
    /// The sequences to check (comma separated; the benchmark's test set is 11-21). Default:
    /// every sequence of ROOT.
    #[arg(long, value_name = "NN", value_delimiter = ',')]
    pub sequences: Vec<u32>,
    /// The class map whose learning_map lists the valid raw ids (a name or a
    /// semantic-kitti.yaml-style file).
    #[arg(long, value_name = "NAME|FILE", default_value = "semantic-kitti")]
    pub class_map: PathBuf,
    /// Pack a valid folder into this zip archive, in the benchmark's layout.
    #[arg(long, value_name = "ZIP")]
    pub zip: Option<PathBuf>,
    /// The archive's description.txt: this text, or the contents of this file.
    #[arg(long, value_name = "TEXT|FILE", requires = "zip")]
    pub description: Option<String>,
    /// Print the check as JSON.
    #[arg(long)]
    pub json: bool,
}

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
        anyhow::bail!(
            "{}: not a valid submission ({} problems)",
            a.pred.display(),
            c.problems.len()
        );
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
