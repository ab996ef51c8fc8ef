//! kitti2pgm: KITTI raw -> labelled Polar Grid Maps for LiDAR(+camera) semantic segmentation.
//!
//! Data flows one way, one module per stage:
//!
//! - [`kitti`] READ: drives, velodyne scans, calibration, tracklets, timestamps, OXTS, images;
//! - [`label`] LABEL: points in tracklet boxes (parry containment tests) -> class and instance;
//! - [`project`] PROJECT: points -> 64 x 512 Polar Grid Map (rings from the scan order), RGB;
//! - [`write`](mod@write) WRITE: `.npy` tensors and `.label` files, atomically;
//! - [`pipeline`] runs them over frames in parallel; [`preview`] draws a converted frame.
//!
//! ```no_run
//! use kitti2pgm::pipeline::{convert, ConvertOptions, FrameSelection, Plan};
//! let plan = Plan::build("fixtures/raw".as_ref(), FrameSelection::Annotated)?;
//! let summary = convert(&plan, &ConvertOptions::new("out"), &|_| {})?;
//! println!("{} frames, fill {:.3}", summary.frames_converted, summary.fill_ratio());
//! # Ok::<(), kitti2pgm::Error>(())
//! ```
#![warn(missing_docs)]

pub mod error;
pub mod geom;
pub mod kitti;
pub mod label;
pub mod pipeline;
pub mod preview;
pub mod project;
pub mod report;
pub mod write;

pub use error::{Error, Result};
