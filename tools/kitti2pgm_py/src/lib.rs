//! `import kitti2pgm`: the kitti2pgm library from Python (PyO3 + rust-numpy).
//!
//! A thin layer: every function here converts arrays and options, calls the Rust library
//! (`kitti2pgm::project::project_cloud`, `kitti2pgm::convert::frame::load`, the readers) with the
//! GIL released, and hands the results back as numpy arrays that own the Rust buffers (no copy).
//! Bad arrays (shape, dtype, non-finite values, lengths) raise `ValueError` naming the argument;
//! unreadable files raise `OSError`, malformed ones `ValueError`, naming the file.

mod arrays;
mod bags;
mod dataset;
mod model;
mod readers;
mod unproject;

use numpy::{PyArray1, PyArrayMethods};
use pyo3::exceptions::{PyOSError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use kitti2pgm::project::{
    project_cloud_on, Augment, Cloud, CloudProjection, IntensityKind, MapChoice, MapPreset,
    PgmSpec, RowMode, EMPTY,
};
use kitti2pgm::source::kitti::DatasetKind;

use arrays::{colours_arg, points_arg, vec_arg};

#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

/// The library's error as a Python exception: files that cannot be read are `OSError`,
/// everything else (bad contents, bad arguments) `ValueError`.
pub(crate) fn py_err(e: kitti2pgm::Error) -> PyErr {
    match e {
        kitti2pgm::Error::Io { .. }
        | kitti2pgm::Error::Write { .. }
        | kitti2pgm::Error::NotAFile { .. }
        | kitti2pgm::Error::TooLarge { .. } => PyOSError::new_err(e.to_string()),
        _ => PyValueError::new_err(e.to_string()),
    }
}

/// The map of the keyword arguments: the preset (`layout`'s default, or squeezeseg without a
/// source) with each value given in its place, as `kitti2pgm convert` resolves its options.
pub(crate) fn spec_of(choice: &MapArgs, layout: Option<DatasetKind>) -> PyResult<PgmSpec> {
    let c = MapChoice {
        preset: choice
            .preset
            .as_deref()
            .map(|p| named::<MapPreset>("preset", p))
            .transpose()?,
        rows: choice.rows,
        cols: choice.cols,
        fov_deg: choice.fov_deg,
        fov_up_deg: choice.fov_up_deg,
        fov_down_deg: choice.fov_down_deg,
        row_mode: choice
            .row_mode
            .as_deref()
            .map(|m| named::<RowMode>("row_mode", m))
            .transpose()?,
    };
    let spec = c.spec(layout);
    spec.validate().map_err(py_err)?;
    Ok(spec)
}

/// The map keywords of `project` and `Dataset.project`, as given (`None`: the preset's).
pub(crate) struct MapArgs {
    pub preset: Option<String>,
    pub rows: Option<usize>,
    pub cols: Option<usize>,
    pub fov_deg: Option<f64>,
    pub fov_up_deg: Option<f64>,
    pub fov_down_deg: Option<f64>,
    pub row_mode: Option<String>,
}

/// `kitti2pgm.PRESETS`: every preset's map, by name (the library's table, which the CLI reads
/// too).
fn presets(py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
    let d = PyDict::new(py);
    for &p in MapPreset::ALL {
        let s = p.spec();
        let e = PyDict::new(py);
        e.set_item("rows", s.rows)?;
        e.set_item("cols", s.cols)?;
        e.set_item("fov_deg", s.fov.0)?;
        e.set_item("fov_up_deg", s.fov_up.0)?;
        e.set_item("fov_down_deg", s.fov_down.0)?;
        e.set_item("row_mode", s.row_mode.as_str())?;
        d.set_item(p.as_str(), e)?;
    }
    Ok(d)
}

/// A library enum from its name, as the CLI spells it (`FromStr`: names and aliases); a
/// `ValueError` naming the argument and the names otherwise.
pub(crate) fn named<T: std::str::FromStr<Err = kitti2pgm::Error>>(
    arg: &str,
    value: &str,
) -> PyResult<T> {
    value.parse().map_err(|e: kitti2pgm::Error| {
        let names = match e {
            kitti2pgm::Error::Config(names) => names,
            other => other.to_string(),
        };
        PyValueError::new_err(format!("{arg} must be a known name: {names}"))
    })
}

/// Ring (laser) index of every point of a scan from its order: an (N,) uint8 array, or None
/// when the scan does not show exactly 64 rings (the converter then bins by elevation).
/// `points`: (N, 3+) float32, in the order of the `.bin` file.
#[pyfunction]
fn rings<'py>(
    py: Python<'py>,
    points: &Bound<'py, PyAny>,
) -> PyResult<Option<Bound<'py, PyArray1<u8>>>> {
    let (pts, _) = points_arg(points, "points", false)?;
    let (r, _found) = py.detach(|| kitti2pgm::project::rings(&pts));
    Ok(r.map(|r| PyArray1::from_vec(py, r)))
}

