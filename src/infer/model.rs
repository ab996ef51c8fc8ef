//! INFER: the model file's owner: an ONNX model opened in ONNX Runtime, its recorded
//! [`ModelSpec`] read and checked against its graph, and maps run through it.

use std::path::{Path, PathBuf};
use std::sync::Mutex;

use ort::session::Session;
use ort::value::{TensorElementType, TensorRef, ValueType};

use super::engine;
use super::spec::{ModelSpec, Normalisation, METADATA_KEY};
use crate::error::{Error, Result};
use crate::label::ClassId;
use crate::project::frame::PgmFrame;
use crate::project::Channels;

/// How a model is opened.
#[derive(Debug, Clone, Default)]
pub struct ModelOptions {
    /// ONNX Runtime's library (or its folder); `None`: found as [`engine::find_library`] says.
    pub onnxruntime: Option<PathBuf>,
    /// Threads ONNX Runtime runs one map on (0: its default, every core).
    pub threads: usize,
    /// The spec to use for a model that records none (someone else's ONNX); a model that
    /// records one must agree with it.
    pub spec: Option<ModelSpec>,
}

/// An opened model.
pub struct Model {
    /// The file.
    pub path: PathBuf,
    /// The file's content hash (`xxh3-128:<hex>`): what the outputs name.
    pub digest: String,
    /// What it is fed and what it returns.
    pub spec: ModelSpec,
    /// Whether the spec was recorded in the file (else given by the user).
    pub recorded: bool,
    /// The threads ONNX Runtime runs one map on (0: one per core).
    pub threads: usize,
    /// The library ONNX Runtime was loaded from (`None`: a record without a graph, whose maps
    /// another engine runs: [`Model::of_record`]).
    pub runtime: Option<PathBuf>,
    channels: Channels,
    session: Option<Mutex<Session>>,
}

impl std::fmt::Debug for Model {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Model")
            .field("path", &self.path)
            .field("digest", &self.digest)
            .finish()
    }
}

/// The dimensions of a graph value of `name` (`-1`: not fixed) and its element type.
fn outlet(session: &Session, name: &str, input: bool) -> Option<(Vec<i64>, TensorElementType)> {
    let list = if input {
        session.inputs()
    } else {
        session.outputs()
    };
    let o = list.iter().find(|o| o.name() == name)?;
    match o.dtype() {
        ValueType::Tensor { ty, shape, .. } => Some((shape.iter().copied().collect(), *ty)),
        _ => None,
    }
}

/// A given spec with the graph's names filled in where it leaves them empty: the input is the
/// graph's only input; the labels the first integer output, the logits the first float one.
fn resolve_names(path: &Path, session: &Session, mut spec: ModelSpec) -> Result<ModelSpec> {
    if spec.input.is_empty() {
        match session.inputs() {
            [one] => spec.input = one.name().to_string(),
            more => {
                return Err(Error::format(
                    path,
                    format!("{} inputs; kitti2pgm feeds a model one map", more.len()),
                ))
            }
        }
    }
    if spec.labels_output.is_none() && spec.logits_output.is_none() {
        for o in session.outputs() {
            let ty = o.dtype().tensor_type();
            if matches!(
                ty,
                Some(TensorElementType::Int64 | TensorElementType::Int32)
            ) {
                spec.labels_output
                    .get_or_insert_with(|| o.name().to_string());
            } else if ty == Some(TensorElementType::Float32) {
                spec.logits_output
                    .get_or_insert_with(|| o.name().to_string());
            }
        }
    }
    Ok(spec)
}

/// Whether graph dimensions `dims` (`-1` free) admit `want`.
fn fits(dims: &[i64], want: &[usize]) -> bool {
    dims.len() == want.len() && dims.iter().zip(want).all(|(&d, &w)| d < 0 || d == w as i64)
}

