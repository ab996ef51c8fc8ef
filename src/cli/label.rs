//! `kitti2pgm label`'s arguments.

use std::path::PathBuf;

use clap::Args as ClapArgs;
use kitti2pgm::source::annotations::{AngleUnit, BoxFormat, CvatSizes};
use kitti2pgm::source::boxes::BoxOrigin;

/// `kitti2pgm label`.
#[derive(Debug, ClapArgs)]
pub struct LabelArgs {
    /// The scans: a root in the sequence layout (ROOT/sequences/<NN>/velodyne/) or one
    /// sequence folder. The labels are written into it (sequences/<NN>/labels/).
    #[arg(value_name = "ROOT")]
    pub root: PathBuf,
    /// The box annotations: the export's folder (or, for a one-file format, the file).
    #[arg(long, value_name = "PATH")]
    pub boxes: PathBuf,
    /// The format of the export (default: recognised from its files, and said).
    #[arg(long, value_name = "NAME")]
    pub box_format: Option<BoxFormat>,
    /// The sequence the boxes annotate (default: the only one under ROOT).
    #[arg(long, value_name = "NN")]
    pub sequence: Option<u32>,
    /// Which object type is which class: a built-in map (kitti-boxes for KITTI's types,
    /// sustechpoints, nuscenes-detection) or a YAML file (classes with their types). Default:
    /// the format's own set (sustechpoints for SUSTechPOINTS, kitti-boxes for CVAT's KITTI
    /// export); other formats name one.
    #[arg(long, value_name = "NAME|YAML")]
    pub class_map: Option<PathBuf>,
    /// One more object type for a class of the map, TYPE=CLASS (repeatable): --alias
    /// Rider=cyclist.
    #[arg(long = "alias", value_name = "TYPE=CLASS")]
    pub aliases: Vec<String>,
    /// The class that boxes of object types the map does not know become (e.g. background).
    /// Without it such boxes are an error that lists them.
    #[arg(long, value_name = "CLASS")]
    pub unknown_class: Option<String>,
    /// Metres added to every side of every box (tight boxes miss points on the object's
    /// surface); 0 to 1.
    #[arg(
        long,
        value_name = "M",
        default_value_t = 0.0,
        allow_hyphen_values = true
    )]
    pub margin: f64,
    /// Where a box's position sits, for CVAT's tracklets (CVAT writes the centre, KITTI the
    /// bottom face's centre). Default: centre.
    #[arg(long, value_name = "WHERE")]
    pub origin: Option<BoxOrigin>,
    /// The order of CVAT's h, w, l: datumaro (CVAT's exports: the x, y, z extents are w, h, l)
    /// or kitti (l, w, h). Default: datumaro.
    #[arg(long, value_name = "ORDER")]
    pub sizes: Option<CvatSizes>,
    /// The unit of labelCloud's angles. Default: degrees.
    #[arg(long, value_name = "UNIT")]
    pub angles: Option<AngleUnit>,
    /// The sensor's pose in the frame the boxes are drawn in, X,Y,Z[,ROLL,PITCH,YAW] (metres,
    /// degrees), for boxes drawn in a vehicle frame around scans in the sensor's: the boxes
    /// are moved into the scan's frame. Default: the boxes are in the scan's frame.
    #[arg(long, value_name = "X,Y,Z[,R,P,Y]", allow_hyphen_values = true)]
    pub sensor_pose: Option<String>,
    /// Write over label files that `label` did not write or that were edited since (never over
    /// the labels a dataset ships).
    #[arg(long)]
    pub overwrite: bool,
    /// Flush every file to the device before it counts as written.
    #[arg(long)]
    pub sync: bool,
    /// Print the report as JSON.
    #[arg(long)]
    pub json: bool,
}
