//! ROS 2 bags from Python: the topics, and a topic's point clouds streamed frame by frame, so a
//! loader can project a user's own recordings on the fly (the bag is never held in memory).

use std::path::PathBuf;
use std::sync::Mutex;

use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use kitti2pgm::source::bag::{Bag, Messages, Next};
use kitti2pgm::source::pointcloud2::{PointCloud2, TYPE_NAME};

use crate::py_err;
use crate::readers::scan_array;

/// The topics of a ROS 2 bag (its directory with metadata.yaml, or a .mcap file): a list of
/// dicts with topic, type, encoding and messages.
#[pyfunction]
fn bag_topics<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyList>> {
    let topics = py
        .detach(|| Bag::open(&path).and_then(|b| b.topics()))
        .map_err(py_err)?;
    let out = PyList::empty(py);
    for t in topics {
        let d = PyDict::new(py);
        d.set_item("topic", t.name)?;
        d.set_item("type", t.type_name)?;
        d.set_item("encoding", t.encoding)?;
        d.set_item("messages", t.messages)?;
        out.append(d)?;
    }
    Ok(out)
}

/// The frames of one PointCloud2 topic, streamed (see [`read_bag`]).
#[pyclass(module = "kitti2pgm")]
pub struct BagFrames {
    messages: Mutex<Messages>,
    topic: String,
    /// Messages on the topic.
    #[pyo3(get)]
    messages_total: u64,
    /// Messages on the topic of other types than PointCloud2 (passed over).
    #[pyo3(get)]
    skipped_other_types: u64,
}

#[pymethods]
impl BagFrames {
    fn __iter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    fn __len__(&self) -> usize {
        self.messages_total as usize
    }

    fn __next__<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let decoded = py.detach(|| {
            // Decoded where the reader holds it (not copied out first).
            let mut messages = self.messages.lock().expect("not poisoned");
            let next = messages.next_with(|m| {
                let what = m
                    .file
                    .join(format!("message {} of {}", m.index, self.topic));
                let msg = PointCloud2::decode(m.data, &what)?;
                let cloud = msg.cloud(&what)?;
                Ok((m.index, msg.stamp, msg.frame_id.clone(), cloud))
            })?;
            Some(next)
        });
        let Some(decoded) = decoded else {
            return Ok(None);
        };
        let (index, stamp, frame_id, cloud) = match decoded.map_err(py_err)? {
            Next::Message(m) => m.map_err(py_err)?,
            // The frames of a damaged chunk fail together; the next call goes on after it.
            Next::Lost(lost) => {
                let frames: Vec<String> =
                    lost.messages.iter().map(|m| m.index.to_string()).collect();
                return Err(pyo3::exceptions::PyValueError::new_err(format!(
                    "{}: {}; frames lost: {} (iterating again goes on after it)",
                    lost.file.display(),
                    lost.damage.error,
                    if frames.is_empty() {
                        "none of the topic's by the bag's index".into()
                    } else {
                        frames.join(", ")
                    }
                )));
            }
        };
        let mut scan = cloud;
        let ring = scan.ring.take();
        let d = PyDict::new(py);
        d.set_item("index", index)?;
        d.set_item("stamp", stamp.nanos())?;
        d.set_item("frame_id", frame_id)?;
        d.set_item("points", scan_array(py, &scan)?)?;
        d.set_item("ring", ring.map(|r| PyArray1::from_vec(py, r)))?;
        d.set_item("file_index", PyArray1::from_vec(py, scan.file_indices()))?;
        d.set_item("file_points", scan.file_len)?;
        d.set_item("dropped", scan.dropped.len())?;
        Ok(Some(d))
    }
}

/// Streams the point clouds of a ROS 2 bag's sensor_msgs/msg/PointCloud2 topic (a bag directory
/// with metadata.yaml, or a .mcap file; CDR in either byte order). Each frame is a dict like
/// read_cloud's (points (N, 4) float32 x, y, z, intensity; ring (N,) uint16 or None;
/// file_index; file_points; dropped) with index (its place on the topic), stamp (header stamp,
/// nanoseconds) and frame_id. A missing or wrong topic raises ValueError listing the bag's
/// point cloud topics; messages of other types on the topic are passed over (counted in
/// skipped_other_types); a message that does not decode, or a chunk that fails its CRC or its
/// decompression (its frames together), raises ValueError when reached, and iterating again
/// goes on after it.
#[pyfunction]
#[pyo3(signature = (path, topic=None))]
fn read_bag(py: Python<'_>, path: PathBuf, topic: Option<String>) -> PyResult<BagFrames> {
    let (bag, t, skipped_other_types) = py
        .detach(|| {
            let bag = Bag::open(&path)?;
            let t = bag.topic(topic.as_deref(), TYPE_NAME)?;
            let others = bag.other_types_on(&t.name, TYPE_NAME)?;
            Ok((bag, t, others))
        })
        .map_err(py_err)?;
    Ok(BagFrames {
        messages: Mutex::new(bag.messages(&t)),
        topic: t.name,
        messages_total: t.messages,
        skipped_other_types,
    })
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(bag_topics, m)?)?;
    m.add_function(wrap_pyfunction!(read_bag, m)?)?;
    m.add_class::<BagFrames>()?;
    Ok(())
}
