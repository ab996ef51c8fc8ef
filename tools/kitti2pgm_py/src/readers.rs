//! The readers: scans, per-point labels, calibrations, tracklets, object labels, class maps,
//! and labelling points in boxes. Structured values (tracklets, class maps) cross as the
//! library's own serde serialisation, parsed into Python dicts.

use std::path::PathBuf;

use numpy::{PyArray1, PyArray2, PyArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use kitti2pgm::geom::{na, Matrix3x4, Real};
use kitti2pgm::label::{ClassMap, LabelBox, Labeller, TypeRule};
use kitti2pgm::source::boxes::{BoxConvention, BoxRotation};
use kitti2pgm::source::kitti::calib::{Calibration, FrameCalib};
use kitti2pgm::source::Scan;

use crate::arrays::points_arg;
use crate::py_err;

/// A serde value as Python objects (through `json.loads`).
pub(crate) fn to_py<'py, T: serde::Serialize>(
    py: Python<'py>,
    v: &T,
) -> PyResult<Bound<'py, PyAny>> {
    let text = serde_json::to_string(v).map_err(|e| PyValueError::new_err(e.to_string()))?;
    py.import("json")?.call_method1("loads", (text,))
}

/// A 3x4 or 4x4 matrix as a float64 numpy array.
fn matrix<'py, R: na::Dim, C: na::Dim, S: na::RawStorage<f64, R, C>>(
    py: Python<'py>,
    m: &na::Matrix<f64, R, C, S>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let rows: Vec<Vec<f64>> = (0..m.nrows())
        .map(|r| (0..m.ncols()).map(|c| m[(r, c)]).collect())
        .collect();
    Ok(PyArray2::from_vec2(py, &rows)?)
}

/// Reads a point cloud of any spinning LiDAR: a PCD file (ascii, binary, binary_compressed),
/// nuScenes' `.pcd.bin`, or a flat `.bin` of the declared `fields` (e.g.
/// "x,y,z,intensity,ring:f32"; KITTI's x, y, z, reflectance float32 by default, with KITTI's
/// rule: a reflectance outside 0-1 is a corrupt point, dropped as the converter drops it).
///
/// Returns a dict: points (N, 4) float32 x, y, z, intensity (as stored; 0 where the file has
/// no intensity), ring (N,) uint16 or None (the ring / channel / laser id field), file_index
/// (N,) uint32 (the index in the file of each kept point), file_points, dropped (points with a
/// non-finite value or beyond MAX_RANGE_M), trailing_bytes (bytes after a binary PCD's
/// declared points, left unread).
#[pyfunction]
#[pyo3(signature = (path, *, fields=None))]
fn read_cloud<'py>(
    py: Python<'py>,
    path: PathBuf,
    fields: Option<String>,
) -> PyResult<Bound<'py, PyDict>> {
    let layout = fields
        .map(|f| kitti2pgm::source::PointLayout::declared(&f))
        .transpose()
        .map_err(py_err)?;
    let mut scan = py
        .detach(|| kitti2pgm::source::read_file(&path, layout.as_ref()))
        .map_err(py_err)?;
    let (trailing, ring) = (scan.trailing_bytes, scan.ring.take());
    let d = PyDict::new(py);
    d.set_item("points", scan_array(py, &scan)?)?;
    d.set_item("ring", ring.map(|r| PyArray1::from_vec(py, r)))?;
    d.set_item("file_index", PyArray1::from_vec(py, scan.file_indices()))?;
    d.set_item("file_points", scan.file_len)?;
    d.set_item("dropped", scan.dropped.len())?;
    d.set_item("trailing_bytes", trailing)?;
    Ok(d)
}

/// Reads a velodyne `.bin`: its points as an (N, 4) float32 array (x, y, z, intensity), without
/// the non-finite points and those beyond MAX_RANGE_M (as the converter reads them). With
/// `with_file_index`, also the index in the file of each point ((N,) uint32), to line up
/// per-point files such as SemanticKITTI `.label`.
#[pyfunction]
#[pyo3(signature = (path, *, with_file_index=false))]
fn read_scan<'py>(
    py: Python<'py>,
    path: PathBuf,
    with_file_index: bool,
) -> PyResult<Bound<'py, PyAny>> {
    let scan = py.detach(|| Scan::read(&path)).map_err(py_err)?;
    let index = with_file_index.then(|| scan.file_indices());
    let pts = scan_array(py, &scan)?.into_any();
    match index {
        Some(i) => Ok((pts, PyArray1::from_vec(py, i))
            .into_pyobject(py)?
            .into_any()),
        None => Ok(pts),
    }
}

