//! The sensor model a conversion decides rows by, as provenance: which model (a built-in
//! sensor, or a calibration file with the digest of its bytes), how ring fields count, and the
//! model itself, resolved once.

use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};

use serde::{Deserialize, Serialize};

use super::ouster::OusterModel;
use super::presets::Sensor;
use super::{read_calibration, RingOrder, SensorModel};
use crate::error::{Error, Result};
use crate::geom::Point3;
use crate::source::PointLayout;

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

/// The rows of a frame of another sensor, from its sensor model.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BeamRowsOf {
    /// The beam row of every point of the scan (0 = the highest beam).
    pub rows: Vec<u8>,
    /// The sensor's beams.
    pub beams: usize,
    /// Where they came from.
    pub from: RowsFrom,
    /// Points that fit no beam of the table (0 for a ring field).
    pub off_model: u64,
    /// The sensor's own column of every point (Ouster's destaggered measurement id), when asked
    /// for ([`SensorParams::ouster_columns`]); `None`: columns by azimuth.
    pub columns: Option<Vec<u16>>,
}

/// Where a frame's beam rows came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RowsFrom {
    /// A ring / channel / laser id field of the scan.
    RingField,
    /// The sensor's beam table (nearest beam by elevation).
    BeamTable,
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
    /// Where the sensor sits in the points' frame (`--sensor-pose`): the points are moved into
    /// the sensor's frame when read. `None`: they are in it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pose: Option<super::SensorPose>,
    /// Columns are Ouster's own (measurement ids, destaggered: the image the vendor's tools
    /// show) instead of azimuth bins; needs an Ouster metadata file ([`SensorParams::check_map`]).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub ouster_columns: bool,
    /// The point layout of the scans' `.bin` files (`--fields`), as a full declaration
    /// ([`PointLayout::declaration`]); `None`: KITTI's (nuScenes' for `.pcd.bin`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fields: Option<String>,
    /// The model, resolved once (not serialised: `source` says what it is; params read back
    /// resolve it at their first use).
    #[serde(skip)]
    model: OnceLock<Arc<SensorModel>>,
    /// An Ouster unit's own model (its columns), resolved with `model`; `None` for others.
    #[serde(skip)]
    ouster: OnceLock<Option<Arc<OusterModel>>>,
}

impl PartialEq for SensorParams {
    fn eq(&self, o: &SensorParams) -> bool {
        (
            &self.source,
            &self.name,
            self.beams,
            self.ring_order,
            self.pose,
            self.ouster_columns,
            &self.fields,
        ) == (
            &o.source,
            &o.name,
            o.beams,
            o.ring_order,
            o.pose,
            o.ouster_columns,
            &o.fields,
        )
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
            pose: None,
            ouster_columns: false,
            fields: None,
            model: OnceLock::from(Arc::new(model)),
            ouster: OnceLock::from(None),
        }
    }

    /// A built-in sensor by name (`vlp16`, `pandar40p`, ... ) or a calibration file by path
    /// (`.yaml`, `.csv`, `.json`), as Python's `sensor=` takes it.
    pub fn named_or_file(name: &str, ring_order: RingOrder) -> Result<SensorParams> {
        match name.parse::<Sensor>() {
            Ok(s) => Ok(SensorParams::preset(s, ring_order)),
            Err(_) if Path::new(name).extension().is_some() => {
                SensorParams::file(Path::new(name), ring_order)
            }
            Err(_) => Err(super::unknown_sensor(name)),
        }
    }

    /// A calibration file (read now, once; the digest of the bytes read recorded).
    pub fn file(path: &Path, ring_order: RingOrder) -> Result<SensorParams> {
        let (model, ouster, digest) = read_with_digest(path)?;
        Ok(SensorParams {
            source: SensorSource::File {
                path: path.to_path_buf(),
                digest,
            },
            name: model.name.clone(),
            beams: model.beams(),
            ring_order,
            pose: None,
            ouster_columns: false,
            fields: None,
            model: OnceLock::from(Arc::new(model)),
            ouster: OnceLock::from(ouster.map(Arc::new)),
        })
    }

    /// A scan of this sensor in its terms (`points` already in the sensor's frame:
    /// [`crate::sensor::read_scan`] applies the pose): every point's beam row, from the scan's
    /// ring field where it has one (its ids must be the sensor's beams; `path` names the scan),
    /// else the table's nearest beam.
    pub fn beam_rows(
        &self,
        points: &[Point3],
        rings: Option<&[u16]>,
        path: &Path,
    ) -> Result<BeamRowsOf> {
        let model = self.model()?;
        let beams = model.beams();
        let mut of = match rings {
            Some(r) => BeamRowsOf {
                rows: super::ring_rows(r, beams, self.ring_order, path)?,
                beams,
                from: RowsFrom::RingField,
                off_model: 0,
                columns: None,
            },
            None => {
                let b = model.assign(points);
                BeamRowsOf {
                    rows: b.rows,
                    beams,
                    from: RowsFrom::BeamTable,
                    off_model: b.off_model,
                    columns: None,
                }
            }
        };
        if self.ouster_columns {
            of.columns = Some(self.ouster_model()?.columns(points, &of.rows));
        }
        Ok(of)
    }

    /// Declares the point layout of the scans' `.bin` files (`--fields x,y,z,intensity,ring:f32`:
    /// [`PointLayout::declared`]).
    pub fn with_fields(mut self, spec: &str) -> Result<SensorParams> {
        self.fields = Some(PointLayout::declared(spec)?.declaration());
        Ok(self)
    }

    /// The declared point layout of the scans' `.bin` files, if any.
    pub fn layout(&self) -> Result<Option<PointLayout>> {
        self.fields
            .as_deref()
            .map(PointLayout::declared)
            .transpose()
    }

    /// Asks for Ouster's own columns ([`SensorParams::ouster_columns`]): an error unless the
    /// model is an Ouster metadata file's.
    pub fn with_ouster_columns(mut self) -> Result<SensorParams> {
        self.ouster_columns = true;
        self.ouster_model()?;
        Ok(self)
    }

    /// Checks that a map of `cols` columns over `fov` can hold this sensor's maps: with Ouster
    /// columns, a full turn of exactly the sensor's columns per frame.
    pub fn check_map(&self, cols: usize, fov: crate::geom::Degrees) -> Result<()> {
        if !self.ouster_columns {
            return Ok(());
        }
        self.ouster_model()?.check_map(cols, fov)
    }

    /// With Ouster columns, the sensor's columns per frame.
    pub fn own_columns(&self) -> Option<usize> {
        let ouster = self.ouster.get()?.as_ref()?;
        self.ouster_columns
            .then_some(ouster.format.columns_per_frame)
    }

    /// The resolved model (rebuilt once where the params were read back: a built-in one from
    /// its table, a file only while its content is the one recorded).
    pub fn model(&self) -> Result<Arc<SensorModel>> {
        if let Some(m) = self.model.get() {
            return Ok(m.clone());
        }
        self.resolve()?;
        Ok(self.model.get().expect("resolved").clone())
    }

    /// The Ouster unit's own model, which its columns need: an error unless the calibration is
    /// an Ouster metadata file.
    pub fn ouster_model(&self) -> Result<Arc<OusterModel>> {
        if self.ouster.get().is_none() {
            self.resolve()?;
        }
        self.ouster.get().cloned().flatten().ok_or_else(|| {
            Error::Config(format!(
                "Ouster columns need an Ouster metadata file (.json) as the sensor calibration; \
                 {} has no Ouster frame layout",
                self.name
            ))
        })
    }

    /// Resolves the model (and an Ouster unit's own) from `source`, once.
    fn resolve(&self) -> Result<()> {
        let (model, ouster) = match &self.source {
            SensorSource::Preset(s) => (s.model_table(), None),
            SensorSource::File { path, digest } => {
                let (model, ouster, now) = read_with_digest(path)?;
                if &now != digest {
                    return Err(Error::format(
                        path,
                        format!(
                            "the calibration changed since the conversion read it (content \
                             {now}, recorded {digest})"
                        ),
                    ));
                }
                (model, ouster)
            }
        };
        // Another thread may have resolved it first: the same files, the same model.
        let _ = self.model.set(Arc::new(model));
        let _ = self.ouster.set(ouster.map(Arc::new));
        Ok(())
    }
}