impl Model {
    /// Opens the model at `path`: loads ONNX Runtime, reads the spec it records (or takes the
    /// one given), and checks the graph's input and outputs against the spec's map.
    pub fn open(path: &Path, opts: &ModelOptions) -> Result<Model> {
        let bytes = crate::fs::read(path, crate::fs::Limit::Data)?;
        let digest = format!("xxh3-128:{:032x}", xxhash_rust::xxh3::xxh3_128(&bytes));
        let rt = engine::runtime(opts.onnxruntime.as_deref())?;
        let not_model = |e: ort::Error| Error::NotFormat {
            path: path.into(),
            format: "an ONNX model",
            detail: e.to_string(),
        };
        let mut builder = ort::session::Session::builder(&rt.env).map_err(not_model)?;
        if opts.threads > 0 {
            builder = builder
                .with_intra_threads(opts.threads)
                .map_err(|e| not_model(e.into()))?;
        }
        let session = builder.commit_from_memory(&bytes).map_err(not_model)?;
        let recorded = session
            .metadata()
            .map_err(not_model)?
            .custom(METADATA_KEY)
            .map(|v| ModelSpec::from_metadata(&v, path))
            .transpose()?;
        let (spec, is_recorded) = match (recorded, &opts.spec) {
            (Some(r), Some(given)) if r.map != given.map => {
                return Err(Error::Config(format!(
                    "{} records its own map ({} x {}, class map {:?}); the map options given \
                     ({} x {}, class map {:?}) disagree: leave them out",
                    path.display(),
                    r.map.spec.rows,
                    r.map.spec.cols,
                    r.map.class_map.name,
                    given.map.spec.rows,
                    given.map.spec.cols,
                    given.map.class_map.name
                )))
            }
            (Some(r), _) => (r, true),
            (None, Some(given)) => {
                let spec = resolve_names(path, &session, given.clone())?;
                spec.validate()?;
                (spec, false)
            }
            (None, None) => {
                return Err(Error::Config(format!(
                    "{} records no kitti2pgm map ({METADATA_KEY} metadata: it was not exported \
                     by kitti2pgm_train): give the map it was trained on with --map-from \
                     (a conversion's output folder)",
                    path.display()
                )))
            }
        };
        let channels = spec.input_channels()?;
        check_graph(path, &session, &spec, &channels)?;
        Ok(Model {
            path: path.into(),
            digest,
            spec,
            recorded: is_recorded,
            threads: opts.threads,
            runtime: Some(rt.library.clone()),
            channels,
            session: Some(Mutex::new(session)),
        })
    }

    /// The record alone (the metadata value an export writes, [`ModelSpec::from_metadata`]):
    /// maps made and carried back as for its ONNX file, run by another engine (the trainer's
    /// PyTorch network); `name` names it in errors. [`Model::run`] is an error.
    pub fn of_record(value: &str, name: &Path) -> Result<Model> {
        let spec = ModelSpec::from_metadata(value, name)?;
        let channels = spec.input_channels()?;
        Ok(Model {
            path: name.into(),
            digest: format!(
                "xxh3-128:{:032x}",
                xxhash_rust::xxh3::xxh3_128(value.as_bytes())
            ),
            spec,
            recorded: true,
            threads: 0,
            runtime: None,
            channels,
            session: None,
        })
    }

    /// The shape of the model's input: 1 x rows x cols x channels.
    pub fn input_shape(&self) -> [usize; 4] {
        let spec = &self.spec.map.spec;
        [1, spec.rows, spec.cols, self.channels.len()]
    }

    /// The model's input for `frame` (a map made with the spec's parameters): its channels in
    /// the spec's order, normalised as the spec says.
    pub fn input_of(&self, frame: &PgmFrame) -> Result<Vec<f32>> {
        let index: Vec<usize> = self
            .channels
            .0
            .iter()
            .map(|&c| {
                frame.channels.index(c).ok_or_else(|| {
                    Error::Config(format!(
                        "the map has no {} channel, which the model takes",
                        c.as_str()
                    ))
                })
            })
            .collect::<Result<_>>()?;
        let depth = frame.depth();
        let mut out = Vec::with_capacity(frame.cells() * index.len());
        for cell in frame.data.chunks_exact(depth) {
            out.extend(index.iter().map(|&i| cell[i]));
        }
        if let Normalisation::PerChannel { mean, std } = &self.spec.normalisation {
            let k = index.len();
            for (cell, &m) in out.chunks_exact_mut(k).zip(&frame.mask) {
                for (j, v) in cell.iter_mut().enumerate() {
                    *v = if m != 0 { (*v - mean[j]) / std[j] } else { 0.0 };
                }
            }
        }
        Ok(out)
    }

    /// Runs the model on one input ([`Model::input_of`]): the class of every cell, row-major.
    /// Runs are serialised (ONNX Runtime spreads one run over its threads).
    pub fn run(&self, input: &[f32]) -> Result<Vec<ClassId>> {
        self.run_timed(input).map(|(classes, _)| classes)
    }

    /// [`Model::run`], and the time the engine took (waiting for another frame's run left out).
    pub fn run_timed(&self, input: &[f32]) -> Result<(Vec<ClassId>, std::time::Duration)> {
        let spec = &self.spec.map.spec;
        let shape = self.input_shape();
        let fail = |e: ort::Error| Error::format(&self.path, format!("running it: {e}"));
        let Some(session) = &self.session else {
            return Err(Error::Config(format!(
                "{}: a model record without its graph: run its maps with the engine it was \
                 opened for",
                self.path.display()
            )));
        };
        let tensor = TensorRef::from_array_view((shape, input)).map_err(fail)?;
        let mut session = session.lock().unwrap_or_else(|p| p.into_inner());
        let started = std::time::Instant::now();
        let inputs = ort::inputs![self.spec.input.as_str() => tensor];
        let outputs = session.run(inputs).map_err(fail)?;
        let took = started.elapsed();
        let classes = self.spec.map.class_map.len();
        let cells = spec.rows * spec.cols;
        if let Some(name) = &self.spec.labels_output {
            let value = &outputs[name.as_str()];
            let labels: Vec<i64> = match value.try_extract_tensor::<i64>() {
                Ok((_, v)) => v.to_vec(),
                Err(_) => {
                    let (_, v) = value.try_extract_tensor::<i32>().map_err(fail)?;
                    v.iter().map(|&x| x as i64).collect()
                }
            };
            return Ok((self.checked(labels, cells, classes)?, took));
        }
        let name = self.spec.logits_output.as_deref().expect("validated");
        let (_, logits) = outputs[name].try_extract_tensor::<f32>().map_err(fail)?;
        Ok((argmax(logits, classes, cells), took))
    }

