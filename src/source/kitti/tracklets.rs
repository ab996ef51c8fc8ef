//! READ: `tracklet_labels.xml`, the boost-serialization XML of a drive's 3D box annotations.
//!
//! Every field of a tracklet (`objectType`, `h`, `w`, `l`, `first_frame`, `finished`) and of a
//! pose (`tx ty tz rx ry rz`, `state`, `occlusion`, `occlusion_kf`, `truncation`,
//! `amt_occlusion`, `amt_occlusion_kf`, `amt_border_l`, `amt_border_r`, `amt_border_kf`) is
//! read; the coded ones become enums. A pose's translation is the centre of the box's
//! *bottom* face in the velodyne frame (metres), `rz` its yaw (radians); `h`, `w`, `l` are full
//! sizes along the box's z, y and x. [`crate::label::LabelBox`] turns them into a parry cuboid
//! (half extents, centred pose) once.
//!
//! [`Tracklets::at`] lists the boxes present at a frame in O(boxes at that frame).

use std::path::{Path, PathBuf};

use roxmltree::Node;
use serde::Serialize;

use crate::error::{Error, Result};
use crate::source::boxes::{AnnotatedBox, Box3, BoxConvention, BoxRotation, BoxSource};

/// The annotated object type (`objectType`).
#[derive(Debug, Clone, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
pub enum ObjectType {
    /// `Car`.
    Car,
    /// `Van`.
    Van,
    /// `Truck`.
    Truck,
    /// `Pedestrian`.
    Pedestrian,
    /// `Person (sitting)` (also accepted: `Person_sitting`).
    PersonSitting,
    /// `Cyclist`.
    Cyclist,
    /// `Tram`.
    Tram,
    /// `Misc`.
    Misc,
    /// Any other spelling, kept as written.
    Other(String),
}

impl ObjectType {
    /// Parses the `objectType` text.
    pub fn parse(s: &str) -> ObjectType {
        match s.trim() {
            "Car" => ObjectType::Car,
            "Van" => ObjectType::Van,
            "Truck" => ObjectType::Truck,
            "Pedestrian" => ObjectType::Pedestrian,
            "Person (sitting)" | "Person_sitting" => ObjectType::PersonSitting,
            "Cyclist" => ObjectType::Cyclist,
            "Tram" => ObjectType::Tram,
            "Misc" => ObjectType::Misc,
            other => ObjectType::Other(other.to_string()),
        }
    }

    /// The name as KITTI writes it.
    pub fn as_str(&self) -> &str {
        match self {
            ObjectType::Car => "Car",
            ObjectType::Van => "Van",
            ObjectType::Truck => "Truck",
            ObjectType::Pedestrian => "Pedestrian",
            ObjectType::PersonSitting => "Person (sitting)",
            ObjectType::Cyclist => "Cyclist",
            ObjectType::Tram => "Tram",
            ObjectType::Misc => "Misc",
            ObjectType::Other(s) => s,
        }
    }
}

/// How a pose was obtained (`state`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
pub enum PoseState {
    /// 0: unset.
    Unset,
    /// 1: interpolated between key frames.
    Interpolated,
    /// 2: labelled by hand (a key frame).
    Labeled,
}

/// Occlusion level (`occlusion`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
pub enum Occlusion {
    /// -1: unset.
    Unset,
    /// 0: fully visible.
    Visible,
    /// 1: partly occluded.
    Partly,
    /// 2: fully occluded.
    Fully,
}

/// Truncation by the camera image (`truncation`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
pub enum Truncation {
    /// -1: unset.
    Unset,
    /// 0: inside the image.
    InImage,
    /// 1: truncated by the image border.
    Truncated,
    /// 2: outside the image.
    OutOfImage,
    /// 99: behind the image plane.
    BehindImage,
}

impl PoseState {
    fn from_code(c: i64) -> Option<Self> {
        Some(match c {
            0 => PoseState::Unset,
            1 => PoseState::Interpolated,
            2 => PoseState::Labeled,
            _ => return None,
        })
    }
}

