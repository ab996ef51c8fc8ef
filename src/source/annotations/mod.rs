//! READ: the 3D box annotations that labelling tools export, one reader a format: [`cvat_kitti`]
//! (CVAT's "Kitti Raw Format 1.0", through Datumaro), [`supervisely`] (the Supervisely point
//! cloud format, also CVAT's "Sly Point Cloud"), [`sustechpoints`] (SUSTechPOINTS' `label/`
//! files), [`labelcloud`] (labelCloud's centroid formats), [`segments`] (Segments.ai's release
//! file), [`xtreme1`] (Xtreme1's and BasicAI's export), [`openlabel`] (ASAM OpenLABEL 1.0).
//!
//! Each reader says what its files say, as [`AnnotatedBox`]es in the scan's frame placed by the
//! format's [`BoxConvention`](super::boxes::BoxConvention) (written down in docs/sources.md with
//! where it was taken from), each frame keyed by the name of the scan it annotates (its file
//! stem: a scan is found by name, never by position). Turning a box into a class is
//! [`crate::label`]'s rule. A box that cannot be a box (a size that is not a positive finite
//! number of at most [`MAX_BOX_EXTENT_M`](crate::geom::MAX_BOX_EXTENT_M), a position or angle
//! that is not finite), an object id twice in one frame, or an empty or malformed file is an
//! error naming the file and the object.

pub mod cvat_kitti;
pub mod labelcloud;
pub mod openlabel;
pub mod segments;
pub mod supervisely;
pub mod sustechpoints;
pub mod xtreme1;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use super::boxes::{AnnotatedBox, Box3, BoxConvention, BoxOrigin, BoxRotation, SizeOrder};
use crate::error::{Error, Result};

/// A box annotation format.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum BoxFormat {
    /// CVAT's "Kitti Raw Format 1.0" export (Datumaro's `kitti_raw`): `tracklet_labels.xml`
    /// beside `velodyne_points/data/*.pcd`, with `frame_list.txt`.
    CvatKittiRaw,
    /// The Supervisely point cloud format (CVAT's "Sly Point Cloud"): `<dataset>/ann/*.pcd.json`.
    Supervisely,
    /// SUSTechPOINTS: `label/<frame>.json` beside `lidar/<frame>.pcd`.
    SusTechPoints,
    /// labelCloud's `centroid_abs` / `centroid_rel`: `labels/<point cloud>.json`.
    LabelCloud,
    /// Segments.ai's release file (cuboids of point cloud samples and sequences).
    SegmentsAi,
    /// Xtreme1's / BasicAI's export: `result/<name>.json` beside `point_cloud/`.
    Xtreme1,
    /// ASAM OpenLABEL 1.0 JSON (cuboids).
    OpenLabel,
}

crate::named_enum!(BoxFormat, "box format", [
    CvatKittiRaw => "cvat-kitti-raw" ["cvat", "kitti-raw"] "CVAT's Kitti Raw Format 1.0: tracklet_labels.xml (box centre, Datumaro's size order)",
    Supervisely => "supervisely" ["sly", "sly-pointcloud"] "Supervisely point cloud: <dataset>/ann/<scan>.pcd.json cuboid_3d figures",
    SusTechPoints => "sustechpoints" ["sustech"] "SUSTechPOINTS: label/<frame>.json (psr: position, scale, rotation)",
    LabelCloud => "labelcloud" ["label-cloud"] "labelCloud's centroid formats: labels/<point cloud>.json (degrees by default)",
    SegmentsAi => "segments-ai" ["segments", "segmentsai"] "Segments.ai's release file: cuboids (yaw or quaternion), ego poses",
    Xtreme1 => "xtreme1" ["basicai", "basic-ai"] "Xtreme1 / BasicAI: result/<name>.json 3D_BOX objects (center3D, size3D, rotation3D)",
    OpenLabel => "openlabel" ["asam-openlabel"] "ASAM OpenLABEL 1.0 JSON: cuboids (Euler ZYX or quaternion)",
]);

