//! CONVERT one frame: read -> label -> project, then write its `.npy` and `.label` files.

use serde::Serialize;

use super::labels::{frame_labels, FrameLabels};
use super::ConvertOptions;
use crate::error::{Error, Result};
use crate::format::shard::viz::VizFrame;
use crate::format::{label_file, pgm};
use crate::fs::Inputs;
use crate::label::ClassCounts;
use crate::plan::DrivePlan;
use crate::project::camera::{CameraProjector, RgbOptions};
use crate::project::frame::{assemble, CellColours, PgmFrame, PointValues};
use crate::project::{project, project_beams, ProjectionStats};
use crate::provenance::MapParams;
use crate::source::kitti::camera::decode_image;
use crate::source::kitti::FrameId;
use crate::source::Scan;

/// What converting one frame found.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FrameReport {
    /// The frame.
    pub id: String,
    /// Finite points in the scan.
    pub points: u64,
    /// Non-finite points dropped.
    pub dropped_nonfinite: u64,
    /// Points beyond the range limit dropped.
    pub dropped_out_of_range: u64,
    /// Boxes of a labelled class at the frame.
    pub boxes: u64,
    /// Whether the frame has labels (a frame without converts with the background class).
    pub annotated: bool,
    /// Points per class.
    pub labelled_points: ClassCounts,
    /// Valid cells per class.
    pub labelled_cells: ClassCounts,
    /// Projection counts of the frame (`ring_fallbacks` is 0 or 1).
    pub projection: ProjectionStats,
    /// Rings found in the scan order.
    pub rings_found: u64,
    /// Cells with a colour.
    pub rgb_cells: u64,
    /// Object types of the frame's boxes that KITTI does not define (object set).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub unknown_object_types: Vec<String>,
}

impl FrameReport {
    /// Whether the frame's rows came from elevation binning.
    pub fn fallback(&self) -> bool {
        self.projection.ring_fallbacks > 0
    }
}

/// Whether a frame keeps what the visualisation topics show (the scan's points with their
/// classes, the boxes, the camera PNG's bytes).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Viz {
    /// Not kept.
    #[default]
    Off,
    /// Kept.
    On,
}

impl From<bool> for Viz {
    fn from(on: bool) -> Viz {
        if on {
            Viz::On
        } else {
            Viz::Off
        }
    }
}

/// The products of one frame, before writing.
#[derive(Debug, Clone)]
pub struct Converted {
    /// The map.
    pub pgm: PgmFrame,
    /// Per-point labels in file order (class ids).
    pub point_class: Vec<u8>,
    /// Per-point instance ids in file order.
    pub point_instance: Vec<u16>,
    /// What was found.
    pub report: FrameReport,
    /// The visualisation payload, with [`Viz::On`].
    pub viz: Option<VizFrame>,
    /// The files it was made from ([`LoadedFrame::inputs`]).
    pub inputs: Inputs,
}

pub use crate::sensor::params::{BeamRowsOf, RowsFrom};