/// Projects a point cloud onto a Polar Grid Map, exactly as `kitti2pgm convert` does.
///
/// points: (N, 4) float32 x, y, z, intensity (velodyne frame, metres), in scan order.
/// preset: "squeezeseg" (the default), "rangenet" or "full" (`kitti2pgm.PRESETS` holds their
/// numbers); rows, cols, fov_deg, fov_up_deg, fov_down_deg, row_mode: single values over it.
/// rings: optional (N,) uint8 beam rows (0 = the highest beam, < beams); default: recovered
/// from the scan order (KITTI), or from `sensor`.
/// beams: the beams `rings` counts (64, KITTI's HDL-64E, by default); with another count the
/// intensity is taken as stored (not KITTI's 0-1 reflectance).
/// sensor: a sensor's beam table, by preset name ("vlp16", "pandar64", ...: `SENSORS`) or
/// calibration file (velodyne .yaml, Hesai .csv, Ouster .json): each point's row is its nearest
/// beam (stats["off_model"] counts the points that fit none), `beams` the table's; with `rings`
/// the table gives only the beam count.
/// sensor_pose: "x,y,z[,roll,pitch,yaw]" (metres, degrees), the sensor's pose in the points'
/// frame (a base_link cloud): the points are moved into the sensor's frame first, and the map's
/// x, y, z are the sensor's (`--sensor-pose`).
/// ouster_columns: with an Ouster metadata file as `sensor`, the columns are Ouster's own
/// (measurement ids, destaggered: the SDK's image), the map its columns per frame over 360
/// degrees (`convert --ouster-columns`); rotate_deg and flip are refused with them.
/// labels: optional (N,) uint8 class ids; instance: optional (N,) uint16.
/// rgb: optional (N, 3) float32 in [0, 1] (adds r, g, b channels); rgb_valid: (N,) bool.
/// rotate_deg, scale, flip, jitter (metres), drop (probability), seed: 3D augmentation applied
/// before projecting (rows stay the rings of the original order; a rotation by k column angles
/// shifts the map by exactly k columns).
/// threads: how many threads one call may use (rayon's pool; default 1, the right choice
/// inside DataLoader workers, which run in parallel already); the same arrays whatever it is.
///
/// Returns a dict: map (H, W, C) float32 with channel names in channels (x y z intensity range
/// label [r g b]), mask (H, W) bool, label (H, W) uint8, instance (H, W) uint16, rgb_valid
/// (H, W) bool or None, row and col (N,) int32 of every point (-1 outside the map or dropped),
/// point_index (H, W) int32 (-1 for empty cells), stats (dict of counts). With
/// point_cells=False, row, col and point_index are None (a little faster, for training).
#[pyfunction]
#[pyo3(signature = (points, *, preset=None, rows=None, cols=None, fov_deg=None, fov_up_deg=None,
    fov_down_deg=None, row_mode=None, rings=None, beams=None, sensor=None, sensor_pose=None,
    ouster_columns=false, labels=None, instance=None, rgb=None, rgb_valid=None, rotate_deg=0.0, scale=1.0, flip=false, jitter=0.0,
    drop=0.0, seed=0, point_cells=true, threads=1),
    text_signature = "(points, *, preset=None, rows=None, cols=None, fov_deg=None, fov_up_deg=None, fov_down_deg=None, row_mode=None, rings=None, beams=None, sensor=None, sensor_pose=None, ouster_columns=False, labels=None, instance=None, rgb=None, rgb_valid=None, rotate_deg=0.0, scale=1.0, flip=False, jitter=0.0, drop=0.0, seed=0, point_cells=True, threads=1)")]
