//! `kitti2pgm.Dataset`: the frames of a KITTI raw, SemanticKITTI or KITTI object root, each
//! read and labelled by the converter's own code (`kitti2pgm::convert::frame::load`).

use std::collections::HashMap;
use std::path::PathBuf;

use numpy::{PyArray1, PyArrayMethods};
use pyo3::exceptions::{PyIndexError, PyKeyError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use kitti2pgm::convert::frame::load;
use kitti2pgm::kitti::Layout;
use kitti2pgm::label::ClassMap;
use kitti2pgm::params::MapParams;
use kitti2pgm::plan::{FrameSelection, Plan};
use kitti2pgm::project::camera::{RgbOptions, Sampling};
use kitti2pgm::project::rings;

use crate::readers::{box_dict, class_map_of, scan_array, to_py};
use crate::{py_err, spec_of};

/// The frames of a dataset root, loaded as `kitti2pgm convert` loads them.
///
/// Dataset(root, *, source=None, class_map=None, rgb_camera=None, sampling="nearest",
///         all_frames=False)
///
/// root: a KITTI raw root (or date / drive folder), a SemanticKITTI root (sequences/) or a
/// KITTI object root (training/, testing/); source forces "raw", "semantickitti" or "object".
/// class_map: "kitti-paper", "semantic-kitti" or a yaml file (default: the layout's).
/// rgb_camera: 2 or 3 to sample each point's colour from that camera's image.
/// all_frames: every scan, not only those with a tracklet pose (KITTI raw).
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
    #[pyo3(signature = (root, *, source=None, class_map=None, rgb_camera=None, sampling="nearest", all_frames=false))]
    fn new(
        py: Python<'_>,
        root: PathBuf,
        source: Option<&str>,
        class_map: Option<&str>,
        rgb_camera: Option<u8>,
        sampling: &str,
        all_frames: bool,
    ) -> PyResult<Dataset> {
        let source = match source {
            None => None,
            Some("raw") => Some(Layout::Raw),
            Some("semantickitti") | Some("sequences") => Some(Layout::Sequence),
            Some("object") => Some(Layout::Object),
            Some(s) => {
                return Err(PyValueError::new_err(format!(
                    "source must be 'raw', 'semantickitti' or 'object', not {s:?}"
                )))
            }
        };
        let sampling = match sampling {
            "nearest" => Sampling::Nearest,
            "bilinear" => Sampling::Bilinear,
            s => {
                return Err(PyValueError::new_err(format!(
                    "sampling must be 'nearest' or 'bilinear', not {s:?}"
                )))
            }
        };
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
            None => ClassMap::default_for(plan.layout()),
        };
        plan.check_class_map(&class_map).map_err(py_err)?;
        let map = MapParams {
            rgb: rgb_camera.map(|camera| RgbOptions { camera, sampling }),
            selection,
            class_map,
            ..Default::default()
        };
        map.validate().map_err(py_err)?;
        let ids: Vec<String> = plan.frame_ids().map(|f| f.to_string()).collect();
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
        match self.plan.layout() {
            Layout::Raw => "raw",
            Layout::Sequence => "semantickitti",
            Layout::Object => "object",
        }
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
            .map(|f| (f.what.clone(), f.error.clone()))
            .collect()
    }

    fn __len__(&self) -> usize {
        self.ids.len()
    }

    fn __repr__(&self) -> String {
        format!(
            "<kitti2pgm.Dataset {} frames ({})>",
            self.ids.len(),
            self.layout()
        )
    }

    /// One frame, read and labelled: a dict with id, points (N, 4) float32 (finite, in range,
    /// file order), file_index (N,) uint32, ring (N,) uint8 or None (no 64 rings), label (N,)
    /// uint8, instance (N,) uint16, annotated (bool), boxes (list of dicts, as label_points
    /// takes them), colours (N, 3) float32 and colour_valid (N,) bool with rgb_camera, else None.
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
            .detach(|| load(dp, f, &self.map, false))
            .map_err(py_err)?;
        let (ring, _) = py.detach(|| rings(&l.scan.points));
        let colours = py.detach(|| l.point_colours());
        let n = l.scan.len();
        let out = PyDict::new(py);
        out.set_item("id", l.id.to_string())?;
        out.set_item("points", scan_array(py, &l.scan)?)?;
        out.set_item("file_index", PyArray1::from_vec(py, l.scan.file_indices()))?;
        match ring {
            Some(r) => out.set_item("ring", PyArray1::from_vec(py, r))?,
            None => out.set_item("ring", py.None())?,
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
                out.set_item("colours", PyArray1::from_vec(py, flat).reshape([n, 3])?)?;
                out.set_item("colour_valid", PyArray1::from_vec(py, valid))?;
            }
            None => {
                out.set_item("colours", py.None())?;
                out.set_item("colour_valid", py.None())?;
            }
        }
        Ok(out)
    }

    /// The map `kitti2pgm convert` writes for a frame (same keyword arguments as
    /// `kitti2pgm.project`'s map shape): load + project in one call.
    #[pyo3(signature = (frame, *, rows=64, cols=512, fov_deg=90.0, fov_up_deg=2.0, fov_down_deg=-24.9, row_mode="rings"))]
    #[allow(clippy::too_many_arguments)]
    fn project<'py>(
        &self,
        py: Python<'py>,
        frame: &Bound<'py, PyAny>,
        rows: usize,
        cols: usize,
        fov_deg: f64,
        fov_up_deg: f64,
        fov_down_deg: f64,
        row_mode: &str,
    ) -> PyResult<Bound<'py, PyAny>> {
        let spec = spec_of(rows, cols, fov_deg, fov_up_deg, fov_down_deg, row_mode)?;
        let k = self.index_of(frame)?;
        let (d, f) = self.plan.jobs[k];
        let dp = &self.plan.drives[d];
        let map = MapParams {
            spec,
            ..self.map.clone()
        };
        let conv = py
            .detach(|| {
                let l = load(dp, f, &map, false)?;
                let cam = l.camera.as_ref().map(|(p, i)| (p, i));
                Ok::<_, kitti2pgm::Error>(kitti2pgm::convert::process(
                    &l.id,
                    &l.scan,
                    &l.labels,
                    &spec,
                    &map.class_map,
                    cam,
                ))
            })
            .map_err(py_err)?;
        let (h, w, c) = (conv.pgm.rows, conv.pgm.cols, conv.pgm.depth());
        Ok(PyArray1::from_vec(py, conv.pgm.data)
            .reshape([h, w, c])?
            .into_any())
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
