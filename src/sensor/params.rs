//! The sensor model a conversion decides rows by, as provenance: which model (a built-in
//! sensor, or a calibration file with the digest of its bytes), how ring fields count, and the
//! model itself, resolved once.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use serde::{Deserialize, Serialize};

use super::presets::Sensor;
use super::{read_calibration, RingOrder, SensorModel};
use crate::error::Result;

/// Where the beam table comes from.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SensorSource {
    /// A built-in nominal table (`--sensor`).
    Preset(Sensor),
    /// A unit's calibration file (`--sensor-calibration`), with the XXH3-64 digest of its bytes.
    File {
        /// The file.
        path: PathBuf,
        /// Its content digest (hex).
        digest: String,
    },
}

/// The sensor model of a conversion.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SensorParams {
    /// Where the beam table comes from.
    pub source: SensorSource,
    /// The sensor's name (the vendor's model, or the calibration file's own).
    pub name: String,
    /// Beams: the map's rows by default.
    pub beams: usize,
    /// How a ring / channel field in the scans counts the beams.
    pub ring_order: RingOrder,
    /// The model, resolved (not serialised: `source` says what it is).
    #[serde(skip)]
    pub model: Option<Arc<SensorModel>>,
}

impl PartialEq for SensorParams {
    fn eq(&self, o: &SensorParams) -> bool {
        (&self.source, &self.name, self.beams, self.ring_order)
            == (&o.source, &o.name, o.beams, o.ring_order)
    }
}

impl SensorParams {
    /// A built-in sensor.
    pub fn preset(sensor: Sensor, ring_order: RingOrder) -> SensorParams {
        let model = sensor.model_table();
        SensorParams {
            source: SensorSource::Preset(sensor),
            name: model.name.clone(),
            beams: model.beams(),
            ring_order,
            model: Some(Arc::new(model)),
        }
    }

    /// A calibration file (read now; its digest recorded).
    pub fn file(path: &Path, ring_order: RingOrder) -> Result<SensorParams> {
        let bytes = crate::fs::read(path, crate::fs::Limit::Text)?;
        let model = read_calibration(path)?;
        Ok(SensorParams {
            source: SensorSource::File {
                path: path.to_path_buf(),
                digest: format!("{:016x}", xxhash_rust::xxh3::xxh3_64(&bytes)),
            },
            name: model.name.clone(),
            beams: model.beams(),
            ring_order,
            model: Some(Arc::new(model)),
        })
    }

    /// The resolved model (a built-in one is rebuilt where the params were read back).
    pub fn model(&self) -> Result<Arc<SensorModel>> {
        if let Some(m) = &self.model {
            return Ok(m.clone());
        }
        Ok(Arc::new(match &self.source {
            SensorSource::Preset(s) => s.model_table(),
            SensorSource::File { path, .. } => read_calibration(path)?,
        }))
    }
}
