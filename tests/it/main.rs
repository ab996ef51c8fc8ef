//! The integration tests: one binary, a module per stage, on the real KITTI files in
//! `fixtures/raw` (and `../shared/kitti` where present).

mod annotation_formats;
mod annotations;
mod architecture;
mod bad_input;
mod bags;
mod box_labels;
mod check;
mod cli;
mod cloud;
mod defaults;
mod errors;
mod fuzz;
mod label;
mod lidars;
mod nuscenes;
mod outputs;
mod own_sensor;
mod pinned;
mod points;
mod project;
mod provenance;
mod readers;
mod reports;
mod resume;
mod score;
mod shards;
mod sources;
mod special_files;
mod truth;
mod unproject;
mod util;
