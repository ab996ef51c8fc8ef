//! REPORTS over what was written: ground truth opened whatever its form ([`truth`]), class and
//! channel statistics ([`stats`]), IoU scoring of predictions ([`score`]) and what a shard holds
//! ([`inspect`]). The split lists are made on the input side ([`crate::plan::split`]).

pub mod inspect;
pub mod score;
pub mod stats;
pub mod submission;
pub mod truth;
pub mod unproject;
