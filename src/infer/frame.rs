//! INFER one scan: read and project it as the model's training data was (`convert`'s code),
//! run the model, carry the map's classes back to every point, write.

use std::path::Path;
use std::time::{Duration, Instant};

use super::model::Model;
use super::InferOptions;
use crate::error::Result;
use crate::format::npy;
use crate::label::{ClassCounts, ClassId, PointLabels};
use crate::plan::DrivePlan;
use crate::project::frame::{assemble, CellColours, PgmFrame, PointValues};
use crate::project::unproject::{unproject, Method, PointsInMap};
use crate::project::{norm, project_loaded_scan, project_scan, Projection, LASERS};
use crate::source::kitti::FrameId;
use crate::source::Scan;

/// The time one scan spent in each stage.
#[derive(Debug, Clone, Copy, Default)]
pub struct StageTimes {
    /// Reading and projecting the scan (and its camera image).
    pub read_project: Duration,
    /// Running the model (the engine's time, not the wait for another frame's run).
    pub model: Duration,
    /// Carrying the map's classes back to the points.
    pub unproject: Duration,
    /// Writing the outputs.
    pub write: Duration,
}

impl std::ops::AddAssign for StageTimes {
    fn add_assign(&mut self, o: StageTimes) {
        self.read_project += o.read_project;
        self.model += o.model;
        self.unproject += o.unproject;
        self.write += o.write;
    }
}

/// What one scan gave.
#[derive(Debug, Clone)]
pub struct ScanResult {
    /// The class of every point of the scan file, in file order (`None`: outside the map, or
    /// dropped when read).
    pub per_point: Vec<Option<ClassId>>,
    /// The class of every cell (row-major).
    pub cells: Vec<ClassId>,
    /// Points per predicted class.
    pub counts: ClassCounts,
    /// The time of each stage.
    pub times: StageTimes,
}

/// A scan projected with the model's map: the scan, where its points went, the map.
pub struct Projected {
    /// The scan as read.
    pub scan: Scan,
    /// Its projection, with every point's cell.
    pub proj: Projection,
    /// Its map.
    pub map: PgmFrame,
}

/// Reads the scan at `path` and projects it with `model`'s map; with colour, the camera image of
/// frame `frame` of `drive` colours it.
pub fn project(model: &Model, path: &Path, camera: Option<(&DrivePlan, u32)>) -> Result<Projected> {
    let params = &model.spec.map;
    let (scan, proj) = project_scan(&params.spec, params.sensor.as_ref(), path)?;
    assembled(model, scan, proj, path, camera)
}

/// Projects a scan read elsewhere (a bag's message, a caller's arrays; named `what`) as [`project`] projects a
/// file; no camera.
pub fn project_points(model: &Model, scan: Scan, what: &Path) -> Result<Projected> {
    let params = &model.spec.map;
    let (scan, proj) = project_loaded_scan(&params.spec, params.sensor.as_ref(), scan, what)?;
    assembled(model, scan, proj, what, None)
}

/// The map of a projected scan, coloured by the camera where the model takes colour.
fn assembled(
    model: &Model,
    scan: Scan,
    proj: Projection,
    path: &Path,
    camera: Option<(&DrivePlan, u32)>,
) -> Result<Projected> {
    let params = &model.spec.map;
    refuse_other_sensor(model, &scan, path)?;
    refuse_off_model(model, &scan, &proj, path)?;
    let colours = match (&params.rgb, camera) {
        (Some(rgb), Some((dp, frame))) => {
            let ((cam, img), _) =
                crate::convert::frame::camera_of(dp, frame, rgb, crate::convert::frame::Viz::Off)?;
            Some(CellColours::of(&proj, |i| {
                cam.colour(&img, &scan.points[i])
            }))
        }
        (Some(_), None) => {
            return Err(crate::error::Error::Config(format!(
                "{}: the model takes colour channels (r, g, b), and this scan has no camera \
                 image: run it on its KITTI raw drive",
                path.display()
            )))
        }
        (None, _) => None,
    };
    let n = scan.len();
    let none = PointLabels {
        class: vec![params.class_map.background; n],
        instance: vec![0; n],
    };
    let map = assemble(PointValues::of_scan(&scan, &none), &proj, colours.as_ref());
    Ok(Projected { scan, proj, map })
}

/// The scan's points with their predicted classes (those with one), for `--viz`.
pub fn viz_points(
    scan: &Scan,
    per_point: &[Option<ClassId>],
) -> Vec<(crate::geom::Point3, f32, ClassId)> {
    (scan.file_indices().iter().enumerate())
        .filter_map(|(i, &f)| per_point[f as usize].map(|c| (scan.points[i], scan.intensity[i], c)))
        .collect()
}

/// Refuses a scan of another sensor than a KITTI model's: the model's map takes its rows from
/// the HDL-64E's scan order ([`LASERS`] rings), and a scan whose ring field counts another
/// number of beams would be binned into rows it was never trained on.
fn refuse_other_sensor(model: &Model, scan: &Scan, path: &Path) -> Result<()> {
    let params = &model.spec.map;
    let Some(rings) = scan.ring.as_ref().filter(|_| params.sensor.is_none()) else {
        return Ok(());
    };
    let beams = rings.iter().max().map_or(0, |&r| r as usize + 1);
    if beams == 0 || beams == LASERS {
        return Ok(());
    }
    Err(crate::error::Error::Input {
        path: path.into(),
        message: format!(
            "a {beams}-beam scan (its ring field), and {} was trained on KITTI's 64-beam maps \
             ({} x {} over {} degrees, rows from the HDL-64E's scan order): run a model trained \
             on this sensor's maps (kitti2pgm convert --sensor ...)",
            model.path.display(),
            params.spec.rows,
            params.spec.cols,
            params.spec.fov.0
        ),
    })
}

