//! `Model` and `model_metadata`: trained ONNX models from Python, run by the library's
//! `kitti2pgm::infer` (the same projection, engine and kNN as `kitti2pgm infer`).

use std::path::PathBuf;

use numpy::{PyArray1, PyArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use kitti2pgm::infer::frame::ScanResult;
use kitti2pgm::infer::{Model as RustModel, ModelOptions, ModelSpec, Normalisation, SPEC_VERSION};
use kitti2pgm::project::unproject::{KnnParams, MethodKind};
use kitti2pgm::provenance::MapParams;

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

    /// Runs the model on the scan file at `path`, read and projected as `kitti2pgm infer` does:
    /// {"classes": (N,) int16, each point's class in file order (-1: outside the map),
    /// "map": (H, W) uint8, each cell's class}. method: "knn" (default) or "cell".
    #[pyo3(signature = (path, *, method="knn"))]
    fn predict_file<'py>(
        &self,
        py: Python<'py>,
        path: PathBuf,
        method: &str,
    ) -> PyResult<Bound<'py, PyDict>> {
        let method = named::<MethodKind>("method", method)?.with(KnnParams::default());
        let r = py
            .detach(|| kitti2pgm::infer::frame::predict_file(&self.inner, &path, &method))
            .map_err(py_err)?;
        let s = &self.inner.spec.map.spec;
        result_dict(py, r, s.rows, s.cols)
    }
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(model_metadata, m)?)?;
    m.add_class::<Model>()?;
    m.add("MODEL_METADATA_KEY", kitti2pgm::infer::METADATA_KEY)?;
    Ok(())
}