/// How to read a format whose files leave a convention open (CVAT's tracklets: where the
/// position sits, the order of the sizes); `None` takes the format's own default.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ReadOptions {
    /// Where the position sits on the box.
    pub origin: Option<BoxOrigin>,
    /// The order of the sizes.
    pub sizes: Option<CvatSizes>,
    /// The unit of the angles (labelCloud's: degrees in `centroid_abs`, radians in
    /// `centroid_rel`).
    pub angles: Option<AngleUnit>,
    /// The motion from the frame the boxes are given in to the scan's (boxes drawn in a
    /// vehicle frame: the inverse of the sensor's pose there, `--sensor-pose`); `None`: the
    /// boxes are in the scan's frame, as every format here assumes by default.
    pub to_scan: Option<crate::geom::na::Isometry3<f64>>,
}

/// The unit a format's angles are written in, where the files do not say it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AngleUnit {
    /// Degrees (labelCloud's `centroid_abs`, its default).
    Degrees,
    /// Radians (labelCloud's `centroid_rel`).
    Radians,
}

crate::named_enum!(AngleUnit, "angle unit", [
    Degrees => "degrees" ["deg"] "degrees (labelCloud's centroid_abs, its default)",
    Radians => "radians" ["rad"] "radians (labelCloud's centroid_rel)",
]);

/// The order of a CVAT tracklet file's `h`, `w`, `l` along the box's own x, y, z.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CvatSizes {
    /// Datumaro's exporter (and CVAT through it): `w`, `h`, `l` are the cuboid's x, y, z
    /// extents (Datumaro issue #1578).
    Datumaro,
    /// KITTI's own: `l` along x, `w` along y, `h` along z.
    Kitti,
}

crate::named_enum!(CvatSizes, "size order", [
    Datumaro => "datumaro" [] "w, h, l are the box's x, y, z extents (CVAT's exports through Datumaro)",
    Kitti => "kitti" [] "l, w, h are the box's x, y, z extents (KITTI's own tracklets)",
]);

impl CvatSizes {
    /// The order as a [`SizeOrder`] of the file's `h w l` triple.
    pub fn of_hwl(self) -> SizeOrder {
        match self {
            CvatSizes::Datumaro => SizeOrder::HwlSwapped,
            CvatSizes::Kitti => SizeOrder::Hwl,
        }
    }
}

/// The boxes of one annotated frame.
#[derive(Debug, Clone, PartialEq)]
pub struct AnnotatedFrame {
    /// The scan it annotates, by name (the scan file's stem: `000042`, `frame1`).
    pub scan: String,
    /// The file the boxes were read from.
    pub file: PathBuf,
    /// The boxes, in the file's order, in the scan's frame.
    pub boxes: Vec<AnnotatedBox>,
    /// Per-point annotations, where the format has them (Segments.ai's point cloud
    /// segmentation): they decide the points they label, the boxes the rest.
    pub points: Option<PointAnnotations>,
}

impl AnnotatedFrame {
    /// Every object of the frame, as (class name, track): its boxes', then its per-point
    /// annotations'.
    pub fn objects(&self) -> impl Iterator<Item = (&str, usize)> + '_ {
        let points = self.points.iter().flat_map(|p| p.classes.values());
        (self.boxes.iter().map(|b| (b.class_name.as_str(), b.track)))
            .chain(points.map(|(c, t)| (c.as_str(), *t)))
    }
}

/// A frame's per-point annotations: each point's object, in the scan file's order.
#[derive(Debug, Clone, PartialEq)]
pub struct PointAnnotations {
    /// Each point's object id (0: none), in the scan file's order.
    pub objects: Vec<u32>,
    /// Each object id's class name (as the file writes it) and track.
    pub classes: BTreeMap<u32, (String, usize)>,
}

