//! The package of kitti2pgm's criterion benchmarks (`stages.rs`); it holds no code of its own.
//! `cargo bench -p kitti2pgm-bench` runs them (docs/performance.md).