/// A scan's points as an (N, 4) float32 array: x, y, z, intensity.
pub(crate) fn scan_array<'py>(py: Python<'py>, scan: &Scan) -> PyResult<Bound<'py, PyArray2<f32>>> {
    let flat: Vec<f32> = scan
        .points
        .iter()
        .zip(&scan.intensity)
        .flat_map(|(p, &r)| [p.x, p.y, p.z, r])
        .collect();
    PyArray1::from_vec(py, flat).reshape([scan.len(), 4])
}

/// Reads a per-point `.label` file (SemanticKITTI): one uint32 per point of the `.bin`, the
/// class in the low 16 bits and the instance in the high 16.
#[pyfunction]
fn read_point_labels<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyArray1<u32>>> {
    let v = py
        .detach(|| kitti2pgm::format::label_file::read_raw(&path))
        .map_err(py_err)?;
    Ok(PyArray1::from_vec(py, v))
}

/// Reads a KITTI raw date folder's calibration (calib_cam_to_cam.txt, calib_velo_to_cam.txt):
/// a dict of float64 matrices: velo_to_cam (4x4), R_rect_00 (4x4), P_rect (list of four 3x4),
/// velo_to_image (list of four 3x4: P_rect_0c * R_rect_00 * velo_to_cam).
#[pyfunction]
fn read_calibration<'py>(py: Python<'py>, date_dir: PathBuf) -> PyResult<Bound<'py, PyDict>> {
    let c = Calibration::read_dir(&date_dir).map_err(py_err)?;
    let d = PyDict::new(py);
    d.set_item(
        "velo_to_cam",
        matrix(py, &c.velo_to_cam.velo_to_cam.to_homogeneous())?,
    )?;
    d.set_item("R_rect_00", matrix(py, &c.cam_to_cam.rect_00())?)?;
    let p: Vec<_> = (0..4)
        .map(|k| matrix(py, &c.cam_to_cam.cameras[k].p_rect))
        .collect::<PyResult<_>>()?;
    d.set_item("P_rect", p)?;
    let v: Vec<_> = (0..4)
        .map(|k| matrix(py, &c.velo_to_image(k)))
        .collect::<PyResult<_>>()?;
    d.set_item("velo_to_image", v)?;
    Ok(d)
}

/// Reads a SemanticKITTI / odometry `calib.txt` or a KITTI object `calib/<frame>.txt`: a dict
/// of float64 matrices: P (four 3x4), R0_rect (3x3), Tr_velo_to_cam (3x4), velo_to_rect (4x4),
/// velo_to_image (four 3x4).
#[pyfunction]
fn read_frame_calibration<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyDict>> {
    let c = FrameCalib::read(&path).map_err(py_err)?;
    let d = PyDict::new(py);
    let p: Vec<_> = c.p.iter().map(|m| matrix(py, m)).collect::<PyResult<_>>()?;
    d.set_item("P", p)?;
    d.set_item("R0_rect", matrix(py, &c.r0_rect)?)?;
    d.set_item("Tr_velo_to_cam", matrix(py, &c.velo_to_cam)?)?;
    d.set_item("velo_to_rect", matrix(py, &c.velo_to_rect())?)?;
    let v: Vec<Matrix3x4> = (0..4).map(|k| c.velo_to_image(k)).collect();
    let v: Vec<_> = v.iter().map(|m| matrix(py, m)).collect::<PyResult<_>>()?;
    d.set_item("velo_to_image", v)?;
    Ok(d)
}

/// Reads a `tracklet_labels.xml`: a list of tracklet dicts (object_type, h, w, l, first_frame,
/// poses with t, r, state, occlusion, truncation, ...).
#[pyfunction]
fn read_tracklets<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyAny>> {
    let t = py
        .detach(|| kitti2pgm::source::kitti::tracklets::Tracklets::read(&path))
        .map_err(py_err)?;
    to_py(py, &t.tracklets)
}

/// Reads a KITTI object `label_2/<frame>.txt`: a list of dicts (type, hwl, location,
/// rotation_y), in the rectified camera 0 frame as written.
#[pyfunction]
fn read_object_labels<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyList>> {
    let objs = kitti2pgm::source::kitti::object::read(&path).map_err(py_err)?;
    let out = PyList::empty(py);
    for o in objs {
        let d = PyDict::new(py);
        d.set_item("type", &o.kind)?;
        d.set_item("hwl", o.hwl.to_vec())?;
        d.set_item("location", o.location.coords.as_slice().to_vec())?;
        d.set_item("rotation_y", o.rotation_y)?;
        out.append(d)?;
    }
    Ok(out)
}