impl Occlusion {
    fn from_code(c: i64) -> Option<Self> {
        Some(match c {
            -1 => Occlusion::Unset,
            0 => Occlusion::Visible,
            1 => Occlusion::Partly,
            2 => Occlusion::Fully,
            _ => return None,
        })
    }
}

impl Truncation {
    fn from_code(c: i64) -> Option<Self> {
        Some(match c {
            -1 => Truncation::Unset,
            0 => Truncation::InImage,
            1 => Truncation::Truncated,
            2 => Truncation::OutOfImage,
            99 => Truncation::BehindImage,
            _ => return None,
        })
    }
}

/// One pose of a tracklet, at frame `first_frame + index`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Pose {
    /// Centre of the box's bottom face, velodyne frame, metres (`tx`, `ty`, `tz`).
    pub t: [f64; 3],
    /// Rotation about x, y, z, radians (`rx`, `ry`, `rz`; KITTI only uses `rz`, the yaw).
    pub r: [f64; 3],
    /// `state`.
    pub state: PoseState,
    /// `occlusion`.
    pub occlusion: Occlusion,
    /// `occlusion_kf`: whether the occlusion is a key frame value.
    pub occlusion_kf: bool,
    /// `truncation`.
    pub truncation: Truncation,
    /// `amt_occlusion` (-1 unset, else 0..1).
    pub amt_occlusion: f64,
    /// `amt_occlusion_kf`.
    pub amt_occlusion_kf: i32,
    /// `amt_border_l` (-1 unset, else 0..1).
    pub amt_border_l: f64,
    /// `amt_border_r` (-1 unset, else 0..1).
    pub amt_border_r: f64,
    /// `amt_border_kf`.
    pub amt_border_kf: i32,
}

/// One annotated object through the frames it is present in.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Tracklet {
    /// `objectType`.
    pub object_type: ObjectType,
    /// Full height (`h`), metres.
    pub h: f64,
    /// Full width (`w`), metres.
    pub w: f64,
    /// Full length (`l`), metres.
    pub l: f64,
    /// Frame index of the first pose.
    pub first_frame: u32,
    /// One pose per frame from `first_frame` on.
    pub poses: Vec<Pose>,
    /// `finished`, when present.
    pub finished: Option<bool>,
}

impl Tracklet {
    /// One past the last frame this tracklet has a pose at.
    pub fn end_frame(&self) -> u32 {
        self.first_frame + self.poses.len() as u32
    }

    /// The pose at `frame`, if the tracklet is present there.
    pub fn pose_at(&self, frame: u32) -> Option<&Pose> {
        frame
            .checked_sub(self.first_frame)
            .and_then(|i| self.poses.get(i as usize))
    }
}

/// The tracklets of a drive, indexed by frame.
#[derive(Debug, Clone, Default)]
pub struct Tracklets {
    /// The file they were read from.
    pub path: PathBuf,
    /// All tracklets, in file order (index + 1 is the instance id).
    pub tracklets: Vec<Tracklet>,
    by_frame: Vec<Vec<u32>>,
}

/// A box present at one frame: tracklet index, tracklet and its pose there.
pub type BoxAt<'a> = (usize, &'a Tracklet, &'a Pose);

impl Tracklets {
    /// Builds the frame index over `tracklets`.
    pub fn new(path: PathBuf, tracklets: Vec<Tracklet>) -> Tracklets {
        let end = tracklets.iter().map(Tracklet::end_frame).max().unwrap_or(0) as usize;
        let mut by_frame = vec![Vec::new(); end];
        for (i, t) in tracklets.iter().enumerate() {
            for f in t.first_frame..t.end_frame() {
                by_frame[f as usize].push(i as u32);
            }
        }
        Tracklets {
            path,
            tracklets,
            by_frame,
        }
    }

    /// Reads and parses a `tracklet_labels.xml`.
    pub fn read(path: &Path) -> Result<Tracklets> {
        let text = crate::fs::read_text(path, crate::fs::Limit::Text)?;
        Tracklets::parse(&text, path)
    }

