//! `Model` and `model_metadata`: trained ONNX models from Python, run by the library's
//! `kitti2pgm::infer` (the same projection, engine and kNN as `kitti2pgm infer`).

use std::path::{Path, PathBuf};

use numpy::{PyArray1, PyArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use kitti2pgm::infer::frame::{self, ScanResult};
use kitti2pgm::infer::{Model as RustModel, ModelOptions, ModelSpec, Normalisation, SPEC_VERSION};
use kitti2pgm::project::unproject::{KnnParams, Method, MethodKind};
use kitti2pgm::provenance::MapParams;
use kitti2pgm::source::Scan;

use crate::arrays::{points_arg, vec_arg};
use crate::{named, py_err};

/// The metadata entry that records a model's map in its ONNX file, as (key, value): what the
/// trainer's export writes (`metadata_props`) and `kitti2pgm infer` reads.
///
/// map: the map parameters its training data was made with, as JSON (a shard's or
/// convert_summary.json's "map"); channels: the input's channels in order (shard channel
/// names); producer: free text naming the trainer, network and input; input, labels_output,
/// logits_output: the graph's names. The record is checked (ValueError naming what is wrong).
#[pyfunction]
#[pyo3(signature = (map, channels, producer="", *, input="tensor", labels_output=Some("labels"),
    logits_output=Some("logits")))]
pub(crate) fn model_metadata(
    map: &str,
    channels: Vec<String>,
    producer: &str,
    input: &str,
    labels_output: Option<&str>,
    logits_output: Option<&str>,
) -> PyResult<(String, String)> {
    let map: MapParams = serde_json::from_str(map)
        .map_err(|e| PyValueError::new_err(format!("map: not kitti2pgm's map parameters: {e}")))?;
    let spec = ModelSpec {
        version: SPEC_VERSION,
        map,
        channels,
        normalisation: Normalisation::InGraph,
        input: input.to_string(),
        labels_output: labels_output.map(str::to_string),
        logits_output: logits_output.map(str::to_string),
        producer: producer.to_string(),
    };
    spec.metadata_entry().map_err(py_err)
}

/// A trained model (ONNX), opened in ONNX Runtime with the map it records.
///
/// `Model(path, *, onnxruntime=None, threads=0)`: onnxruntime names ONNX Runtime's library
/// (default: the onnxruntime Python package's); threads: ONNX Runtime's threads (0: every core).
#[pyclass(module = "kitti2pgm", frozen)]
pub(crate) struct Model {
    inner: RustModel,
}

fn result_dict<'py>(
    py: Python<'py>,
    r: ScanResult,
    rows: usize,
    cols: usize,
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let classes: Vec<i16> = r
        .per_point
        .iter()
        .map(|c| c.map_or(-1, i16::from))
        .collect();
    d.set_item("classes", PyArray1::from_vec(py, classes))?;
    d.set_item(
        "map",
        PyArray1::from_vec(py, r.cells).reshape([rows, cols])?,
    )?;
    Ok(d)
}

#[pymethods]
impl Model {
    #[new]
    #[pyo3(signature = (path, *, onnxruntime=None, threads=0))]
    fn new(
        py: Python<'_>,
        path: PathBuf,
        onnxruntime: Option<PathBuf>,
        threads: usize,
    ) -> PyResult<Model> {
        let opts = ModelOptions {
            onnxruntime,
            threads,
            spec: None,
        };
        let inner = py
            .detach(|| RustModel::open(&path, &opts))
            .map_err(py_err)?;
        Ok(Model { inner })
    }

    /// The model file's content hash (`xxh3-128:<hex>`).
    #[getter]
    fn digest(&self) -> String {
        self.inner.digest.clone()
    }