/// A class map as a dict (name, classes with name and colour, background, ignore, miou,
/// object_types, learning_map, ...): "kitti-paper-4" (the name outputs record; also
/// "kitti-paper": background, car, pedestrian, cyclist), "semantic-kitti" (the 20 training
/// classes), or a SemanticKITTI-style yaml file.
#[pyfunction]
#[pyo3(signature = (name="kitti-paper-4"))]
fn class_map<'py>(py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyAny>> {
    to_py(py, &class_map_of(name)?)
}

/// The class map of a name or yaml path.
pub(crate) fn class_map_of(name: &str) -> PyResult<ClassMap> {
    ClassMap::named_or_file(std::path::Path::new(name)).map_err(py_err)
}

/// A box dict as the library's box ([`BoxConvention::CENTRED_LWH`]): centre (3), size (l, w, h:
/// full extents along the box's x, y, z), rotation (3x3, box to velodyne) or yaw (radians about
/// z), class, instance.
fn box_of(
    d: &Bound<'_, PyAny>,
    index: usize,
    classes: Option<&TypeRule>,
    margin: f64,
) -> PyResult<LabelBox> {
    let get = |k: &str| d.get_item(k);
    let err = |what: &str| PyValueError::new_err(format!("box {index}: {what}"));
    let centre: Vec<f64> = get("centre").map_err(|_| err("no 'centre'"))?.extract()?;
    let size: Vec<f64> = get("size")
        .map_err(|_| err("no 'size' (l, w, h)"))?
        .extract()?;
    if centre.len() != 3 || size.len() != 3 {
        return Err(err("centre and size need 3 values each"));
    }
    // Finite in single precision, the labeller's (1e39 overflows f32 to inf).
    let f32_finite = |v: &f64| (*v as Real).is_finite();
    if !centre.iter().all(f32_finite) {
        return Err(err("centre must be finite (in float32)"));
    }
    kitti2pgm::geom::check_box_extents(&[size[0], size[1], size[2]], ["l", "w", "h"])
        .map_err(|m| err(&m))?;
    let rotation = match get("rotation") {
        Ok(r) => {
            let m: Vec<Vec<f64>> = r.extract()?;
            if m.len() != 3 || m.iter().any(|row| row.len() != 3) {
                return Err(err("rotation must be 3x3"));
            }
            let m = na::Matrix3::from_fn(|r, c| m[r][c]);
            kitti2pgm::geom::check_rotation(&m).map_err(|e| err(&format!("rotation {e}")))?;
            BoxRotation::Matrix(m)
        }
        Err(_) => {
            let yaw: f64 = get("yaw")
                .map_err(|_| err("no 'rotation' or 'yaw'"))?
                .extract()?;
            if !yaw.is_finite() {
                return Err(err(&format!("yaw must be finite, not {yaw}")));
            }
            BoxRotation::Yaw(yaw)
        }
    };
    let class: u8 = match (get("class"), classes) {
        (Ok(c), _) => c.extract()?,
        (Err(_), Some(classes)) => {
            let name: String = get("class_name")
                .map_err(|_| err("no 'class' or 'class_name'"))?
                .extract()?;
            let known = classes.class_of(&name).map(|(c, _)| c);
            known.ok_or_else(|| {
                PyValueError::new_err(format!(
                    "object type {name:?} is not one the class map {} knows ({}): pass unknown_class=",
                    classes.map.name,
                    classes.map.object_types.keys().cloned().collect::<Vec<_>>().join(", ")
                ))
            })?
        }
        (Err(_), None) => return Err(err("no 'class' (or 'class_name' with class_map=)")),
    };
    // The instance given, else the track's (`read_boxes`: track + 1, as `kitti2pgm label`
    // numbers a fresh sequence's tracks), else the box's place + 1.
    let instance: u16 = match (get("instance"), get("track")) {
        (Ok(v), _) => v.extract()?,
        (Err(_), Ok(t)) => kitti2pgm::label::instance_of(t.extract()?),
        _ => u16::try_from(index + 1).unwrap_or(u16::MAX),
    };
    let mut geometry = BoxConvention::CENTRED_LWH.place(
        [centre[0], centre[1], centre[2]],
        [size[0], size[1], size[2]],
        &rotation,
        None,
    );
    geometry.half_extents.add_scalar_mut(margin as Real);
    Ok(LabelBox::of(&geometry, class, instance))
}

