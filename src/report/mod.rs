//! REPORTS over what was written: ground truth opened whatever its form ([`truth`]), class and
//! channel statistics ([`stats`]), IoU scoring of predictions ([`score`]) and what a shard holds
//! ([`inspect`]), pictures of a sequence labelled from boxes ([`labelled`]). The split lists are made on the input side ([`crate::plan::split`]).

pub mod inspect;
pub mod labelled;
pub mod score;
pub mod stats;
pub mod submission;
pub mod truth;
pub mod unproject;