// One Rust argument per Python keyword: the signature is the Python API.
#[allow(clippy::too_many_arguments)]
fn project<'py>(
    py: Python<'py>,
    points: &Bound<'py, PyAny>,
    preset: Option<String>,
    rows: Option<usize>,
    cols: Option<usize>,
    fov_deg: Option<f64>,
    fov_up_deg: Option<f64>,
    fov_down_deg: Option<f64>,
    row_mode: Option<String>,
    rings: Option<&Bound<'py, PyAny>>,
    beams: Option<usize>,
    sensor: Option<String>,
    sensor_pose: Option<String>,
    ouster_columns: bool,
    labels: Option<&Bound<'py, PyAny>>,
    instance: Option<&Bound<'py, PyAny>>,
    rgb: Option<&Bound<'py, PyAny>>,
    rgb_valid: Option<&Bound<'py, PyAny>>,
    rotate_deg: f64,
    scale: f32,
    flip: bool,
    jitter: f32,
    drop: f32,
    seed: u64,
    point_cells: bool,
    threads: usize,
) -> PyResult<Bound<'py, PyDict>> {
    if threads == 0 {
        return Err(PyValueError::new_err("threads must be at least 1"));
    }
    let map = MapArgs {
        preset,
        rows,
        cols,
        fov_deg,
        fov_up_deg,
        fov_down_deg,
        row_mode,
    };
    let (mut pts, intensity) = points_arg(points, "points", true)?;
    let n = pts.len();
    let mut rings = rings.map(|a| vec_arg::<u8>(a, "rings", n)).transpose()?;
    // The sensor as `convert --sensor` resolves it: its beam model, and an Ouster unit's own.
    let params = (sensor.as_deref())
        .map(|s| kitti2pgm::sensor::SensorParams::named_or_file(s, Default::default()))
        .transpose()
        .map_err(py_err)?;
    let model = (params.as_ref())
        .map(kitti2pgm::sensor::SensorParams::model)
        .transpose()
        .map_err(py_err)?;
    let mut off_model = None;
    let beams = match (&model, beams) {
        (Some(m), Some(b)) if b != m.beams() => {
            return Err(PyValueError::new_err(format!(
                "beams={b}, but sensor {} has {} beams",
                m.name,
                m.beams()
            )))
        }
        (Some(m), _) => Some(m.beams()),
        (None, b) => b,
    };
    // A vehicle-frame cloud moved into the sensor's frame first (`--sensor-pose`).
    match (&model, sensor_pose.as_deref()) {
        (Some(_), Some(text)) => {
            let pose = kitti2pgm::sensor::SensorPose::parse(text).map_err(py_err)?;
            py.detach(|| pose.to_sensor_frame(&mut pts));
        }
        (None, Some(_)) => {
            return Err(PyValueError::new_err(
                "sensor_pose needs the sensor (sensor=)",
            ))
        }
        _ => {}
    }
    let own = match (&model, ouster_columns) {
        (_, false) => None,
        (Some(_), true) => Some(
            (params.as_ref().expect("a model has its params"))
                .ouster_model()
                .map_err(py_err)?,
        ),
        (None, true) => {
            return Err(PyValueError::new_err(
                "ouster_columns needs the sensor: sensor=\"<unit's metadata>.json\"",
            ))
        }
    };
    // One row per beam unless rows says otherwise (as `convert --sensor`); Ouster's columns
    // per frame over a full turn (as `convert --ouster-columns`).
    let map = MapArgs {
        rows: map.rows.or(beams),
        cols: map
            .cols
            .or(own.as_ref().map(|f| f.format.columns_per_frame)),
        fov_deg: map.fov_deg.or(own.as_ref().map(|_| 360.0)),
        ..map
    };
    let spec = spec_of(&map, None)?;
    if let (Some(m), None) = (&model, &rings) {
        let assigned = py.detach(|| m.assign(&pts));
        off_model = Some(assigned.off_model);
        rings = Some(assigned.rows);
    }
    let columns = match (own, &rings) {
        (Some(f), Some(r)) => {
            f.check_map(spec.cols, spec.fov).map_err(py_err)?;
            Some(py.detach(|| f.columns(&pts, r)))
        }
        _ => None,
    };
    let labels = labels.map(|a| vec_arg::<u8>(a, "labels", n)).transpose()?;
    let instance = instance
        .map(|a| vec_arg::<u16>(a, "instance", n))
        .transpose()?;
    let colours = rgb.map(|a| colours_arg(a, n)).transpose()?;
    let colour_valid = rgb_valid
        .map(|a| vec_arg::<bool>(a, "rgb_valid", n))
        .transpose()?;
    let augment = Augment {
        rotate: rotate_deg.to_radians(),
        scale,
        flip,
        jitter,
        drop,
        seed,
    };
    let intensity = intensity.expect("asked for");
    let map = py
        .detach(|| {
            let cloud = Cloud {
                points: &pts,
                intensity: &intensity,
                rings: rings.as_deref(),
                beams: beams.unwrap_or(kitti2pgm::project::LASERS),
                columns: columns.as_deref(),
                intensity_kind: match beams {
                    Some(b) if b != kitti2pgm::project::LASERS || model.is_some() => {
                        IntensityKind::AsStored
                    }
                    _ => IntensityKind::Reflectance,
                },
                labels: labels.as_deref(),
                instance: instance.as_deref(),
                colours: colours.as_deref(),
                colour_valid: colour_valid.as_deref(),
            };
            project_cloud_on(&cloud, &spec, Some(&augment), threads)
        })
        .map_err(py_err)?;
    let d = map_dict(py, map, point_cells)?;
    if let Some(off) = off_model {
        d.get_item("stats")?
            .expect("map_dict sets stats")
            .set_item("off_model", off)?;
    }
    Ok(d)
}