    /// The class of every cell given by another engine (`labels`, row-major), checked: one a
    /// cell, each one of the class map's.
    pub fn classes_of(&self, labels: Vec<i64>) -> Result<Vec<ClassId>> {
        let spec = &self.spec.map.spec;
        self.checked(labels, spec.rows * spec.cols, self.spec.map.class_map.len())
    }

    /// `labels` as class ids, each checked to be one of the map's classes.
    fn checked(&self, labels: Vec<i64>, cells: usize, classes: usize) -> Result<Vec<ClassId>> {
        if labels.len() != cells {
            let n = labels.len();
            let message = format!("{n} labels out, the map has {cells} cells");
            return Err(Error::format(&self.path, message));
        }
        if let Some(i) = labels.iter().position(|&l| l < 0 || l as usize >= classes) {
            let message = format!(
                "cell {i} is given class {}, the class map {:?} has {classes}",
                labels[i], self.spec.map.class_map.name
            );
            return Err(Error::format(&self.path, message));
        }
        Ok(labels.into_iter().map(|l| l as ClassId).collect())
    }
}

/// The class of highest score in every cell of `K x cells` scores (the first on ties, as
/// numpy's and torch's argmax).
fn argmax(logits: &[f32], classes: usize, cells: usize) -> Vec<ClassId> {
    let mut best = vec![0 as ClassId; cells];
    let mut top: Vec<f32> = logits[..cells].to_vec();
    for k in 1..classes {
        let plane = &logits[k * cells..(k + 1) * cells];
        for ((b, t), &v) in best.iter_mut().zip(top.iter_mut()).zip(plane) {
            if v > *t {
                *t = v;
                *b = k as ClassId;
            }
        }
    }
    best
}

/// The graph's input and outputs against the spec: the input 1 x rows x cols x channels
/// float32, the labels 1 x rows x cols integers, the logits 1 x classes x rows x cols float32.
fn check_graph(path: &Path, session: &Session, spec: &ModelSpec, ch: &Channels) -> Result<()> {
    let (rows, cols) = (spec.map.spec.rows, spec.map.spec.cols);
    let k = spec.map.class_map.len();
    let bad = |message: String| Error::format(path, message);
    let shape_err = |what: String, found: &[i64], expected: String| {
        bad(format!(
            "{what} is {found:?}, but its recorded map wants {expected} ({rows} x {cols} map, \
             channels {}, {k} classes)",
            ch.names().join(" ")
        ))
    };
    let names = |input: bool| {
        let l = if input {
            session.inputs()
        } else {
            session.outputs()
        };
        l.iter().map(|o| o.name().to_string()).collect::<Vec<_>>()
    };
    let Some((dims, ty)) = outlet(session, &spec.input, true) else {
        return Err(bad(format!(
            "the graph has no tensor input {:?} (its inputs: {:?})",
            spec.input,
            names(true)
        )));
    };
    if ty != TensorElementType::Float32 || !fits(&dims, &[1, rows, cols, ch.len()]) {
        return Err(shape_err(
            format!("the input {:?} ({ty:?})", spec.input),
            &dims,
            format!("float32 [1, {rows}, {cols}, {}]", ch.len()),
        ));
    }
    for (name, want, float) in [
        (&spec.labels_output, vec![1, rows, cols], false),
        (&spec.logits_output, vec![1, k, rows, cols], true),
    ] {
        let Some(name) = name else { continue };
        let Some((dims, ty)) = outlet(session, name, false) else {
            return Err(bad(format!(
                "the graph has no tensor output {name:?} (its outputs: {:?})",
                names(false)
            )));
        };
        let ty_ok = if float {
            ty == TensorElementType::Float32
        } else {
            matches!(ty, TensorElementType::Int64 | TensorElementType::Int32)
        };
        if !ty_ok || !fits(&dims, &want) {
            return Err(shape_err(
                format!("the output {name:?} ({ty:?})"),
                &dims,
                format!("{want:?}"),
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn argmax_takes_the_first_of_equal_scores() {
        // 2 cells, 3 classes, class-major as the logits output is.
        let logits = [1.0, 5.0, 3.0, 5.0, 3.0, 2.0];
        assert_eq!(argmax(&logits, 3, 2), vec![1, 0]);
    }

    #[test]
    fn free_dimensions_fit_any_size() {
        assert!(fits(&[1, -1, 512, 5], &[1, 64, 512, 5]));
        assert!(!fits(&[1, 64, 512, 5], &[1, 64, 512, 8]));
        assert!(!fits(&[64, 512, 5], &[1, 64, 512, 5]));
    }
}