/// Reads a box annotation export (format: "cvat-kitti-raw", "supervisely", "sustechpoints",
/// "labelcloud", "segments-ai", "xtreme1" or "openlabel"; for CVAT's, origin="centre"|"bottom" and sizes="datumaro"|"kitti", its
/// defaults centre and datumaro; for labelCloud's, angles="degrees"|"radians", degrees;
/// sensor_pose="x,y,z[,roll,pitch,yaw]" for boxes drawn in a vehicle frame, as --sensor-pose): a dict with format, tracks (the tool's id of every track, by track index) and
/// frames ({scan name: {"file": path, "boxes": [box dicts]}}), each box with class_name (as the
/// file writes it), track, centre, size (full x, y, z extents) and rotation (3x3, box to scan):
/// the form `label_points` takes once a "class" is set.
#[pyfunction]
#[pyo3(signature = (path, format, *, origin=None, sizes=None, angles=None, sensor_pose=None))]
fn read_boxes<'py>(
    py: Python<'py>,
    path: PathBuf,
    format: &str,
    origin: Option<&str>,
    sizes: Option<&str>,
    angles: Option<&str>,
    sensor_pose: Option<&str>,
) -> PyResult<Bound<'py, PyDict>> {
    use kitti2pgm::source::annotations::{self, AngleUnit, BoxFormat, CvatSizes};
    use kitti2pgm::source::boxes::BoxOrigin;
    let format = crate::named::<BoxFormat>("format", format)?;
    let origin = origin
        .map(|s| crate::named::<BoxOrigin>("origin", s))
        .transpose()?;
    let sizes = sizes
        .map(|s| crate::named::<CvatSizes>("sizes", s))
        .transpose()?;
    let angles = angles
        .map(|s| crate::named::<AngleUnit>("angles", s))
        .transpose()?;
    let sensor_pose = sensor_pose
        .map(kitti2pgm::sensor::SensorPose::parse)
        .transpose()
        .map_err(py_err)?;
    let opts = kitti2pgm::format::box_labels::read_options(origin, sizes, angles, sensor_pose);
    let a = py
        .detach(|| annotations::read(&path, format, &opts))
        .map_err(py_err)?;
    let frames = PyDict::new(py);
    for (scan, f) in &a.frames {
        let boxes = PyList::empty(py);
        for b in &f.boxes {
            let d = PyDict::new(py);
            set_geometry(&d, &b.geometry.pose, &b.geometry.half_extents)?;
            d.set_item("class_name", &b.class_name)?;
            d.set_item("track", b.track)?;
            boxes.append(d)?;
        }
        let fd = PyDict::new(py);
        fd.set_item("file", f.file.to_string_lossy())?;
        fd.set_item("boxes", boxes)?;
        frames.set_item(scan, fd)?;
    }
    let d = PyDict::new(py);
    d.set_item("format", a.format.as_str())?;
    d.set_item("tracks", &a.tracks)?;
    d.set_item("frames", frames)?;
    Ok(d)
}

/// A box as a dict (the form `label_points` takes).
pub(crate) fn box_dict<'py>(py: Python<'py>, b: &LabelBox) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("class", b.class)?;
    d.set_item("instance", b.instance)?;
    set_geometry(&d, &b.pose, &b.cuboid.half_extents)?;
    Ok(d)
}

/// A box's centre, size (full extents) and rotation (3x3, box to scan) as `d`'s items.
fn set_geometry(
    d: &Bound<'_, PyDict>,
    pose: &kitti2pgm::geom::Iso3,
    half: &kitti2pgm::geom::Vector3,
) -> PyResult<()> {
    let t = pose.translation.vector;
    let r = pose.rotation.to_rotation_matrix();
    let m: Vec<Vec<f64>> = (0..3)
        .map(|i| (0..3).map(|j| r[(i, j)] as f64).collect())
        .collect();
    d.set_item("centre", vec![t.x as f64, t.y as f64, t.z as f64])?;
    d.set_item(
        "size",
        vec![
            2.0 * half.x as f64,
            2.0 * half.y as f64,
            2.0 * half.z as f64,
        ],
    )?;
    d.set_item("rotation", m)
}

/// Class and instance arrays.
type Labels<'py> = (Bound<'py, PyArray1<u8>>, Bound<'py, PyArray1<u16>>);