/// The dict `project` returns; every array takes over its Rust buffer.
pub(crate) fn map_dict<'py>(
    py: Python<'py>,
    m: CloudProjection,
    point_cells: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let CloudProjection {
        frame,
        point_cell,
        cell_point,
        stats,
        rings_found,
    } = m;
    let (h, w, c) = (frame.rows, frame.cols, frame.depth());
    let d = PyDict::new(py);
    d.set_item(
        "map",
        PyArray1::from_vec(py, frame.data).reshape([h, w, c])?,
    )?;
    d.set_item("channels", frame.channels.names())?;
    // (each conversion below collects in place: the same buffer, no allocation)
    let mask: Vec<bool> = frame.mask.into_iter().map(|v| v != 0).collect();
    d.set_item("mask", PyArray1::from_vec(py, mask).reshape([h, w])?)?;
    d.set_item(
        "label",
        PyArray1::from_vec(py, frame.label).reshape([h, w])?,
    )?;
    d.set_item(
        "instance",
        PyArray1::from_vec(py, frame.instance).reshape([h, w])?,
    )?;
    match frame.rgb_valid {
        Some(v) => {
            let v: Vec<bool> = v.into_iter().map(|b| b != 0).collect();
            d.set_item("rgb_valid", PyArray1::from_vec(py, v).reshape([h, w])?)?
        }
        None => d.set_item("rgb_valid", py.None())?,
    }
    if !point_cells {
        for key in ["row", "col", "point_index"] {
            d.set_item(key, py.None())?;
        }
        return stats_into(py, &d, &stats, rings_found).map(|()| d);
    }
    // `c / w` by a multiplication in double precision (the integer division and remainder of
    // every point were 7% of the call): exact, `(c + 0.5) / w` lying at least `0.5 / w` from an
    // integer, far beyond the product's rounding for cells below 2^32. A map's cells are below
    // 2^28 (4096 x 65536), so a cell is a non-negative i32, whose conversions vectorise (those of
    // a u32 do not with AVX2); EMPTY becomes -1.
    assert!(h * w <= 1 << 28, "a map has at most 2^28 cells");
    let (inv_w, w_i) = (1.0 / w as f64, w as i32);
    let (row, col) = arrays::with_simd(
        #[inline(always)]
        || {
            // (`move`: by reference, the loop reloaded `w` after every store, and ran a value
            // at a time)
            arrays::unzip_map(&point_cell, move |c| {
                let x = (f64::from(c as i32) + 0.5) * inv_w;
                // SAFETY: x is finite and within (-1, 2^28]: it fits an i32.
                let q: i32 = unsafe { x.to_int_unchecked() };
                // (wrapping: an EMPTY cell's quotient is meaningless, and discarded)
                let rem = (c as i32).wrapping_sub(q.wrapping_mul(w_i));
                if c == EMPTY {
                    (-1, -1)
                } else {
                    (q, rem)
                }
            })
        },
    );
    d.set_item("row", PyArray1::from_vec(py, row))?;
    d.set_item("col", PyArray1::from_vec(py, col))?;
    // EMPTY (u32::MAX) is -1 as an i32, the "no point" of the array.
    let index: Vec<i32> = cell_point.into_iter().map(|i| i as i32).collect();
    d.set_item(
        "point_index",
        PyArray1::from_vec(py, index).reshape([h, w])?,
    )?;
    stats_into(py, &d, &stats, rings_found)?;
    Ok(d)
}

