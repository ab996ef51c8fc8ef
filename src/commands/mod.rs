//! One module per subcommand; each turns its clap struct into library options and runs it.

pub mod check;
mod convert;
mod infer;
mod inspect;
mod label;
mod preview;
pub mod progress;
mod score;
mod split;
mod stats;
pub mod submission;
mod unpack;
mod unpack_nuscenes;
pub mod unproject;

use crate::cli::{Args, Command};
use crate::Outcome;

/// Runs the parsed command.
pub fn run(args: Args) -> anyhow::Result<Outcome> {
    let global = Global {
        threads: args.threads,
        progress: !args.no_progress,
    };
    match args.command {
        Command::Check(a) => check::run(a, &global),
        Command::Convert(a) => convert::run(a, &global),
        Command::Preview(a) => preview::run(a, &global),
        Command::Split(a) => split::run(a),
        Command::Stats(a) => stats::run(a, &global),
        Command::Score(a) => score::run(a, &global),
        Command::Inspect(a) => inspect::run(a),
        Command::Label(a) => label::run(a, &global),
        Command::Unproject(a) => unproject::run(a, &global),
        Command::Infer(a) => infer::run(a, &global),
        Command::Submission(a) => submission::run(a),
        Command::Unpack(a) => unpack::run(a, &global),
    }
}

/// The option that answers a library error, for the line after it: the library names no flag.
pub fn hint(e: &anyhow::Error) -> Option<String> {
    use kitti2pgm::Error;
    e.chain().find_map(|c| match c.downcast_ref::<Error>()? {
        Error::MissingPrediction { .. } => Some(
            "--missing-as-background scores frames without a prediction as all background".into(),
        ),
        Error::NeedsScans { .. } => Some("pass the dataset root with --raw ROOT".into()),
        Error::Unfinished { .. } => {
            Some("--partial reads it anyway (and the report says PARTIAL)".into())
        }
        Error::Input { path, .. } => {
            kitti2pgm::source::Recording::of(path).map(|r| unpack_hint(path, &r))
        }
        _ => None,
    })
}

/// The commands that make a sequence folder of the recording `r` at `path`.
fn unpack_hint(path: &std::path::Path, r: &kitti2pgm::source::Recording) -> String {
    use kitti2pgm::source::Recording;
    let shown = path.display();
    match r {
        Recording::Ros2Bag { clouds } => {
            let (topic, listed) = match clouds.as_slice() {
                [one] => (one.clone(), String::new()),
                [] => (
                    "TOPIC".into(),
                    format!("; `kitti2pgm unpack {shown} --list` lists its topics"),
                ),
                many => (
                    "TOPIC".into(),
                    format!("; its point cloud topics: {}", many.join(", ")),
                ),
            };
            format!(
                "make it a sequence folder first, `kitti2pgm unpack {shown} --topic {topic} --out \
                 ROOT`, then convert ROOT{listed}"
            )
        }
        Recording::Ros1Bag | Recording::Sqlite3Bag => format!(
            "convert it to an MCAP bag first (`rosbags-convert --src {shown} --dst BAG \
             --dst-storage mcap`, docs/sources.md), then `kitti2pgm unpack BAG --topic TOPIC --out \
             ROOT`"
        ),
        Recording::NuScenes => format!(
            "make its scenes sequence folders first, `kitti2pgm unpack {shown} --out ROOT`, then \
             convert ROOT with --sensor hdl32e --class-map nuscenes"
        ),
    }
}

impl Global {
    /// The worker pool of `--threads`: every command's parallel work runs in it (`convert`
    /// hands the count to the library, which builds the same pool).
    pub fn pool(&self) -> anyhow::Result<rayon::ThreadPool> {
        Ok(rayon::ThreadPoolBuilder::new()
            .num_threads(self.threads)
            .build()?)
    }
}

/// Options shared by every subcommand.
pub struct Global {
    /// Worker threads (0 = all cores).
    pub threads: usize,
    /// Whether a progress bar may be drawn.
    pub progress: bool,
}

/// The durability `--sync` asks for.
pub fn durability(sync: bool) -> kitti2pgm::format::Durability {
    if sync {
        kitti2pgm::format::Durability::Synced
    } else {
        kitti2pgm::format::Durability::Renamed
    }
}

/// The readers' rule for an unfinished conversion, from `--partial`.
pub fn completeness(partial: bool) -> kitti2pgm::report::truth::Completeness {
    use kitti2pgm::report::truth::Completeness;
    if partial {
        Completeness::AllowPartial
    } else {
        Completeness::Require
    }
}
