//! `kitti2pgm.Dataset`: the frames of a KITTI raw, SemanticKITTI or KITTI object root, each
//! read and labelled by the converter's own code (`kitti2pgm::convert::frame::load`).

use std::collections::HashMap;
use std::path::PathBuf;

use numpy::{PyArray1, PyArrayMethods};
use pyo3::exceptions::{PyIndexError, PyKeyError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use kitti2pgm::convert::frame::{load, Viz};
use kitti2pgm::geom::Degrees;
use kitti2pgm::plan::{FrameSelection, Plan};
use kitti2pgm::project::camera::{RgbOptions, Sampling};
use kitti2pgm::project::{project_cloud, rings, Cloud, PgmSpec};
use kitti2pgm::provenance::MapParams;
use kitti2pgm::sensor::params::SensorParams;
use kitti2pgm::sensor::{RingOrder, SensorPose};
use kitti2pgm::source::kitti::DatasetKind;

use crate::readers::{box_dict, class_map_of, scan_array, to_py};
use crate::{py_err, spec_of, MapArgs};

/// The frames of a dataset root, loaded as `kitti2pgm convert` loads them.
///
/// Dataset(root, *, dataset=None, class_map=None, rgb_camera=None, sampling="nearest",
///         all_frames=False)
///
/// root: a KITTI raw root (or date / drive folder), a SemanticKITTI root (sequences/) or a
/// KITTI object root (training/, testing/); dataset forces "raw", "semantickitti" or "object"
/// (source=, its older name, is still taken).
/// class_map: "kitti-paper-4", "semantic-kitti" or a yaml file (default: the layout's).
/// `len(ds)`, `ds[i]` / `ds["<frame id>"]` and `for frame in ds` give the frames as `load` does.
/// rgb_camera: 2 or 3 to sample each point's colour from that camera's image.
/// all_frames: every scan, not only those with a tracklet pose (KITTI raw).
/// sensor: another sensor's scans (a sequence of `.pcd` files, an unpacked ROS 2 bag): a
/// built-in sensor ("vlp16", ... `SENSORS`) or its calibration file; rows are its beams, from
/// the scans' ring field (counted as ring_order says: "bottom-up" or "top-down") or its table,
/// and `project` makes one row per beam unless rows= says otherwise (as `convert --sensor`).
/// sensor_pose: "x,y,z[,roll,pitch,yaw]" (metres, degrees), the sensor's pose in the points'
/// frame (a base_link cloud): the points are moved into the sensor's frame (`--sensor-pose`).
/// fields: the point layout of the scans' flat `.bin` files ("x,y,z,intensity,ring:f32", as
/// `--fields`; with sensor=).
/// ouster_columns: with an Ouster metadata file as sensor, Ouster's own columns (measurement
/// ids, destaggered: `load` gives each point's as "column", `project` makes the SDK's image,
/// its columns per frame over 360 degrees), as `convert --ouster-columns`.
#[pyclass(frozen, module = "kitti2pgm")]
pub struct Dataset {
    plan: Plan,
    map: MapParams,
    ids: Vec<String>,
    by_id: HashMap<String, usize>,
}

#[pymethods]
impl Dataset {
    #[new]
    #[pyo3(signature = (root, *, dataset=None, class_map=None, rgb_camera=None, sampling="nearest", all_frames=false, sensor=None, ring_order="bottom-up", sensor_pose=None, ouster_columns=false, fields=None, source=None))]
    // One Rust argument per Python keyword: the signature is the Python API.
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        root: PathBuf,
        dataset: Option<&str>,
        class_map: Option<&str>,
        rgb_camera: Option<u8>,
        sampling: &str,
        all_frames: bool,
        sensor: Option<&str>,
        ring_order: &str,
        sensor_pose: Option<&str>,
        ouster_columns: bool,
        fields: Option<&str>,
        source: Option<&str>,
    ) -> PyResult<Dataset> {
        let ring_order = crate::named::<RingOrder>("ring_order", ring_order)?;
        let mut sensor = sensor
            .map(|s| SensorParams::named_or_file(s, ring_order))
            .transpose()
            .map_err(py_err)?;
        if let Some(pose) = sensor_pose {
            let Some(s) = sensor.as_mut() else {
                return Err(PyValueError::new_err(
                    "sensor_pose needs the sensor (sensor=)",
                ));
            };
            s.pose = Some(SensorPose::parse(pose).map_err(py_err)?);
        }
        if let Some(spec) = fields {
            let Some(s) = sensor.take() else {
                return Err(PyValueError::new_err("fields needs the sensor (sensor=)"));
            };
            sensor = Some(s.with_fields(spec).map_err(py_err)?);
        }
        if ouster_columns {
            let Some(s) = sensor.take() else {
                return Err(PyValueError::new_err(
                    "ouster_columns needs the sensor: sensor=\"<unit's metadata>.json\"",
                ));
            };
            sensor = Some(s.with_ouster_columns().map_err(py_err)?);
        }
        let own_columns = sensor.as_ref().and_then(SensorParams::own_columns);
        if dataset.is_some() && source.is_some() {
            return Err(PyValueError::new_err(
                "dataset= and source= (its older name) are one option: give one",
            ));
        }
        let source = (dataset.or(source))
            .map(|s| crate::named::<DatasetKind>("dataset", s))
            .transpose()?;
        let sampling = crate::named::<Sampling>("sampling", sampling)?;
        let selection = if all_frames {
            FrameSelection::All
        } else {
            FrameSelection::Annotated
        };
        let plan = py
            .detach(|| Plan::build_as(&root, selection, source))
            .map_err(py_err)?;
        let class_map = match class_map {
            Some(name) => class_map_of(name)?,
            None => kitti2pgm::format::box_labels::default_class_map(&plan).map_err(py_err)?,
        };
        plan.check_class_map(&class_map).map_err(py_err)?;
        let map = MapParams {
            spec: own_columns.map_or_else(PgmSpec::default, |w| PgmSpec {
                cols: w,
                fov: Degrees(360.0),
                ..PgmSpec::default()
            }),
            rgb: rgb_camera.map(|camera| RgbOptions { camera, sampling }),
            selection,
            class_map,
            sensor,
        };
        map.validate().map_err(py_err)?;
        let ids: Vec<String> = plan.frame_ids().map(|f| f.to_string()).collect();
        if ids.is_empty() {
            let why: Vec<String> = plan.failed.iter().map(|f| f.error.clone()).collect();
            return Err(PyValueError::new_err(format!(
                "{}: no frame to load{}",
                root.display(),
                if why.is_empty() {
                    " (no scan with annotations; all_frames=True takes every scan)".to_string()
                } else {
                    format!(": {}", why.join("; "))
                }
            )));
        }
        let by_id = ids
            .iter()
            .enumerate()
            .map(|(i, s)| (s.clone(), i))
            .collect();
        Ok(Dataset {
            plan,
            map,
            ids,
            by_id,
        })
    }

    /// Frame ids, in order (as `convert` names its outputs).
    #[getter]
    fn frames(&self) -> Vec<String> {
        self.ids.clone()
    }

    /// "raw", "semantickitti" or "object".
    #[getter]
    fn layout(&self) -> &'static str {
        self.plan.layout().as_str()
    }

    /// The class map the labels use (a dict).
    #[getter]
    fn class_map<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_py(py, &self.map.class_map)
    }

    /// Drives or frames that could not be planned: (what, error) pairs.
    #[getter]
    fn failed(&self) -> Vec<(String, String)> {
        self.plan
            .failed
            .iter()
            .map(|f| (f.what.to_string(), f.error.clone()))
            .collect()
    }

    fn __len__(&self) -> usize {
        self.ids.len()
    }

    /// `ds[i]` or `ds["<frame id>"]`: the frame, as `load` gives it.
    fn __getitem__<'py>(
        &self,
        py: Python<'py>,
        frame: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyDict>> {
        self.load(py, frame)
    }

    /// `for frame in ds`: every frame in order, as `load` gives it.
    fn __iter__(slf: Bound<'_, Self>) -> DatasetIter {
        DatasetIter {
            dataset: slf.unbind(),
            next: 0,
        }
    }

    fn __repr__(&self) -> String {
        format!(
            "<kitti2pgm.Dataset {} frames ({})>",
            self.ids.len(),
            self.layout()
        )
    }

    /// One frame, read and labelled: a dict with id, file_len (points in the .bin, dropped ones
    /// included), points (N, 4) float32 (finite, in range, file order), file_index (N,) uint32, ring (N,) uint8 or None (the beam rows with a sensor, row 0 the highest; else KITTI rings from the scan order, None without 64), label (N,)
    /// uint8, instance (N,) uint16, annotated (bool), boxes (list of dicts, as label_points
    /// takes them), rgb (N, 3) float32 and rgb_valid (N,) bool with rgb_camera, else None (the
    /// point shards' names, and `project`'s keywords).
    /// `frame`: an id or an index.
    fn load<'py>(
        &self,
        py: Python<'py>,
        frame: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let k = self.index_of(frame)?;
        let (d, f) = self.plan.jobs[k];
        let dp = &self.plan.drives[d];
        let l = py
            .detach(|| load(dp, f, &self.map, Viz::Off))
            .map_err(py_err)?;
        // The beam rows of the sensor (row 0 the highest beam), else KITTI's rings from the
        // scan order.
        let ring = match &l.beams {
            Some(b) => Some(b.rows.clone()),
            None => py.detach(|| rings(&l.scan.points)).0,
        };
        let colours = py.detach(|| l.point_colours());
        let n = l.scan.len();
        let out = PyDict::new(py);
        out.set_item("id", l.id.to_string())?;
        out.set_item("file_len", l.scan.file_len)?;
        out.set_item("points", scan_array(py, &l.scan)?)?;
        out.set_item("file_index", PyArray1::from_vec(py, l.scan.file_indices()))?;
        match ring {
            Some(r) => out.set_item("ring", PyArray1::from_vec(py, r))?,
            None => out.set_item("ring", py.None())?,
        }
        match l.beams.as_ref().and_then(|b| b.columns.clone()) {
            Some(c) => out.set_item("column", PyArray1::from_vec(py, c))?,
            None => out.set_item("column", py.None())?,
        }
        out.set_item("label", PyArray1::from_vec(py, l.labels.points.class))?;
        out.set_item("instance", PyArray1::from_vec(py, l.labels.points.instance))?;
        out.set_item("annotated", l.labels.annotated)?;
        let boxes = PyList::empty(py);
        for b in &l.labels.boxes {
            boxes.append(box_dict(py, b)?)?;
        }
        out.set_item("boxes", boxes)?;
        match colours {
            Some(c) => {
                let valid: Vec<bool> = c.iter().map(Option::is_some).collect();
                let flat: Vec<f32> = c.iter().flat_map(|v| v.unwrap_or([0.0; 3])).collect();
                let rgb = PyArray1::from_vec(py, flat).reshape([n, 3])?;
                let rgb_valid = PyArray1::from_vec(py, valid);
                out.set_item("rgb", rgb)?;
                out.set_item("rgb_valid", rgb_valid)?;
            }
            None => {
                for key in ["rgb", "rgb_valid"] {
                    out.set_item(key, py.None())?;
                }
            }
        }
        Ok(out)
    }

    /// The frame projected as `kitti2pgm convert` projects it: the dict `kitti2pgm.project`
    /// returns (map, channels, mask, label, instance, rgb_valid, row, col, point_index, stats),
    /// with the same map keywords, whose preset defaults to `convert`'s for this source (full
    /// for SemanticKITTI, squeezeseg for KITTI raw and the object set); load + project in one
    /// call.
    #[pyo3(signature = (frame, *, preset=None, rows=None, cols=None, fov_deg=None, fov_up_deg=None, fov_down_deg=None, row_mode=None),
        text_signature = "(self, frame, *, preset=None, rows=None, cols=None, fov_deg=None, fov_up_deg=None, fov_down_deg=None, row_mode=None)")]
    // One Rust argument per Python keyword: the signature is the Python API.
    #[allow(clippy::too_many_arguments)]
    fn project<'py>(
        &self,
        py: Python<'py>,
        frame: &Bound<'py, PyAny>,
        preset: Option<String>,
        rows: Option<usize>,
        cols: Option<usize>,
        fov_deg: Option<f64>,
        fov_up_deg: Option<f64>,
        fov_down_deg: Option<f64>,
        row_mode: Option<String>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let args = MapArgs {
            preset,
            rows,
            cols,
            fov_deg,
            fov_up_deg,
            fov_down_deg,
            row_mode,
        };
        // One row per beam of the sensor unless rows= says otherwise (as `convert --sensor`);
        // Ouster's columns per frame over a full turn with its columns.
        let own = self.map.sensor.as_ref().and_then(SensorParams::own_columns);
        let args = MapArgs {
            rows: args.rows.or(self.map.sensor.as_ref().map(|s| s.beams)),
            cols: args.cols.or(own),
            fov_deg: args.fov_deg.or(own.map(|_| 360.0)),
            ..args
        };
        let spec = spec_of(&args, Some(self.plan.layout()))?;
        if let Some(s) = &self.map.sensor {
            s.check_map(spec.cols, spec.fov).map_err(py_err)?;
        }
        let k = self.index_of(frame)?;
        let (d, f) = self.plan.jobs[k];
        let dp = &self.plan.drives[d];
        let map = MapParams {
            spec,
            ..self.map.clone()
        };
        let projected = py
            .detach(|| {
                let l = load(dp, f, &map, Viz::Off)?;
                let colours = l.point_colours();
                let valid: Option<Vec<bool>> = colours
                    .as_ref()
                    .map(|c| c.iter().map(Option::is_some).collect());
                let flat: Option<Vec<[f32; 3]>> = colours
                    .as_ref()
                    .map(|c| c.iter().map(|v| v.unwrap_or([0.0; 3])).collect());
                let cloud = Cloud {
                    points: &l.scan.points,
                    intensity: &l.scan.intensity,
                    rings: l.beams.as_ref().map(|b| &b.rows[..]),
                    beams: l
                        .beams
                        .as_ref()
                        .map_or(kitti2pgm::project::LASERS, |b| b.beams),
                    columns: l.beams.as_ref().and_then(|b| b.columns.as_deref()),
                    intensity_kind: if l.beams.is_some() {
                        kitti2pgm::project::IntensityKind::AsStored
                    } else {
                        kitti2pgm::project::IntensityKind::Reflectance
                    },
                    labels: Some(&l.labels.points.class),
                    instance: Some(&l.labels.points.instance),
                    colours: flat.as_deref(),
                    colour_valid: valid.as_deref(),
                };
                let off_model = l.beams.as_ref().map(|b| b.off_model);
                project_cloud(&cloud, &spec, None).map(|p| (p, off_model))
            })
            .map_err(py_err)?;
        let (projected, off_model) = projected;
        let d = crate::map_dict(py, projected, true)?;
        if let Some(off) = off_model {
            // As `project(sensor=...)`: the points that fit no beam of the sensor's table.
            d.get_item("stats")?
                .expect("map_dict has stats")
                .set_item("off_model", off)?;
        }
        Ok(d)
    }
}

/// Iterates over a [`Dataset`]'s frames.
#[pyclass(module = "kitti2pgm")]
pub struct DatasetIter {
    dataset: Py<Dataset>,
    next: usize,
}

#[pymethods]
impl DatasetIter {
    fn __iter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    fn __next__<'py>(&mut self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let ds = self.dataset.bind(py).get();
        if self.next >= ds.ids.len() {
            return Ok(None);
        }
        let i = self.next;
        self.next += 1;
        ds.load(py, &i.into_pyobject(py)?.into_any()).map(Some)
    }
}

impl Dataset {
    fn index_of(&self, frame: &Bound<'_, PyAny>) -> PyResult<usize> {
        if let Ok(i) = frame.extract::<i64>() {
            let n = self.ids.len() as i64;
            let j = if i < 0 { i + n } else { i };
            if !(0..n).contains(&j) {
                return Err(PyIndexError::new_err(format!("frame {i} of {n}")));
            }
            return Ok(j as usize);
        }
        let id: String = frame.extract()?;
        self.by_id
            .get(&id)
            .copied()
            .ok_or_else(|| PyKeyError::new_err(format!("no frame {id:?} in the dataset")))
    }
}
