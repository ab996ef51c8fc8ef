//! The integration tests: one binary, a module per stage, on the real KITTI files in
//! `fixtures/raw` (and `../shared/kitti` where present).

mod architecture;
mod audit;
mod audit2;
mod bad_input;
mod check;
mod cli;
mod cloud;
mod errors;
mod fuzz;
mod label;
mod newcomer;
mod outputs;
mod pinned;
mod points;
mod project;
mod provenance;
mod readers;
mod reports;
mod score;
mod shards;
mod sources;
mod special_files;
mod truth;
mod unproject;
mod util;
