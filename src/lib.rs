//! kitti2pgm: LiDAR scans (the KITTI family's, and any spinning LiDAR's) -> labelled Polar Grid
//! Maps for LiDAR(+camera) 3D semantic segmentation, and back to every point.
//!
//! Data flows one way, one module per stage (`docs/architecture.md` draws it):
//!
//! - [`source`] READ: every input, each format one reader giving the neutral
//!   [`Scan`](source::Scan): the KITTI family ([`source::kitti`]: drives, scans, calibration,
//!   tracklets, object labels, timestamps, OXTS, images), PCD, flat `.bin`, ROS 2 bags,
//!   nuScenes;
//! - [`sensor`] the sensor model: beam tables (Velodyne, Hesai, Ouster) that make rows beams,
//!   the mounting pose, and [`sensor::read_scan`]: a scan read as its conversion reads it;
//! - [`plan`] which frames, which split: the selection and split rules, on the input side;
//! - [`label`] LABEL: the [`ClassMap`](label::ClassMap) and points in boxes (parry containment);
//! - [`project`] PROJECT: points -> Polar Grid Map (rows: rings from the scan order, or beams),
//!   named channels, RGB; and map predictions back to points (`unproject`);
//! - [`format`] WRITE: the one owner of every file kind (`.npy`, `.label`, layout, summary,
//!   ImageSet, shards, PNG), written atomically and read back;
//! - [`convert`] runs them over frames in parallel, with the typed [`provenance`] recorded;
//!   `unpack` makes sequence folders of bags and nuScenes roots;
//! - [`report`] reads what was written: ground truth, statistics, scores, shard inspection;
//! - [`infer`] runs a trained model (ONNX) on scans projected as its training data was, and
//!   carries its classes back to every point;
//! - [`check`] lints the inputs; [`draw`] pictures: previews and charts.
//!
//! ```no_run
//! use kitti2pgm::convert::{convert, ConvertOptions};
//! use kitti2pgm::plan::{FrameSelection, Plan};
//! let plan = Plan::build("fixtures/raw".as_ref(), FrameSelection::Annotated)?;
//! let summary = convert(&plan, &ConvertOptions::new("out"), &|_| {})?;
//! println!("{} frames, fill {:.3}", summary.frames_converted, summary.fill_ratio());
//! # Ok::<(), kitti2pgm::Error>(())
//! ```
#![warn(missing_docs)]

pub mod alloc;
pub mod check;
pub mod convert;
pub mod draw;
pub mod error;
pub mod format;
pub mod fs;
pub mod geom;
pub mod infer;

#[macro_use]
mod names;
pub mod label;
pub mod plan;
pub mod project;
pub mod provenance;
pub mod raster;
pub mod report;
pub mod rng;
pub mod sensor;
pub mod simd;
pub mod source;

pub use error::{Error, Result};