/// Reads a calibration file once, as a beam model (and an Ouster unit's own model, from its
/// metadata `.json`), with the XXH3-64 digest (hex) of the bytes read
/// ([`crate::fs::recording`] fingerprints them).
fn read_with_digest(path: &Path) -> Result<(SensorModel, Option<OusterModel>, String)> {
    let ouster = path.extension().is_some_and(|e| e == "json");
    let (read, inputs) = crate::fs::recording(|| match ouster {
        true => super::ouster::read_model(path).map(|m| (m.sensor.clone(), Some(m))),
        false => read_calibration(path).map(|m| (m, None)),
    });
    let (model, ouster) = read?;
    let fingerprint = inputs
        .records()
        .iter()
        .find(|r| r.path == path)
        .and_then(|r| r.file)
        .expect("read_calibration reads its file through fs::read");
    Ok((model, ouster, format!("{:016x}", fingerprint.xxh3)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An Ouster unit's metadata gives its own model (its columns' tables built once), shared by
    /// every frame; read back, the same.
    #[test]
    fn an_ouster_unit_s_own_model_is_resolved_once() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("fixtures/lidars/ouster/OS-1-128_767798045_1024x10_20230712_120049.json");
        let made = SensorParams::file(&path, RingOrder::BottomUp)
            .unwrap()
            .with_ouster_columns()
            .unwrap();
        assert_eq!(made.own_columns(), Some(1024));
        let back: SensorParams =
            serde_json::from_str(&serde_json::to_string(&made).unwrap()).unwrap();
        let (a, b) = (back.ouster_model().unwrap(), back.ouster_model().unwrap());
        assert!(Arc::ptr_eq(&a, &b) && a.sensor == *back.model().unwrap());
        assert_eq!(*a, *made.ouster_model().unwrap());
    }

    #[test]
    fn a_calibration_read_back_is_used_only_while_its_content_is_the_recorded_one() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.csv");
        std::fs::write(&path, "Laser id,Elevation,Azimuth\n1,2.0,0\n2,-2.0,0\n").unwrap();
        let made = SensorParams::file(&path, RingOrder::BottomUp).unwrap();
        let json = serde_json::to_string(&made).unwrap();
        let back: SensorParams = serde_json::from_str(&json).unwrap();
        assert_eq!(back, made);
        assert_eq!(back.model().unwrap().beams(), 2);
        // Resolved once: every later use shares the model (and its tables).
        assert!(Arc::ptr_eq(&back.model().unwrap(), &back.model().unwrap()));
        assert!(back.ouster_model().is_err());
        std::fs::write(&path, "Laser id,Elevation,Azimuth\n1,3.0,0\n2,-2.0,0\n").unwrap();
        let back: SensorParams = serde_json::from_str(&json).unwrap();
        let e = back.model().unwrap_err().to_string();
        assert!(e.contains("t.csv") && e.contains("changed since"), "{e}");
    }
}