/// Labels points by the boxes that hold them (parry containment; a point in several boxes
/// takes the smallest box's class), as `kitti2pgm label` does. `boxes`: dicts with centre, size
/// (l, w, h), rotation (3x3) or yaw, and class (an id) or, with `class_map` (a built-in name or
/// a YAML file), class_name (the annotation's type, as `read_boxes` gives it: an unknown type is
/// an error unless `unknown_class` names a class); instance, else track + 1, else position + 1;
/// `margin` metres added to every side. Returns (class (N,) uint8, instance (N,) uint16);
/// points in no box get `background` (the class map's, with one).
#[pyfunction]
#[pyo3(signature = (points, boxes, *, background=0, class_map=None, unknown_class=None, margin=0.0))]
fn label_points<'py>(
    py: Python<'py>,
    points: &Bound<'py, PyAny>,
    boxes: &Bound<'py, PyAny>,
    background: u8,
    class_map: Option<&str>,
    unknown_class: Option<&str>,
    margin: f64,
) -> PyResult<Labels<'py>> {
    let (pts, _) = points_arg(points, "points", false)?;
    if !(0.0..=1.0).contains(&margin) {
        return Err(PyValueError::new_err(format!(
            "margin must be 0 to 1 metre, not {margin}"
        )));
    }
    let map = class_map.map(class_map_of).transpose()?;
    let classes = (map.as_ref())
        .map(|m| TypeRule::new(m, unknown_class))
        .transpose()
        .map_err(py_err)?;
    let background = classes.as_ref().map_or(background, |c| c.map.background);
    let boxes: Vec<LabelBox> = boxes
        .try_iter()?
        .enumerate()
        .map(|(i, b)| box_of(&b?, i, classes.as_ref(), margin))
        .collect::<PyResult<_>>()?;
    let labels = py.detach(|| Labeller::new(&boxes, background).label(&pts));
    Ok((
        PyArray1::from_vec(py, labels.class),
        PyArray1::from_vec(py, labels.instance),
    ))
}

/// A frame id from its string (`2011_09_26_0001_0000000010`, `00_000000`, `000042`).
fn frame_id(frame: &str) -> PyResult<kitti2pgm::source::kitti::FrameId> {
    frame
        .parse()
        .map_err(|e: kitti2pgm::error::NotAFrameId| PyValueError::new_err(e.to_string()))
}

/// Where `kitti2pgm unproject` writes a frame's per-point predictions under `out`:
/// `out/sequences/<NN>/predictions/<frame6>.label` for SemanticKITTI (the benchmark's layout),
/// `out/labels/<drive>/<frame>.label` otherwise.
#[pyfunction]
pub fn point_prediction_path(out: PathBuf, frame: &str) -> PyResult<PathBuf> {
    Ok(kitti2pgm::format::layout::point_prediction_path(
        &out,
        &frame_id(frame)?,
    ))
}

/// Writes a frame's per-point predictions as `kitti2pgm unproject` does (atomically, at
/// `point_prediction_path(out, frame)`): classes is (N,) integers, one per point of the scan
/// file in its order, each a class id of `class_map` or negative for a point without a
/// prediction; SemanticKITTI frames get the dataset's raw ids (0 without a prediction), others
/// class ids (0xFFFF without). Returns (the file, the points without a prediction).
#[pyfunction]
#[pyo3(signature = (out, frame, classes, *, class_map))]
pub fn write_point_predictions(
    py: Python<'_>,
    out: PathBuf,
    frame: &str,
    classes: &Bound<'_, PyAny>,
    class_map: &str,
) -> PyResult<(PathBuf, u64)> {
    let id = frame_id(frame)?;
    let map = class_map_of(class_map)?;
    let v = crate::arrays::list_arg::<i64>(classes, "classes")?;
    let per_point = v
        .iter()
        .enumerate()
        .map(|(i, &c)| match c {
            c if c < 0 => Ok(None),
            c if (c as usize) < map.len() => Ok(Some(c as kitti2pgm::label::ClassId)),
            c => Err(PyValueError::new_err(format!(
                "classes: point {i} has class {c}, not a class id of {} (0-{})",
                map.name,
                map.len() - 1
            ))),
        })
        .collect::<PyResult<Vec<_>>>()?;
    py.detach(|| {
        kitti2pgm::format::label_file::write_predictions(
            &out,
            &id,
            &per_point,
            &map,
            kitti2pgm::format::Durability::Renamed,
        )
    })
    .map_err(py_err)
}

/// Adds the readers to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(read_scan, m)?)?;
    m.add_function(wrap_pyfunction!(read_cloud, m)?)?;
    m.add_function(wrap_pyfunction!(read_boxes, m)?)?;
    m.add_function(wrap_pyfunction!(read_point_labels, m)?)?;
    m.add_function(wrap_pyfunction!(read_calibration, m)?)?;
    m.add_function(wrap_pyfunction!(read_frame_calibration, m)?)?;
    m.add_function(wrap_pyfunction!(read_tracklets, m)?)?;
    m.add_function(wrap_pyfunction!(read_object_labels, m)?)?;
    m.add_function(wrap_pyfunction!(class_map, m)?)?;
    m.add_function(wrap_pyfunction!(label_points, m)?)?;
    Ok(())
}