/// The share of a scan's points that fit no beam of the model's sensor beyond which the scan is
/// refused (the points are another sensor's, or not in the sensor's frame): ten times `check`'s
/// `beam-model.warn-share` and a fifth of its error share, since a model given rows it never saw
/// gives no warning of its own (a KITTI HDL-64E scan read as a VLP-16's: 21% of its points).
pub const OFF_MODEL_REFUSED: f64 = 0.1;

/// Refuses a scan most of whose points fit no beam of the sensor the model was trained on.
fn refuse_off_model(model: &Model, scan: &Scan, proj: &Projection, path: &Path) -> Result<()> {
    let (off, n) = (proj.stats.off_model, scan.len());
    let Some(sensor) = model.spec.map.sensor.as_ref() else {
        return Ok(());
    };
    if n == 0 || (off as f64) <= OFF_MODEL_REFUSED * n as f64 {
        return Ok(());
    }
    let spec = &model.spec.map.spec;
    Err(crate::error::Error::Input {
        path: path.into(),
        message: format!(
            "{off} of {n} points fit no beam of {} ({} beams), the sensor {} was trained on \
             ({} x {} map): the scan is another sensor's, or not in the sensor's frame",
            sensor.name,
            sensor.beams,
            model.path.display(),
            spec.rows,
            spec.cols
        ),
    })
}

/// Runs `model` on a projected scan and carries its classes back to the points.
pub fn predict(model: &Model, p: &Projected, method: &Method) -> Result<ScanResult> {
    let input = model.input_of(&p.map)?;
    let (cells, took) = model.run_timed(&input)?;
    let mut r = carry(model, p, cells, method)?;
    r.times.model = took;
    Ok(r)
}

/// Carries the class of every cell of a projected scan's map (`cells`, row-major) back to its
/// points by `method`.
pub fn carry(
    model: &Model,
    p: &Projected,
    cells: Vec<ClassId>,
    method: &Method,
) -> Result<ScanResult> {
    let mut times = StageTimes::default();
    let t = Instant::now();
    let classes = &model.spec.map.class_map;
    let point_range: Vec<f32> = p.scan.points.iter().map(norm).collect();
    let m = PointsInMap::of(&p.proj, &point_range);
    let kept = unproject(&m, &cells, method, classes)?;
    let counts = ClassCounts::count(classes.len(), kept.iter().flatten().copied());
    let per_point = p.scan.to_file_order(&kept, None);
    times.unproject = t.elapsed();
    Ok(ScanResult {
        per_point,
        cells,
        counts,
        times,
    })
}

/// Writes a frame's per-point predictions (in the layout `score` reads) and, when asked, its
/// map prediction (`OUT/maps/<id>.npy`, rows x cols class ids as float32).
pub fn write(
    out: &Path,
    id: &FrameId,
    r: &ScanResult,
    model: &Model,
    opts: &InferOptions,
) -> Result<()> {
    let classes = &model.spec.map.class_map;
    crate::format::label_file::write_predictions(out, id, &r.per_point, classes, opts.durability)?;
    if opts.maps {
        let dir = out.join(super::MAPS_DIR);
        write_map(
            &crate::format::layout::npy_path_in(&dir, id),
            r,
            model,
            opts,
        )?;
    }
    Ok(())
}

/// Writes a lone scan's per-point predictions, `out/<stem>.label` (class ids,
/// [`NOT_PREDICTED`](crate::format::label_file::NOT_PREDICTED) outside the map), and with maps
/// `out/maps/<stem>.npy`.
pub fn write_file(
    out: &Path,
    stem: &str,
    r: &ScanResult,
    model: &Model,
    opts: &InferOptions,
) -> Result<()> {
    let entries = crate::format::label_file::encode_class_predictions(&r.per_point);
    crate::format::create_dir(out)?;
    let bytes = crate::format::label_file::encode_raw(&entries);
    crate::format::atomic_write(&out.join(format!("{stem}.label")), &bytes, opts.durability)?;
    if opts.maps {
        let path = out.join(super::MAPS_DIR).join(format!("{stem}.npy"));
        write_map(&path, r, model, opts)?;
    }
    Ok(())
}

/// Writes a map prediction: rows x cols class ids as float32 `.npy` (what `score` reads).
fn write_map(path: &Path, r: &ScanResult, model: &Model, opts: &InferOptions) -> Result<()> {
    let spec = &model.spec.map.spec;
    crate::format::create_dir(path.parent().expect("a file in a folder"))?;
    let data: Vec<f32> = r.cells.iter().map(|&c| c as f32).collect();
    let bytes = npy::encode_f32(&[spec.rows as u64, spec.cols as u64], &data);
    crate::format::atomic_write(path, &bytes, opts.durability)
}