/// An export as read: its frames by scan name, and its tracks (a box's `track` indexes
/// `tracks`: the tool's own id of the object).
#[derive(Debug, Clone, PartialEq)]
pub struct Annotations {
    /// The format read.
    pub format: BoxFormat,
    /// The annotated frames, by scan name.
    pub frames: BTreeMap<String, AnnotatedFrame>,
    /// The tool's id of every track, by track index.
    pub tracks: Vec<String>,
}

impl Annotations {
    /// Boxes in all frames.
    pub fn boxes(&self) -> usize {
        self.frames.values().map(|f| f.boxes.len()).sum()
    }
}

/// Imported boxes by the frame number of the scan each annotated frame was matched to: a
/// [`BoxSource`](super::boxes::BoxSource) like KITTI's tracklets.
#[derive(Debug, Clone, Default)]
pub struct FrameBoxes {
    /// The export the boxes were read from.
    pub file: PathBuf,
    /// The boxes of each frame, in the file's order.
    pub frames: BTreeMap<u32, Vec<AnnotatedBox>>,
    /// The annotation file of each frame.
    pub files: BTreeMap<u32, PathBuf>,
    /// The annotation tool's own id of each track.
    pub tool_ids: BTreeMap<usize, String>,
}

impl super::boxes::BoxSource for FrameBoxes {
    fn boxes_at(&self, frame: u32) -> Vec<AnnotatedBox> {
        self.frames.get(&frame).cloned().unwrap_or_default()
    }
    fn count_at(&self, frame: u32) -> usize {
        self.frames.get(&frame).map_or(0, Vec::len)
    }
    fn end_frame(&self) -> u32 {
        self.frames.keys().next_back().map_or(0, |f| f + 1)
    }
    fn unknown_types(&self) -> Vec<String> {
        Vec::new()
    }
    fn file(&self) -> Option<&Path> {
        Some(&self.file)
    }
}

/// Reads the export at `path` as `format`. A path that holds another format's files is an error
/// that names the format it looks like.
pub fn read(path: &Path, format: BoxFormat, opts: &ReadOptions) -> Result<Annotations> {
    let read = match format {
        BoxFormat::CvatKittiRaw => cvat_kitti::read(path, opts),
        BoxFormat::Supervisely => supervisely::read(path),
        BoxFormat::SusTechPoints => sustechpoints::read(path),
        BoxFormat::LabelCloud => labelcloud::read(path, opts),
        BoxFormat::SegmentsAi => segments::read(path),
        BoxFormat::Xtreme1 => xtreme1::read(path),
        BoxFormat::OpenLabel => openlabel::read(path),
    };
    let mut a = read.map_err(|e| match detect(path) {
        Some(other) if other != format => Error::Input {
            path: path.into(),
            message: format!("not a {format} export: it looks like {other} ({e})"),
        },
        _ => e,
    })?;
    if let Some(motion) = &opts.to_scan {
        for b in a.frames.values_mut().flat_map(|f| f.boxes.iter_mut()) {
            b.geometry = b.geometry.moved(motion);
        }
    }
    Ok(a)
}

/// The format the export at `path` looks like, from its files' names and first bytes.
pub fn detect(path: &Path) -> Option<BoxFormat> {
    if cvat_kitti::looks_like(path) {
        return Some(BoxFormat::CvatKittiRaw);
    }
    if supervisely::looks_like(path) {
        return Some(BoxFormat::Supervisely);
    }
    if sustechpoints::looks_like(path) {
        return Some(BoxFormat::SusTechPoints);
    }
    if xtreme1::looks_like(path) {
        return Some(BoxFormat::Xtreme1);
    }
    if segments::looks_like(path) {
        return Some(BoxFormat::SegmentsAi);
    }
    if openlabel::looks_like(path) {
        return Some(BoxFormat::OpenLabel);
    }
    labelcloud::looks_like(path).then_some(BoxFormat::LabelCloud)
}

