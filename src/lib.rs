//! kitti2pgm: KITTI raw -> labelled Polar Grid Maps for LiDAR(+camera) semantic segmentation.
//!
//! Data flows one way, one module per stage (`docs/architecture.md` draws it):
//!
//! - [`kitti`] READ: drives, velodyne scans, calibration, tracklets, timestamps, OXTS, images;
//! - [`source`] READ: point clouds of any spinning LiDAR (PCD, flat `.bin`, nuScenes);
//! - [`sensor`] the sensor model: beam tables (Velodyne, Hesai, Ouster) that make rows beams;
//! - [`plan`] which frames, which split: the selection and split rules, on the input side;
//! - [`label`] LABEL: the [`ClassMap`](label::ClassMap) and points in boxes (parry containment);
//! - [`project`] PROJECT: points -> Polar Grid Map (rings from the scan order), named channels, RGB;
//! - [`format`] WRITE: the one owner of every file kind (`.npy`, `.label`, layout, summary,
//!   ImageSet, shards, PNG), written atomically and read back;
//! - [`convert`] runs them over frames in parallel, with the typed [`params`] as provenance;
//! - [`report`] reads what was written: ground truth, statistics, scores, shard inspection;
//! - [`draw`] pictures: previews and charts.
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

#[macro_use]
mod names;
pub mod label;
pub mod params;
pub mod plan;
pub mod project;
pub mod report;
pub mod rng;
pub mod sensor;
pub mod simd;
pub mod source;

pub use error::{Error, Result};