    /// What the model records: map, channels, normalisation, graph names (a dict).
    #[getter]
    fn spec<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let json = serde_json::to_string(&self.inner.spec)
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        py.import("json")?.call_method1("loads", (json,))
    }

    /// A model record alone (the metadata value the export writes: model_metadata's second
    /// item), without a graph: its maps are made and carried back as for the ONNX file, and
    /// another engine runs them (predict's runner=: the trainer's PyTorch network).
    #[staticmethod]
    #[pyo3(signature = (record, *, name="record"))]
    fn from_record(record: &str, name: &str) -> PyResult<Model> {
        let inner = RustModel::of_record(record, Path::new(name)).map_err(py_err)?;
        Ok(Model { inner })
    }

    /// Runs the model on the scan file at `path`, read and projected as `kitti2pgm infer` does:
    /// {"classes": (N,) int16, each point's class in file order (-1: outside the map),
    /// "map": (H, W) uint8, each cell's class}. method: "knn" (default) or "cell"; runner: a
    /// callable run instead of ONNX Runtime, given the (1, H, W, C) float32 input and returning
    /// each cell's class as integers of H x W values.
    #[pyo3(signature = (path, *, method="knn", runner=None))]
    fn predict_file<'py>(
        &self,
        py: Python<'py>,
        path: PathBuf,
        method: &str,
        runner: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let method = named::<MethodKind>("method", method)?.with(KnnParams::default());
        let p = py
            .detach(|| frame::project(&self.inner, &path, None))
            .map_err(py_err)?;
        self.finish(py, &p, &method, runner)
    }

    /// Runs the model on points held in memory, projected as `kitti2pgm infer` projects a scan
    /// file of them (the model's sensor, pose, rows and columns): points (N, 4) float32 x, y, z,
    /// intensity in the scan's frame (as a file stores them; non-finite points get no class);
    /// ring (N,) uint16, the sensor's beam ids where the cloud has them. Returns what
    /// predict_file returns, classes in the order of the points.
    #[pyo3(signature = (points, *, ring=None, method="knn", runner=None))]
    fn predict<'py>(
        &self,
        py: Python<'py>,
        points: &Bound<'py, PyAny>,
        ring: Option<&Bound<'py, PyAny>>,
        method: &str,
        runner: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let method = named::<MethodKind>("method", method)?.with(KnnParams::default());
        let (pts, intensity) = points_arg(points, "points", true)?;
        let ring = ring
            .map(|a| vec_arg::<u16>(a, "ring", pts.len()))
            .transpose()?;
        let intensity = intensity.expect("asked for");
        let p = py
            .detach(|| {
                let scan = Scan::of_columns(pts, intensity, ring);
                frame::project_points(&self.inner, scan, Path::new("points"))
            })
            .map_err(py_err)?;
        self.finish(py, &p, &method, runner)
    }
}

impl Model {
    /// Runs a projected scan (on ONNX Runtime, or `runner`) and carries its classes back.
    fn finish<'py>(
        &self,
        py: Python<'py>,
        p: &frame::Projected,
        method: &Method,
        runner: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let m = &self.inner;
        let input = m.input_of(&p.map).map_err(py_err)?;
        let cells = match runner {
            None => py.detach(|| m.run(&input)).map_err(py_err)?,
            Some(f) => {
                let labels = run_runner(py, f, input, m.input_shape())?;
                m.classes_of(labels).map_err(py_err)?
            }
        };
        let r = py
            .detach(|| frame::carry(m, p, cells, method))
            .map_err(py_err)?;
        let s = &m.spec.map.spec;
        result_dict(py, r, s.rows, s.cols)
    }
}

/// Calls `runner` on the input (1 x H x W x C float32) and takes its result: integers, H x W of
/// them (any shape of that size: (H, W), (1, H, W)); anything else is a ValueError.
fn run_runner<'py>(
    py: Python<'py>,
    runner: &Bound<'py, PyAny>,
    input: Vec<f32>,
    shape: [usize; 4],
) -> PyResult<Vec<i64>> {
    let x = PyArray1::from_vec(py, input).reshape(shape)?;
    let out = runner.call1((x,))?;
    let np = py.import("numpy")?;
    let a = np.call_method1("asarray", (out,))?;
    let kind: String = a.getattr("dtype")?.getattr("kind")?.extract()?;
    let cells = shape[1] * shape[2];
    let size: usize = a.getattr("size")?.extract()?;
    if !(kind == "i" || kind == "u") || size != cells {
        return Err(PyValueError::new_err(format!(
            "runner must return the class of each of the {} x {} cells as integers, got an \
             array of dtype {} and shape {}",
            shape[1],
            shape[2],
            a.getattr("dtype")?.str()?,
            a.getattr("shape")?.str()?
        )));
    }
    let flat = np
        .call_method1("ascontiguousarray", (a.call_method1("reshape", (-1,))?,))?
        .call_method1("astype", ("int64",))?;
    vec_arg::<i64>(&flat, "runner's result", cells)
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(model_metadata, m)?)?;
    m.add_class::<Model>()?;
    m.add("MODEL_METADATA_KEY", kitti2pgm::infer::METADATA_KEY)?;
    Ok(())
}