/// Interns the tool's object ids as track indices, in the order first seen.
#[derive(Debug, Default)]
struct Tracks {
    ids: Vec<String>,
    index: std::collections::HashMap<String, usize>,
}

impl Tracks {
    /// The track of the tool's id `id`.
    fn of(&mut self, id: &str) -> usize {
        if let Some(&i) = self.index.get(id) {
            return i;
        }
        self.ids.push(id.to_string());
        self.index.insert(id.to_string(), self.ids.len() - 1);
        self.ids.len() - 1
    }
}

/// Checks a box's numbers as a file gives them: a finite position and rotation, sizes that are
/// positive finite numbers of at most [`MAX_BOX_EXTENT_M`](crate::geom::MAX_BOX_EXTENT_M) (the
/// same rule as KITTI's tracklets); `what` names the object in the error.
fn check_box(
    file: &Path,
    what: &str,
    position: [f64; 3],
    sizes: [f64; 3],
    angles: &[f64],
) -> Result<()> {
    let bad = |message: String| Error::format(file, format!("{what}: {message}"));
    if let Some(v) = position.iter().find(|v| !v.is_finite() || v.abs() > 1e6) {
        return Err(bad(format!(
            "position {v} is not a finite number of at most 1e6 m"
        )));
    }
    if let Some(v) = angles.iter().find(|v| !v.is_finite()) {
        return Err(bad(format!("rotation {v} is not finite")));
    }
    crate::geom::check_box_extents(&sizes, ["x", "y", "z"]).map_err(bad)
}

/// A number at `key` of a JSON object `v`, or an error naming `what` and the key.
fn number(v: &serde_json::Value, key: &str, file: &Path, what: &str) -> Result<f64> {
    v.get(key)
        .and_then(serde_json::Value::as_f64)
        .ok_or_else(|| Error::format(file, format!("{what}: no number at \"{key}\"")))
}

/// An `{x, y, z}` JSON object's three numbers.
fn xyz(v: Option<&serde_json::Value>, key: &str, file: &Path, what: &str) -> Result<[f64; 3]> {
    let v = v.ok_or_else(|| Error::format(file, format!("{what}: no \"{key}\"")))?;
    let w = |k: &str| number(v, k, file, &format!("{what} {key}"));
    Ok([w("x")?, w("y")?, w("z")?])
}

/// The scan name a file reference gives (a URL, a URI, a path): its last segment without a
/// query or fragment, and without its extension (`.pcd.bin` whole): `https://x/a/000042.pcd?sig=1`
/// -> `000042`.
fn uri_stem(uri: &str) -> String {
    let file = uri.split(['?', '#']).next().unwrap_or(uri);
    let file = file.rsplit('/').next().unwrap_or(file);
    let file = file.strip_suffix(".pcd.bin").unwrap_or(file);
    file.rsplit_once('.').map_or(file, |(s, _)| s).to_string()
}

/// Reads a JSON file (a regular file of at most the text limit).
fn read_json(file: &Path) -> Result<serde_json::Value> {
    let text = crate::fs::read_text(file, crate::fs::Limit::Text)?;
    if text.trim().is_empty() {
        return Err(Error::format(file, "empty file (no JSON)"));
    }
    serde_json::from_str(&text).map_err(|e| Error::NotFormat {
        path: file.into(),
        format: "JSON",
        detail: e.to_string(),
    })
}

/// The order in which a format composes its Euler angles into a rotation.
#[derive(Debug, Clone, Copy)]
enum EulerOrder {
    /// `Rx(x) * Ry(y) * Rz(z)`: three.js's `XYZ` order (the web editors: Supervisely,
    /// SUSTechPOINTS' `euler_angle_to_rotate_matrix`, Xtreme1).
    Xyz,
    /// `Rz(z) * Ry(y) * Rx(x)`: OpenLABEL's (its reference library VCD: `euler2R([rz, ry, rx])`,
    /// sequence `ZYX`).
    Zyx,
}