/// Projects one labelled scan (no file access but the image, already decoded, if any); with
/// `beams`, rows are the sensor's beams.
pub fn process(
    id: &FrameId,
    scan: &Scan,
    frame_labels: &FrameLabels,
    map: &MapParams,
    beams: Option<&BeamRowsOf>,
    camera: Option<(&CameraProjector, &crate::raster::RgbImage)>,
) -> Converted {
    let (spec, classes) = (&map.spec, &map.class_map);
    let labels = &frame_labels.points;
    let mut proj = match beams {
        Some(b) => project_beams(&scan.points, spec, &b.rows, b.beams, b.columns.as_deref()),
        None => project(&scan.points, spec),
    };
    if let Some(b) = beams {
        proj.stats.ring_field_frames = (b.from == RowsFrom::RingField) as u64;
        proj.stats.beam_table_frames = (b.from == RowsFrom::BeamTable) as u64;
        proj.stats.off_model = b.off_model;
    }
    let colours =
        camera.map(|(cam, img)| CellColours::of(&proj, |i| cam.colour(img, &scan.points[i])));
    let pgm = assemble(PointValues::of_scan(scan, labels), &proj, colours.as_ref());
    let report = FrameReport {
        id: id.to_string(),
        points: scan.len() as u64,
        dropped_nonfinite: (scan.dropped.len() - scan.dropped_out_of_range) as u64,
        dropped_out_of_range: scan.dropped_out_of_range as u64,
        boxes: frame_labels.boxes.len() as u64,
        annotated: frame_labels.annotated,
        labelled_points: labels.class_counts(classes.len()),
        labelled_cells: pgm.class_cells(classes.len()),
        projection: proj.stats,
        rings_found: proj.rings_found as u64,
        rgb_cells: pgm
            .rgb_valid
            .as_ref()
            .map_or(0, |v| v.iter().map(|&b| b as u64).sum()),
        unknown_object_types: frame_labels.unknown_types.clone(),
    };
    Converted {
        point_class: scan.to_file_order(&labels.class, classes.background),
        point_instance: scan.to_file_order(&labels.instance, 0),
        pgm,
        report,
        viz: None,
        inputs: Inputs::default(),
    }
}

/// One frame read and labelled: everything projecting it needs.
#[derive(Debug, Clone)]
pub struct LoadedFrame {
    /// The frame.
    pub id: FrameId,
    /// Its scan (finite, in-range points in file order).
    pub scan: Scan,
    /// The labels of the scan's points.
    pub labels: FrameLabels,
    /// The camera and its decoded image, when colour is asked for.
    pub camera: Option<(CameraProjector, crate::raster::RgbImage)>,
    /// The camera's PNG bytes, when kept (visualisation).
    pub png: Option<Vec<u8>>,
    /// The rows of another sensor's scan, by its sensor model.
    pub beams: Option<BeamRowsOf>,
    /// Every file read for it (scan, labels, calibration, image, the drive's tracklets and
    /// timestamps) with its fingerprint, and every path looked for and absent: what the
    /// frame's outputs are made from.
    pub inputs: Inputs,
}

impl LoadedFrame {
    /// The colour of every point of the scan (`None` where the camera does not see it), when
    /// colour is on.
    pub fn point_colours(&self) -> Option<Vec<Option<[f32; 3]>>> {
        let (cam, img) = self.camera.as_ref()?;
        Some(
            self.scan
                .points
                .iter()
                .map(|p| cam.colour(img, p))
                .collect(),
        )
    }
}

/// Reads frame `frame` of `dp` as `map` asks: scan, labels and, with colour, the camera image
/// (checked against the calibrated size); with [`Viz::On`] the image's file bytes are kept.
/// Every input read is recorded in [`LoadedFrame::inputs`].
pub fn load(dp: &DrivePlan, frame: u32, map: &MapParams, viz: Viz) -> Result<LoadedFrame> {
    let (loaded, inputs) = crate::fs::recording(|| {
        crate::fs::note(&dp.inputs);
        read_frame(dp, frame, map, viz)
    });
    Ok(LoadedFrame { inputs, ..loaded? })
}

fn read_frame(dp: &DrivePlan, frame: u32, map: &MapParams, viz: Viz) -> Result<LoadedFrame> {
    let id = dp.drive.frame_id(frame);
    let scan_path = dp.drive.scan_path(frame);
    let (scan, beams) = crate::sensor::read_scan(map.sensor.as_ref(), &scan_path)?;
    let labels = frame_labels(dp, frame, &scan, &map.class_map)?;
    let (camera, png) = match &map.rgb {
        Some(rgb) => {
            let (camera, png) = camera_of(dp, frame, rgb, viz)?;
            (Some(camera), png)
        }
        None => (None, None),
    };
    Ok(LoadedFrame {
        id,
        scan,
        labels,
        camera,
        png,
        beams,
        inputs: Inputs::default(),
    })
}

