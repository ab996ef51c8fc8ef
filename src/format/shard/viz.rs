//! WRITE: visualisation topics in a shard (`--viz`), in Foxglove's well-known schemas with JSON
//! encoding, so that Foxglove opens them directly: the labelled point cloud
//! (`foxglove.PointCloud`, coloured by class through its `red`/`green`/`blue`/`alpha` fields),
//! the tracklet boxes (`foxglove.SceneUpdate`, one cube per box) and the camera image
//! (`foxglove.CompressedImage`, the PNG as it is on disk). Everything is in the `velodyne` frame.

use std::collections::BTreeMap;

use base64::Engine as _;
use serde_json::json;

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

fn schema(title: &str, props: &[&str]) -> Vec<u8> {
    let properties: serde_json::Map<String, serde_json::Value> =
        props.iter().map(|p| (p.to_string(), json!({}))).collect();
    serde_json::to_vec(&json!({ "title": title, "type": "object", "properties": properties }))
        .expect("static JSON")
}

fn time(ns: u64) -> serde_json::Value {
    json!({ "sec": ns / 1_000_000_000, "nsec": ns % 1_000_000_000 })
}

impl VizChannels {
    /// Adds the schemas and channels.
    pub fn add<W: std::io::Write + std::io::Seek>(
        w: &mut mcap::Writer<W>,
    ) -> mcap::McapResult<VizChannels> {
        let none = BTreeMap::new();
        let s = w.add_schema(
            "foxglove.PointCloud",
            "jsonschema",
            &schema(
                "foxglove.PointCloud",
                &[
                    "timestamp",
                    "frame_id",
                    "pose",
                    "point_stride",
                    "fields",
                    "data",
                ],
            ),
        )?;
        let points = w.add_channel(s, POINTS_TOPIC, "json", &none)?;
        let s = w.add_schema(
            "foxglove.SceneUpdate",
            "jsonschema",
            &schema("foxglove.SceneUpdate", &["deletions", "entities"]),
        )?;
        let boxes = w.add_channel(s, BOXES_TOPIC, "json", &none)?;
        let s = w.add_schema(
            "foxglove.CompressedImage",
            "jsonschema",
            &schema(
                "foxglove.CompressedImage",
                &["timestamp", "frame_id", "data", "format"],
            ),
        )?;
        let image = w.add_channel(s, IMAGE_TOPIC, "json", &none)?;
        Ok(VizChannels {
            points,
            boxes,
            image,
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
        let b64 = base64::engine::general_purpose::STANDARD;
        let header = |channel_id| mcap::records::MessageHeader {
            channel_id,
            sequence,
            log_time,
            publish_time: log_time,
        };
        // x, y, z, intensity: float32 (7); class, red, green, blue, alpha: uint8 (1). 21 bytes.
        let mut data = Vec::with_capacity(v.points.len() * 21);
        for (p, i, c) in &v.points {
            for f in [p.x, p.y, p.z, *i] {
                data.extend_from_slice(&f.to_le_bytes());
            }
            let [r, g, b] = v.colour(*c);
            data.extend_from_slice(&[*c, r, g, b, 255]);
        }
        let field = |name: &str, offset: u32, ty: u32| json!({ "name": name, "offset": offset, "type": ty });
        let cloud = json!({
            "timestamp": time(log_time),
            "frame_id": FRAME_ID,
            "pose": { "position": { "x": 0.0, "y": 0.0, "z": 0.0 }, "orientation": { "x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0 } },
            "point_stride": 21,
            "fields": [field("x", 0, 7), field("y", 4, 7), field("z", 8, 7), field("intensity", 12, 7),
                       field("class", 16, 1), field("red", 17, 1), field("green", 18, 1), field("blue", 19, 1), field("alpha", 20, 1)],
            "data": b64.encode(&data),
        });
        w.write_to_known_channel(
            &header(self.points),
            &serde_json::to_vec(&cloud).expect("JSON"),
        )?;
        let cubes: Vec<serde_json::Value> = v
            .boxes
            .iter()
            .map(|b| {
                let t = b.pose.translation.vector;
                let q = b.pose.rotation;
                let [r, g, bl] = v.colour(b.class);
                let e = b.cuboid.half_extents * 2.0;
                json!({
                    "pose": { "position": { "x": t.x, "y": t.y, "z": t.z }, "orientation": { "x": q.i, "y": q.j, "z": q.k, "w": q.w } },
                    "size": { "x": e.x, "y": e.y, "z": e.z },
                    "color": { "r": r as f64 / 255.0, "g": g as f64 / 255.0, "b": bl as f64 / 255.0, "a": 0.4 },
                })
            })
            .collect();
        let scene = json!({
            "deletions": [{ "timestamp": time(log_time), "type": 1, "id": "" }],
            "entities": [{
                "timestamp": time(log_time), "frame_id": FRAME_ID, "id": "tracklets",
                "lifetime": { "sec": 0, "nsec": 0 }, "frame_locked": false, "metadata": [],
                "arrows": [], "cubes": cubes, "spheres": [], "cylinders": [], "lines": [],
                "triangles": [], "texts": [], "models": [],
            }],
        });
        w.write_to_known_channel(
            &header(self.boxes),
            &serde_json::to_vec(&scene).expect("JSON"),
        )?;
        if let Some(png) = &v.png {
            let img = json!({
                "timestamp": time(log_time),
                "frame_id": format!("camera_{:02}", v.camera),
                "data": b64.encode(png),
                "format": "png",
            });
            w.write_to_known_channel(
                &header(self.image),
                &serde_json::to_vec(&img).expect("JSON"),
            )?;
        }
        Ok(())
    }
}
