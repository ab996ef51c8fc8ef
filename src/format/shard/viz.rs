//! WRITE: visualisation topics in a shard (`--viz`), in Foxglove's official schemas, protobuf
//! encoded (the `foxglove` crate's messages and descriptors), so that Foxglove opens them
//! directly: the labelled point cloud (`foxglove.PointCloud`, coloured by class through its
//! `red`/`green`/`blue`/`alpha` fields), the tracklet boxes (`foxglove.SceneUpdate`, one cube per
//! box) and the camera image (`foxglove.CompressedImage`, the PNG as it is on disk). Everything
//! is in the `velodyne` frame.

use std::collections::BTreeMap;

use foxglove::schemas::{
    packed_element_field::NumericType, scene_entity_deletion, Color, CompressedImage,
    CubePrimitive, Duration, PackedElementField, PointCloud, Pose, Quaternion, SceneEntity,
    SceneEntityDeletion, SceneUpdate, Timestamp, Vector3,
};
use prost::Message as _;

use crate::geom::Point3;
use crate::label::{ClassId, LabelBox};

/// Topic of the point cloud (under `viz/`: the point shards' data topic is `/kitti2pgm/points`).
pub const POINTS_TOPIC: &str = "/kitti2pgm/viz/points";
/// Topic of the boxes.
pub const BOXES_TOPIC: &str = "/kitti2pgm/viz/boxes";
/// Topic of the camera image.
pub const IMAGE_TOPIC: &str = "/kitti2pgm/viz/image";
/// Coordinate frame of the points and boxes.
pub const FRAME_ID: &str = "velodyne";

/// What one frame shows.
#[derive(Debug, Clone, Default)]
pub struct VizFrame {
    /// Points (velodyne frame) with reflectance and class.
    pub points: Vec<(Point3, f32, ClassId)>,
    /// Labelled boxes.
    pub boxes: Vec<LabelBox>,
    /// The camera PNG, when colour was sampled.
    pub png: Option<Vec<u8>>,
    /// Camera number of the PNG.
    pub camera: u8,
    /// Display colour of each class id (the class map's).
    pub colours: Vec<[u8; 3]>,
}

impl VizFrame {
    fn colour(&self, c: ClassId) -> [u8; 3] {
        self.colours
            .get(c as usize)
            .copied()
            .unwrap_or([128, 128, 128])
    }
}

/// The three channels in a writer.
#[derive(Debug, Clone, Copy)]
pub struct VizChannels {
    points: u16,
    boxes: u16,
    image: u16,
}

/// Adds a channel on `topic` for Foxglove's message type `T` (its schema, protobuf encoded).
fn channel<T: foxglove::Encode, W: std::io::Write + std::io::Seek>(
    w: &mut mcap::Writer<W>,
    topic: &str,
) -> mcap::McapResult<u16> {
    let s = T::get_schema().expect("Foxglove's schemas are known");
    let schema = w.add_schema(&s.name, &s.encoding, &s.data)?;
    w.add_channel(schema, topic, &T::get_message_encoding(), &BTreeMap::new())
}

fn time(ns: u64) -> Option<Timestamp> {
    Some(Timestamp::new(
        (ns / 1_000_000_000) as u32,
        (ns % 1_000_000_000) as u32,
    ))
}

/// The velodyne frame's own pose.
fn identity() -> Option<Pose> {
    Some(Pose {
        position: Some(Vector3::default()),
        orientation: Some(Quaternion {
            w: 1.0,
            ..Default::default()
        }),
    })
}

/// A visualisation file being written: its MCAP writer over a temporary file beside `path`,
/// renamed into place by [`VizFile::finish`] (dropped unfinished, the temporary file goes).
pub struct VizFile {
    /// Where it goes.
    pub path: std::path::PathBuf,
    /// The writer.
    pub writer: mcap::Writer<std::io::BufWriter<std::fs::File>>,
    /// Its channels.
    pub channels: VizChannels,
    tmp: tempfile::TempPath,
}

impl VizFile {
    /// Starts the file `path` (its folder made) with the three channels.
    pub fn create(path: &std::path::Path) -> crate::error::Result<VizFile> {
        use crate::error::Error;
        let dir = path
            .parent()
            .filter(|p| !p.as_os_str().is_empty())
            .unwrap_or(std::path::Path::new("."));
        crate::format::create_dir(dir)?;
        let werr = |source| Error::Write {
            path: path.into(),
            source,
        };
        let merr = |e: mcap::McapError| Error::mcap(path, "MCAP writer", e);
        let (file, tmp) = crate::format::temp_builder()
            .suffix(".mcap")
            .tempfile_in(dir)
            .map_err(werr)?
            .into_parts();
        let mut writer = mcap::WriteOptions::new()
            .profile("kitti2pgm")
            .library(format!("kitti2pgm {}", env!("CARGO_PKG_VERSION")))
            .create(std::io::BufWriter::new(file))
            .map_err(merr)?;
        let channels = VizChannels::add(&mut writer).map_err(merr)?;
        Ok(VizFile {
            path: path.into(),
            writer,
            channels,
            tmp,
        })
    }