    /// Parses the XML text; `path` names the file in errors.
    pub fn parse(text: &str, path: &Path) -> Result<Tracklets> {
        // KITTI's files carry `<!DOCTYPE boost_serialization>`: allow the DTD, it declares nothing.
        let options = roxmltree::ParsingOptions {
            allow_dtd: true,
            ..Default::default()
        };
        let doc = roxmltree::Document::parse_with_options(text, options).map_err(|e| {
            Error::NotFormat {
                path: path.into(),
                format: "well-formed XML",
                detail: e.to_string(),
            }
        })?;
        let p = Parser { path };
        let root = doc.root_element();
        let list = p.child(root, "tracklets")?;
        let items = p.counted_items(list)?;
        let tracklets = items
            .iter()
            .enumerate()
            .map(|(i, n)| {
                p.tracklet(*n)
                    .map_err(|e| p.context(e, &format!("tracklet {i}")))
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(Tracklets::new(path.into(), tracklets))
    }

    /// The boxes present at `frame`, in tracklet order.
    pub fn at(&self, frame: u32) -> impl Iterator<Item = BoxAt<'_>> + '_ {
        self.by_frame
            .get(frame as usize)
            .into_iter()
            .flatten()
            .map(move |&i| {
                let t = &self.tracklets[i as usize];
                (
                    i as usize,
                    t,
                    t.pose_at(frame).expect("index built from poses"),
                )
            })
    }

    /// Number of tracklet poses at `frame`.
    pub fn count_at(&self, frame: u32) -> usize {
        self.by_frame.get(frame as usize).map_or(0, Vec::len)
    }

    /// One past the last frame any tracklet reaches (0 without tracklets).
    pub fn end_frame(&self) -> u32 {
        self.by_frame.len() as u32
    }
}

struct Parser<'p> {
    path: &'p Path,
}

impl Parser<'_> {
    fn err(&self, node: Node, message: String) -> Error {
        let pos = node.document().text_pos_at(node.range().start);
        Error::Format {
            path: self.path.into(),
            line: Some(pos.row as usize),
            message,
        }
    }

    fn context(&self, e: Error, what: &str) -> Error {
        match e {
            Error::Format {
                path,
                line,
                message,
            } => Error::Format {
                path,
                line,
                message: format!("{what}: {message}"),
            },
            other => other,
        }
    }

    fn child<'a, 'i>(&self, node: Node<'a, 'i>, name: &str) -> Result<Node<'a, 'i>> {
        node.children()
            .find(|c| c.has_tag_name(name))
            .ok_or_else(|| {
                self.err(
                    node,
                    format!("<{}> has no <{name}>", node.tag_name().name()),
                )
            })
    }

    fn text<'a>(&self, node: Node<'a, '_>, name: &str) -> Result<&'a str> {
        let c = self.child(node, name)?;
        Ok(c.text().unwrap_or("").trim())
    }

    fn num<T: std::str::FromStr>(&self, node: Node, name: &str) -> Result<T> {
        let c = self.child(node, name)?;
        let s = c.text().unwrap_or("").trim();
        s.parse()
            .map_err(|_| self.err(c, format!("<{name}> is not a number: {s:?}")))
    }

    fn real(&self, node: Node, name: &str) -> Result<f64> {
        let v: f64 = self.num(node, name)?;
        if !v.is_finite() {
            return Err(self.err(node, format!("<{name}> is not finite: {v}")));
        }
        Ok(v)
    }

    /// The `<item>` children of a boost list, checked against its `<count>`.
    fn counted_items<'a, 'i>(&self, list: Node<'a, 'i>) -> Result<Vec<Node<'a, 'i>>> {
        let count: usize = self.num(list, "count")?;
        let items: Vec<_> = list.children().filter(|c| c.has_tag_name("item")).collect();
        if items.len() != count {
            return Err(self.err(
                list,
                format!("<count> says {count} items but {} are present", items.len()),
            ));
        }
        Ok(items)
    }

