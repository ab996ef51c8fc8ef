//! INFER: what a model needs to be fed, as its ONNX file records it.
//!
//! The trainer's export (`python -m kitti2pgm_train export`) writes one metadata entry,
//! [`METADATA_KEY`], holding a [`ModelSpec`] as JSON: the map parameters its training data was
//! made with (map shape and rows, sensor model and pose, colour, class map), the input's
//! channels and where the normalisation is. This module is the one place that decides the key
//! and the record: the export builds its entry through the Python module
//! (`kitti2pgm.model_metadata`), which calls [`ModelSpec::metadata_entry`].

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::project::{Channel, Channels};
use crate::provenance::MapParams;

/// The ONNX metadata key (`metadata_props`) of a [`ModelSpec`].
pub const METADATA_KEY: &str = "kitti2pgm.model";

/// The version of the record this build writes and reads.
pub const SPEC_VERSION: u32 = 1;

/// Where a model's input normalisation happens.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Normalisation {
    /// Inside the graph: the model takes the channels as a kitti2pgm map holds them (the
    /// trainer's export).
    InGraph,
    /// Per channel, before the model: `(value - mean) / std` in cells with a point, 0 in empty
    /// cells (SqueezeSeg's and RangeNet++'s own preprocessing).
    PerChannel {
        /// Mean of each input channel.
        mean: Vec<f32>,
        /// Standard deviation of each input channel.
        std: Vec<f32>,
    },
}

/// Everything needed to feed a model and read its output.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelSpec {
    /// The record's version ([`SPEC_VERSION`]).
    pub version: u32,
    /// The map parameters the model's training data was made with.
    pub map: MapParams,
    /// The input's channels, in order: a 1 x rows x cols x channels float32 tensor.
    pub channels: Vec<String>,
    /// Where the input is normalised.
    pub normalisation: Normalisation,
    /// The input's name in the graph.
    pub input: String,
    /// The output holding each cell's class (1 x rows x cols, integers), if the model has one.
    pub labels_output: Option<String>,
    /// The output holding the class scores (1 x classes x rows x cols), if any.
    pub logits_output: Option<String>,
    /// Who made the model (free text, for people: the trainer, its network and input).
    #[serde(default)]
    pub producer: String,
}

impl ModelSpec {
    /// The spec of a model that records none, trained on maps of `map` (their channels, the
    /// label excepted, taken as they are): the graph's names are found when it is opened
    /// ([`super::Model::open`]).
    pub fn for_map(map: MapParams) -> ModelSpec {
        let channels = map.channels().inputs();
        ModelSpec {
            version: SPEC_VERSION,
            channels: channels.names().iter().map(|n| n.to_string()).collect(),
            map,
            normalisation: Normalisation::InGraph,
            input: String::new(),
            labels_output: None,
            logits_output: None,
            producer: String::new(),
        }
    }

    /// The input channels, parsed.
    pub fn input_channels(&self) -> Result<Channels> {
        Channels::from_names(&self.channels).map_err(|name| {
            Error::Config(format!(
                "the model's channel {name:?} is not a kitti2pgm channel ({})",
                Channel::ALL
                    .iter()
                    .map(|c| c.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            ))
        })
    }

    /// Checks the record: its version, the map, the channels (each a map channel, the label
    /// excluded, colour only with a colour map), the normalisation's lengths and an output.
    pub fn validate(&self) -> Result<()> {
        let bad = |what: String| Err(Error::Config(format!("the model's record: {what}")));
        if self.version != SPEC_VERSION {
            return bad(format!(
                "version {} (this kitti2pgm reads version {SPEC_VERSION})",
                self.version
            ));
        }
        self.map.validate()?;
        let channels = self.input_channels()?;
        if channels.is_empty() || channels.has(Channel::Label) {
            return bad(format!(
                "channels {:?}: the input is one or more map channels, never the label",
                self.channels
            ));
        }
        if !channels.has(Channel::Range) {
            return bad("the channels lack range (it marks the empty cells)".into());
        }
        if channels.has_rgb() && self.map.rgb.is_none() {
            return bad("colour channels, but the map samples no colour".into());
        }
        if let Normalisation::PerChannel { mean, std } = &self.normalisation {
            if mean.len() != channels.len() || std.len() != channels.len() {
                return bad(format!(
                    "{} means and {} deviations for {} channels",
                    mean.len(),
                    std.len(),
                    channels.len()
                ));
            }
            if std.iter().any(|s| !(s.is_finite() && *s > 0.0))
                || mean.iter().any(|m| !m.is_finite())
            {
                return bad("the deviations must be finite and positive, the means finite".into());
            }
        }
        if self.labels_output.is_none() && self.logits_output.is_none() {
            return bad("neither a labels nor a logits output".into());
        }
        Ok(())
    }

    /// The metadata entry (key, JSON value) that records this spec in an ONNX file; the spec is
    /// checked first.
    pub fn metadata_entry(&self) -> Result<(String, String)> {
        self.validate()?;
        let json = serde_json::to_string(self)
            .map_err(|e| Error::Config(format!("the model's record: {e}")))?;
        Ok((METADATA_KEY.to_string(), json))
    }

    /// The spec recorded in a model's metadata value (`source` names the file in errors).
    pub fn from_metadata(value: &str, source: &std::path::Path) -> Result<ModelSpec> {
        let bad = |e: String| Error::format(source, format!("its {METADATA_KEY} metadata: {e}"));
        let spec: ModelSpec = serde_json::from_str(value).map_err(|e| bad(e.to_string()))?;
        spec.validate().map_err(|e| bad(e.to_string()))?;
        Ok(spec)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec() -> ModelSpec {
        ModelSpec {
            input: "tensor".into(),
            labels_output: Some("labels".into()),
            ..ModelSpec::for_map(MapParams::default())
        }
    }

    #[test]
    fn a_record_round_trips_through_its_metadata_entry() {
        let (key, value) = spec().metadata_entry().unwrap();
        assert_eq!(key, METADATA_KEY);
        let back = ModelSpec::from_metadata(&value, "m.onnx".as_ref()).unwrap();
        assert_eq!(back, spec());
        assert_eq!(back.channels, ["x", "y", "z", "intensity", "range"]);
    }

    #[test]
    fn bad_records_are_refused_naming_what_is_wrong() {
        let err = |f: fn(&mut ModelSpec)| {
            let mut s = spec();
            f(&mut s);
            s.validate().unwrap_err().to_string()
        };
        assert!(err(|s| s.version = 2).contains("version 2"));
        assert!(err(|s| s.channels.push("label".into())).contains("never the label"));
        assert!(err(|s| s.channels.push("r".into())).contains("samples no colour"));
        assert!(err(|s| s.channels.push("depth".into())).contains("\"depth\""));
        assert!(err(|s| s.channels.retain(|c| c != "range")).contains("lack range"));
        assert!(err(|s| s.labels_output = None).contains("neither"));
        assert!(err(|s| s.normalisation = Normalisation::PerChannel {
            mean: vec![0.0; 5],
            std: vec![1.0; 4]
        })
        .contains("5 means and 4 deviations"));
        let e = ModelSpec::from_metadata("{\"version\": 1}", "m.onnx".as_ref()).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("m.onnx: its kitti2pgm.model metadata"),
            "{e}"
        );
    }
}
