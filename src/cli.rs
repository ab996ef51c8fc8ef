//! Command-line arguments (clap derive): raw input, validated into library types by
//! `commands::*`.

use std::path::PathBuf;

use clap::{Args as ClapArgs, Parser, Subcommand, ValueEnum};

/// KITTI raw -> labelled Polar Grid Maps for LiDAR(+camera) semantic segmentation
/// (SqueezeSeg / PointSeg training data).
#[derive(Debug, Parser)]
#[command(name = "kitti2pgm", version, about, long_about = None, propagate_version = true)]
pub struct Args {
    /// Worker threads (0 = one per core; 1 = sequential, for debugging).
    #[arg(long, global = true, default_value_t = 0)]
    pub threads: usize,
    /// Never draw a progress bar (it is only drawn on a terminal anyway).
    #[arg(long, global = true)]
    pub no_progress: bool,
    /// The task.
    #[command(subcommand)]
    pub command: Command,
}

/// Subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Convert KITTI raw drives to 64x512 Polar Grid Maps (.npy) and per-point .label files.
    ///
    /// RAW_ROOT is a KITTI raw root (<date>/calib_*.txt and <date>/<date>_drive_NNNN_sync/),
    /// one date folder, or one drive folder. Writes DIR/lidar_2d/<date>_<drive4>_<frame10>.npy
    /// (float32 64x512x6: x, y, z, intensity, range, label; with --rgb 64x512x9 adding r, g, b)
    /// and DIR/labels/<drive>/<frame10>.label (u32 per point: class | instance << 16).
    /// Exit status: 0 all converted, 1 fatal error, 3 some frames failed (reported, others written).
    Convert(ConvertArgs),
    /// Draw converted frames (.npy) as PNG: range, intensity, colour and labels stacked.
    Preview(PreviewArgs),
}

/// Row assignment.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum RowModeArg {
    /// Rings recovered from the scan order; elevation binning only where a scan breaks it.
    Rings,
    /// Elevation binning between --fov-up-deg and --fov-down-deg for every scan.
    Elevation,
}

/// Colour sampling.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum SamplingArg {
    /// The pixel whose centre is nearest.
    Nearest,
    /// Bilinear blend of the four neighbouring pixels.
    Bilinear,
}

/// `kitti2pgm convert`.
#[derive(Debug, ClapArgs)]
pub struct ConvertArgs {
    /// KITTI raw root, date folder or drive folder.
    #[arg(value_name = "RAW_ROOT")]
    pub raw_root: PathBuf,
    /// Output folder (created if needed).
    #[arg(long, short, value_name = "DIR")]
    pub out: PathBuf,
    /// Add r, g, b channels sampled from the camera image (64x512x9 output).
    #[arg(long)]
    pub rgb: bool,
    /// Colour camera for --rgb: 2 (left) or 3 (right).
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u8).range(2..=3))]
    pub camera: u8,
    /// Colour sampling for --rgb.
    #[arg(long, value_enum, default_value_t = SamplingArg::Nearest)]
    pub rgb_sampling: SamplingArg,
    /// Convert every scan, not only SqueezeSeg's (scans with at least one tracklet pose).
    #[arg(long)]
    pub all_frames: bool,
    /// Rows of the map.
    #[arg(long, default_value_t = 64)]
    pub rows: usize,
    /// Columns of the map.
    #[arg(long, default_value_t = 512)]
    pub cols: usize,
    /// Horizontal field of view in degrees, centred on the x axis (360 for a full map).
    #[arg(long, default_value_t = 90.0)]
    pub fov_deg: f64,
    /// Top of the elevation range for elevation binning, degrees.
    #[arg(long, default_value_t = 2.0, allow_negative_numbers = true)]
    pub fov_up_deg: f64,
    /// Bottom of the elevation range for elevation binning, degrees.
    #[arg(long, default_value_t = -24.9, allow_negative_numbers = true)]
    pub fov_down_deg: f64,
    /// How rows are assigned.
    #[arg(long, value_enum, default_value_t = RowModeArg::Rings)]
    pub row_mode: RowModeArg,
    /// Do not write the per-point .label files.
    #[arg(long)]
    pub no_point_labels: bool,
    /// Flush each output file to the device before renaming it into place. Files are always
    /// written atomically (never half-written); this also makes them survive a power cut.
    #[arg(long)]
    pub sync: bool,
    /// Print the summary as JSON on stdout instead of a table.
    #[arg(long)]
    pub json: bool,
}

/// `kitti2pgm preview`.
#[derive(Debug, ClapArgs)]
pub struct PreviewArgs {
    /// Converted frames (.npy, 64x512x6 or x9).
    #[arg(required = true, value_name = "NPY")]
    pub inputs: Vec<PathBuf>,
    /// Output: a .png file for one input, else a folder (one <stem>.png per input).
    #[arg(long, short, value_name = "PATH")]
    pub out: PathBuf,
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    #[test]
    fn cli_is_consistent() {
        Args::command().debug_assert();
    }

    #[test]
    fn parses_convert() {
        let a = Args::try_parse_from([
            "kitti2pgm",
            "convert",
            "raw",
            "--out",
            "o",
            "--rgb",
            "--camera",
            "3",
            "--fov-down-deg",
            "-20",
        ])
        .unwrap();
        let Command::Convert(c) = a.command else {
            panic!()
        };
        assert!(c.rgb);
        assert_eq!(c.camera, 3);
        assert_eq!(c.fov_down_deg, -20.0);
        assert!(Args::try_parse_from([
            "kitti2pgm",
            "convert",
            "raw",
            "--out",
            "o",
            "--camera",
            "1"
        ])
        .is_err());
    }
}