/// The box of a centre, x, y, z extents and Euler angles x, y, z composed in `order`, checked;
/// `what` names the object in errors.
fn centred_euler(
    file: &Path,
    what: &str,
    (centre, sizes): ([f64; 3], [f64; 3]),
    [x, y, z]: [f64; 3],
    order: EulerOrder,
) -> Result<Box3> {
    check_box(file, what, centre, sizes, &[x, y, z])?;
    let r = match order {
        EulerOrder::Xyz => axis(0, x) * axis(1, y) * axis(2, z),
        EulerOrder::Zyx => axis(2, z) * axis(1, y) * axis(0, x),
    };
    Ok(centred(centre, sizes, *r.matrix()))
}

/// The box of the web editors' form: [`centred_euler`] in the `XYZ` order.
fn centred_xyz_euler(
    file: &Path,
    what: &str,
    centre: [f64; 3],
    sizes: [f64; 3],
    angles: [f64; 3],
) -> Result<Box3> {
    centred_euler(file, what, (centre, sizes), angles, EulerOrder::Xyz)
}

/// Reads one annotation file a scan, each named by its file's stem (`label/000042.json`
/// annotates scan `000042`), with `read_frame`.
fn frames_by_stem(
    format: BoxFormat,
    files: Vec<PathBuf>,
    mut read_frame: impl FnMut(&Path, String, &mut Tracks) -> Result<AnnotatedFrame>,
) -> Result<Annotations> {
    let mut tracks = Tracks::default();
    let mut frames = BTreeMap::new();
    for file in files {
        let scan = (file.file_stem().and_then(|s| s.to_str()))
            .unwrap_or("")
            .to_string();
        let frame = read_frame(&file, scan.clone(), &mut tracks)?;
        frames.insert(scan, frame);
    }
    Ok(Annotations {
        format,
        frames,
        tracks: tracks.ids,
    })
}

/// The box of a rotation quaternion `[qx, qy, qz, qw]` (Segments.ai, OpenLABEL), checked
/// ([`unit_quaternion`]).
fn centred_quaternion(
    file: &Path,
    what: &str,
    centre: [f64; 3],
    sizes: [f64; 3],
    q: [f64; 4],
) -> Result<Box3> {
    check_box(file, what, centre, sizes, &q)?;
    let r = unit_quaternion(file, what, q)?.to_rotation_matrix();
    Ok(centred(centre, sizes, *r.matrix()))
}

/// A rotation quaternion `[qx, qy, qz, qw]`: one whose length is more than 1% from 1 is an
/// error (it is no rotation: a typing error or another convention), a nearly unit one is
/// normalised.
fn unit_quaternion(
    file: &Path,
    what: &str,
    [qx, qy, qz, qw]: [f64; 4],
) -> Result<crate::geom::na::UnitQuaternion<f64>> {
    use crate::geom::na::{Quaternion, UnitQuaternion};
    let q = Quaternion::new(qw, qx, qy, qz);
    let norm = q.norm();
    if !((0.99..=1.01).contains(&norm)) {
        return Err(Error::format(
            file,
            format!("{what}: rotation quaternion of length {norm}, far from unit length"),
        ));
    }
    Ok(UnitQuaternion::from_quaternion(q))
}

/// A rotation of `angle` radians about axis `i` (0 x, 1 y, 2 z).
fn axis(i: usize, angle: f64) -> crate::geom::na::Rotation3<f64> {
    use crate::geom::na::{Rotation3, Vector3};
    let a = [Vector3::x_axis(), Vector3::y_axis(), Vector3::z_axis()][i];
    Rotation3::from_axis_angle(&a, angle)
}

/// A checked box of centre `centre`, x, y, z extents `sizes` and rotation `r` (box to scan).
fn centred(centre: [f64; 3], sizes: [f64; 3], r: crate::geom::na::Matrix3<f64>) -> Box3 {
    BoxConvention::CENTRED_LWH.place(centre, sizes, &BoxRotation::Matrix(r), None)
}