/// A frame's camera: its projection from the scan, and its decoded image.
pub type FrameCamera = (CameraProjector, crate::raster::RgbImage);

/// Camera `rgb.camera` of frame `frame` of `dp`: its projection from the scan and its decoded
/// image (checked against the calibrated size); with [`Viz::On`] the image's file bytes too.
pub fn camera_of(
    dp: &DrivePlan,
    frame: u32,
    rgb: &RgbOptions,
    viz: Viz,
) -> Result<(FrameCamera, Option<Vec<u8>>)> {
    let path = dp.drive.image_path(rgb.camera, frame);
    let bytes = crate::fs::read(&path, crate::fs::Limit::Data)?;
    let img = decode_image(&bytes, &path)?;
    let (velo_to_image, size, calib_file) = dp.camera(frame, rgb.camera)?;
    // The projection matrix maps into an image of the rectified size: a picture of another
    // size would be sampled at the wrong pixels.
    if let Some([w, h]) = size {
        if (img.width() as f64, img.height() as f64) != (w, h) {
            return Err(Error::Shape {
                path,
                what: "the image".into(),
                found: vec![img.width() as usize, img.height() as usize],
                expected: format!(
                    "{w}x{h}, the size camera {} is calibrated for in {}",
                    rgb.camera,
                    calib_file.display()
                ),
            });
        }
    }
    let proj = CameraProjector {
        velo_to_image,
        sampling: rgb.sampling,
    };
    Ok(((proj, img), (viz == Viz::On).then_some(bytes)))
}

impl LoadedFrame {
    /// Projects the frame with `map` (no output written): [`process`], and with [`Viz::On`] the
    /// visualisation payload.
    pub fn into_converted(self, map: &MapParams, viz: Viz) -> Converted {
        let LoadedFrame {
            id,
            scan,
            labels,
            camera,
            png,
            beams,
            inputs,
        } = self;
        let camera = camera.as_ref().map(|(p, i)| (p, i));
        let mut out = process(&id, &scan, &labels, map, beams.as_ref(), camera);
        out.inputs = inputs;
        if viz == Viz::On {
            let file_idx = scan.file_indices();
            let points = scan.points.iter().zip(&scan.intensity).zip(&file_idx);
            out.viz = Some(VizFrame {
                points: points
                    .map(|((p, r), &fi)| (*p, *r, out.point_class[fi as usize]))
                    .collect(),
                boxes: labels.boxes.clone(),
                png,
                camera: map.rgb.map_or(2, |r| r.camera),
                colours: map.class_map.classes.iter().map(|c| c.colour).collect(),
            });
        }
        out
    }
}

/// Writes a converted frame's `.npy` and `.label` files, as the options ask.
pub fn write_frame_files(
    dp: &DrivePlan,
    frame: u32,
    out: &Converted,
    opts: &ConvertOptions,
) -> Result<()> {
    let id = dp.drive.frame_id(frame);
    if opts.params.npy {
        pgm::write(&opts.out.npy_path(&id), &out.pgm, opts.durability)?;
    }
    if opts.params.labels {
        let bytes = label_file::encode(&out.point_class, &out.point_instance);
        crate::format::atomic_write(&opts.out.label_path(&id), &bytes, opts.durability)?;
    }
    Ok(())
}

/// Reads, converts and writes one frame (`.npy` and `.label` outputs): [`load`],
/// [`LoadedFrame::into_converted`], [`write_frame_files`]; returns what was found and the
/// inputs it was made from.
pub fn convert_frame(
    dp: &DrivePlan,
    frame: u32,
    opts: &ConvertOptions,
) -> Result<(FrameReport, Inputs)> {
    let map = &opts.params.map;
    let out = load(dp, frame, map, Viz::Off)?.into_converted(map, Viz::Off);
    write_frame_files(dp, frame, &out, opts)?;
    Ok((out.report, out.inputs))
}