    fn tracklet(&self, n: Node) -> Result<Tracklet> {
        let first_frame: u32 = self.num(n, "first_frame")?;
        if first_frame >= super::MAX_FRAME {
            return Err(self.err(
                n,
                format!(
                    "<first_frame> {first_frame} is beyond any drive (frames are below {})",
                    super::MAX_FRAME
                ),
            ));
        }
        let (h, w, l) = (self.real(n, "h")?, self.real(n, "w")?, self.real(n, "l")?);
        crate::geom::check_box_extents(&[h, w, l], ["h", "w", "l"]).map_err(|m| self.err(n, m))?;
        let poses = self
            .counted_items(self.child(n, "poses")?)?
            .into_iter()
            .enumerate()
            .map(|(i, p)| {
                self.pose(p)
                    .map_err(|e| self.context(e, &format!("pose {i}")))
            })
            .collect::<Result<Vec<_>>>()?;
        if first_frame as u64 + poses.len() as u64 > super::MAX_FRAME as u64 {
            return Err(self.err(
                n,
                format!(
                    "poses reach frame {}, beyond any drive (frames are below {})",
                    first_frame as u64 + poses.len() as u64,
                    super::MAX_FRAME
                ),
            ));
        }
        let finished = match n.children().find(|c| c.has_tag_name("finished")) {
            Some(_) => Some(self.num::<i64>(n, "finished")? != 0),
            None => None,
        };
        Ok(Tracklet {
            object_type: ObjectType::parse(self.text(n, "objectType")?),
            h,
            w,
            l,
            first_frame,
            poses,
            finished,
        })
    }

    fn coded<T>(&self, n: Node, name: &str, f: fn(i64) -> Option<T>) -> Result<T> {
        let code: i64 = self.num(n, name)?;
        f(code).ok_or_else(|| self.err(n, format!("<{name}> has unknown code {code}")))
    }

    fn pose(&self, n: Node) -> Result<Pose> {
        Ok(Pose {
            t: [
                self.real(n, "tx")?,
                self.real(n, "ty")?,
                self.real(n, "tz")?,
            ],
            r: [
                self.real(n, "rx")?,
                self.real(n, "ry")?,
                self.real(n, "rz")?,
            ],
            state: self.coded(n, "state", PoseState::from_code)?,
            occlusion: self.coded(n, "occlusion", Occlusion::from_code)?,
            occlusion_kf: self.num::<i64>(n, "occlusion_kf")? != 0,
            truncation: self.coded(n, "truncation", Truncation::from_code)?,
            amt_occlusion: self.real(n, "amt_occlusion")?,
            amt_occlusion_kf: self.num(n, "amt_occlusion_kf")?,
            amt_border_l: self.real(n, "amt_border_l")?,
            amt_border_r: self.real(n, "amt_border_r")?,
            amt_border_kf: self.num(n, "amt_border_kf")?,
        })
    }
}

impl Tracklet {
    /// The box at `pose`, in the velodyne frame ([`BoxConvention::KITTI_TRACKLET`]).
    pub fn box_at(&self, pose: &Pose) -> Box3 {
        BoxConvention::KITTI_TRACKLET.place(
            pose.t,
            [self.h, self.w, self.l],
            &BoxRotation::Euler(pose.r),
            None,
        )
    }
}

/// KITTI's tracklets as a box source: a box per tracklet pose, its class name the tracklet's
/// `objectType`, its track the tracklet's index.
impl BoxSource for Tracklets {
    fn boxes_at(&self, frame: u32) -> Vec<AnnotatedBox> {
        self.at(frame)
            .map(|(i, t, p)| AnnotatedBox {
                geometry: t.box_at(p),
                class_name: t.object_type.as_str().to_string(),
                track: i,
            })
            .collect()
    }
    fn count_at(&self, frame: u32) -> usize {
        Tracklets::count_at(self, frame)
    }
    fn end_frame(&self) -> u32 {
        Tracklets::end_frame(self)
    }
    fn unknown_types(&self) -> Vec<String> {
        (self.tracklets.iter())
            .filter_map(|t| match &t.object_type {
                ObjectType::Other(name) => Some(name.clone()),
                _ => None,
            })
            .collect()
    }
    fn file(&self) -> Option<&Path> {
        (!self.path.as_os_str().is_empty()).then_some(self.path.as_path())
    }
}