/// The projection's counts as `d["stats"]`.
fn stats_into(
    py: Python<'_>,
    d: &Bound<'_, PyDict>,
    stats: &kitti2pgm::project::ProjectionStats,
    rings_found: usize,
) -> PyResult<()> {
    let s = PyDict::new(py);
    s.set_item("in_fov", stats.in_fov)?;
    s.set_item("filled_cells", stats.filled_cells)?;
    s.set_item("collisions", stats.collisions)?;
    s.set_item("ring_fallback", stats.ring_fallbacks > 0)?;
    s.set_item("rings_found", rings_found)?;
    d.set_item("stats", s)
}

/// kitti2pgm's library as a Python module: read KITTI raw, SemanticKITTI and KITTI object
/// frames, label points in boxes, recover laser rings, and project clouds to Polar Grid Maps
/// (optionally augmented in 3D) exactly as `kitti2pgm convert` does.
#[pymodule]
#[pyo3(name = "kitti2pgm")]
fn kitti2pgm_module(m: &Bound<'_, PyModule>) -> PyResult<()> {
    kitti2pgm::alloc::tune_mimalloc();
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("LASERS", kitti2pgm::project::LASERS)?;
    let sensors = PyDict::new(m.py());
    for s in kitti2pgm::sensor::presets::Sensor::ALL {
        sensors.set_item(s.as_str(), s.model_table().beams())?;
    }
    m.add("SENSORS", sensors)?;
    m.add(
        "MAX_RANGE_M",
        kitti2pgm::source::kitti::velodyne::MAX_RANGE_M,
    )?;
    m.add_function(wrap_pyfunction!(project, m)?)?;
    m.add_function(wrap_pyfunction!(rings, m)?)?;
    m.add_function(wrap_pyfunction!(unproject::unproject, m)?)?;
    m.add_function(wrap_pyfunction!(readers::point_prediction_path, m)?)?;
    m.add_function(wrap_pyfunction!(readers::write_point_predictions, m)?)?;
    m.add("PRESETS", presets(m.py())?)?;
    readers::register(m)?;
    bags::register(m)?;
    model::register(m)?;
    m.add_class::<dataset::Dataset>()?;
    m.add_class::<dataset::DatasetIter>()?;
    Ok(())
}