    /// Writes one frame ([`VizChannels::write`]).
    pub fn write(
        &mut self,
        v: &VizFrame,
        sequence: u32,
        log_time: u64,
    ) -> crate::error::Result<()> {
        (self.channels)
            .write(&mut self.writer, v, sequence, log_time)
            .map_err(|e| crate::error::Error::mcap(&self.path, "MCAP writer", e))
    }

    /// Finishes the file, flushes it and renames it into place.
    pub fn finish(mut self) -> crate::error::Result<()> {
        use crate::error::Error;
        let path = self.path.clone();
        let werr = |source| Error::Write {
            path: path.clone(),
            source,
        };
        (self.writer)
            .finish()
            .map_err(|e| Error::mcap(&path, "MCAP writer", e))?;
        let file = (self.writer.into_inner().into_inner()).map_err(|e| werr(e.into_error()))?;
        file.sync_data().map_err(werr)?;
        self.tmp.persist(&path).map_err(|e| werr(e.error))?;
        Ok(())
    }
}

impl VizChannels {
    /// Adds the schemas and channels.
    pub fn add<W: std::io::Write + std::io::Seek>(
        w: &mut mcap::Writer<W>,
    ) -> mcap::McapResult<VizChannels> {
        Ok(VizChannels {
            points: channel::<PointCloud, W>(w, POINTS_TOPIC)?,
            boxes: channel::<SceneUpdate, W>(w, BOXES_TOPIC)?,
            image: channel::<CompressedImage, W>(w, IMAGE_TOPIC)?,
        })
    }

    /// Writes one frame's visualisation messages.
    pub fn write<W: std::io::Write + std::io::Seek>(
        &self,
        w: &mut mcap::Writer<W>,
        v: &VizFrame,
        sequence: u32,
        log_time: u64,
    ) -> mcap::McapResult<()> {
        let header = |channel_id| mcap::records::MessageHeader {
            channel_id,
            sequence,
            log_time,
            publish_time: log_time,
        };
        w.write_to_known_channel(&header(self.points), &cloud(v, log_time).encode_to_vec())?;
        w.write_to_known_channel(&header(self.boxes), &scene(v, log_time).encode_to_vec())?;
        if let Some(png) = &v.png {
            let img = CompressedImage {
                timestamp: time(log_time),
                frame_id: format!("camera_{:02}", v.camera),
                data: png.clone().into(),
                format: "png".into(),
            };
            w.write_to_known_channel(&header(self.image), &img.encode_to_vec())?;
        }
        Ok(())
    }
}

/// The points: x, y, z, intensity float32; class, red, green, blue, alpha uint8 (21 bytes).
fn cloud(v: &VizFrame, log_time: u64) -> PointCloud {
    const STRIDE: usize = 21;
    let mut data = Vec::with_capacity(v.points.len() * STRIDE);
    for (p, i, c) in &v.points {
        for f in [p.x, p.y, p.z, *i] {
            data.extend_from_slice(&f.to_le_bytes());
        }
        let [r, g, b] = v.colour(*c);
        data.extend_from_slice(&[*c, r, g, b, 255]);
    }
    let field = |name: &str, offset: u32, ty: NumericType| PackedElementField {
        name: name.into(),
        offset,
        r#type: ty as i32,
    };
    let (f32_, u8_) = (NumericType::Float32, NumericType::Uint8);
    PointCloud {
        timestamp: time(log_time),
        frame_id: FRAME_ID.into(),
        pose: identity(),
        point_stride: STRIDE as u32,
        fields: vec![
            field("x", 0, f32_),
            field("y", 4, f32_),
            field("z", 8, f32_),
            field("intensity", 12, f32_),
            field("class", 16, u8_),
            field("red", 17, u8_),
            field("green", 18, u8_),
            field("blue", 19, u8_),
            field("alpha", 20, u8_),
        ],
        data: data.into(),
    }
}

/// The boxes, one translucent cube each in its class's colour; the previous frame's removed.
fn scene(v: &VizFrame, log_time: u64) -> SceneUpdate {
    let cubes = v
        .boxes
        .iter()
        .map(|b| {
            let t = b.pose.translation.vector;
            let q = b.pose.rotation;
            let [r, g, bl] = v.colour(b.class);
            let e = b.cuboid.half_extents * 2.0;
            CubePrimitive {
                pose: Some(Pose {
                    position: Some(Vector3 {
                        x: t.x as f64,
                        y: t.y as f64,
                        z: t.z as f64,
                    }),
                    orientation: Some(Quaternion {
                        x: q.i as f64,
                        y: q.j as f64,
                        z: q.k as f64,
                        w: q.w as f64,
                    }),
                }),
                size: Some(Vector3 {
                    x: e.x as f64,
                    y: e.y as f64,
                    z: e.z as f64,
                }),
                color: Some(Color {
                    r: r as f64 / 255.0,
                    g: g as f64 / 255.0,
                    b: bl as f64 / 255.0,
                    a: 0.4,
                }),
            }
        })
        .collect();
    SceneUpdate {
        deletions: vec![SceneEntityDeletion {
            timestamp: time(log_time),
            r#type: scene_entity_deletion::Type::All as i32,
            id: String::new(),
        }],
        entities: vec![SceneEntity {
            timestamp: time(log_time),
            frame_id: FRAME_ID.into(),
            id: "tracklets".into(),
            lifetime: Some(Duration::new(0, 0)),
            cubes,
            ..Default::default()
        }],
    }
}
