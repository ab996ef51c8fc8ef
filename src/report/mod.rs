//! REPORTS over what was written (and the raw tracklets): the train/val split ([`split`]) and the
//! class and channel statistics ([`stats`]).

pub mod imageset;
pub mod inspect;
pub mod score;
pub mod split;
pub mod stats;
