//! CVAT's "Kitti Raw Format 1.0" export, as Datumaro's `kitti_raw` plugin writes it (CVAT exports
//! through Datumaro): `tracklet_labels.xml` (KITTI's tracklet XML, boost serialisation) beside
//! `velodyne_points/data/<name>.pcd`, and `frame_list.txt` (`<frame index> <name>` a line) that
//! names each frame's point cloud; without it a frame is named `<frame10>` as KITTI's.
//!
//! The conventions differ from KITTI's own tracklets, which the file format otherwise shares
//! (Datumaro's `kitti_raw/exporter.py` and `base.py`): the pose's `tx ty tz` is the cuboid's
//! **centre** (CVAT's `cuboid_3d` position), not the bottom centre; and the sizes are written
//! `w = scale x`, `h = scale y`, `l = scale z` (Datumaro issue #1578), not KITTI's `l` along x
//! and `h` along z. Both are options ([`super::ReadOptions`]) with CVAT's as the default. Poses
//! marked `truncation` 2 (outside the image) or 99 (behind it) are the gaps Datumaro's exporter
//! fills between a track's keyframes and its importer skips: they are skipped here too.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use super::{check_box, AnnotatedFrame, Annotations, BoxFormat, CvatSizes, ReadOptions};
use crate::error::{Error, Result};
use crate::source::boxes::{AnnotatedBox, BoxConvention, BoxFrame, BoxOrigin, BoxRotation};
use crate::source::kitti::tracklets::{Tracklets, Truncation};

/// The annotation file's name.
pub const ANNOTATIONS: &str = "tracklet_labels.xml";
/// The frame list's name: `<frame index> <point cloud name>` a line.
pub const FRAME_LIST: &str = "frame_list.txt";

/// The annotation file of an export at `path` (the folder, or the file itself).
fn annotation_file(path: &Path) -> PathBuf {
    if path.is_dir() {
        path.join(ANNOTATIONS)
    } else {
        path.to_path_buf()
    }
}

/// Whether `path` holds (or is) a tracklet XML file.
pub fn looks_like(path: &Path) -> bool {
    let file = annotation_file(path);
    file.extension().is_some_and(|e| e == "xml")
        && crate::fs::read_text(&file, crate::fs::Limit::Text)
            .is_ok_and(|t| t.contains("<boost_serialization") && t.contains("<tracklets"))
}

/// Reads the export at `path` (its folder or its `tracklet_labels.xml`).
pub fn read(path: &Path, opts: &ReadOptions) -> Result<Annotations> {
    let file = annotation_file(path);
    let tracklets = Tracklets::read(&file)?;
    let names = frame_names(&file.with_file_name(FRAME_LIST))?;
    let convention = BoxConvention {
        origin: opts.origin.unwrap_or(BoxOrigin::Centre),
        sizes: opts.sizes.unwrap_or(CvatSizes::Datumaro).of_hwl(),
        frame: BoxFrame::Scan,
    };
    let mut frames: BTreeMap<String, AnnotatedFrame> = BTreeMap::new();
    for frame in 0..tracklets.end_frame() {
        let name = names
            .get(&frame)
            .cloned()
            .unwrap_or_else(|| format!("{frame:010}"));
        for (i, t, pose) in tracklets.at(frame) {
            if matches!(
                pose.truncation,
                Truncation::OutOfImage | Truncation::BehindImage
            ) {
                continue;
            }
            let what = format!("tracklet {i} ({}) at frame {frame}", t.object_type.as_str());
            check_box(&file, &what, pose.t, [t.h, t.w, t.l], &pose.r)?;
            let geometry =
                convention.place(pose.t, [t.h, t.w, t.l], &BoxRotation::Euler(pose.r), None);
            let f = frames
                .entry(name.clone())
                .or_insert_with(|| AnnotatedFrame {
                    scan: name.clone(),
                    file: file.clone(),
                    boxes: Vec::new(),
                    points: None,
                });
            f.boxes.push(AnnotatedBox {
                geometry,
                class_name: t.object_type.as_str().to_string(),
                track: i,
            });
        }
    }
    Ok(Annotations {
        format: BoxFormat::CvatKittiRaw,
        frames,
        // Datumaro numbers the tracks from 1, in file order.
        tracks: (1..=tracklets.tracklets.len())
            .map(|i| i.to_string())
            .collect(),
    })
}

/// The frame list: frame index -> the point cloud's name (its path under
/// `velodyne_points/data/`, without `.pcd`); empty when the file is absent.
fn frame_names(path: &Path) -> Result<BTreeMap<u32, String>> {
    if !crate::fs::present(path) {
        return Ok(BTreeMap::new());
    }
    let text = crate::fs::read_text(path, crate::fs::Limit::Text)?;
    let mut out = BTreeMap::new();
    for (n, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let bad = |m: &str| Error::Format {
            path: path.into(),
            line: Some(n + 1),
            message: m.into(),
        };
        let (index, name) = line
            .split_once(char::is_whitespace)
            .ok_or_else(|| bad("expected `<frame index> <name>`"))?;
        let index: u32 = (index.parse().ok())
            .filter(|&i| i < crate::source::kitti::MAX_FRAME)
            .ok_or_else(|| bad("the frame index is not a frame number"))?;
        let name = name.trim().trim_end_matches(".pcd");
        let stem = Path::new(name)
            .file_name()
            .and_then(|s| s.to_str())
            .unwrap_or("");
        if stem.is_empty() || name.contains("..") {
            return Err(bad(
                "the name is not a point cloud's name under velodyne_points/data",
            ));
        }
        if out.insert(index, stem.to_string()).is_some() {
            return Err(bad(&format!("frame {index} is listed twice")));
        }
    }
    Ok(out)
}
