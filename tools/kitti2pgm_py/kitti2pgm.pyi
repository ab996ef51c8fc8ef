"""Type stubs of kitti2pgm's native module (the Rust library from Python).

One dtype rule for every array argument: numpy arrays of any real numeric dtype are accepted and
converted (one copy): points to float32; integer arrays (labels, rings, instance) to their type
when every value fits, else ValueError; float arrays are refused where integers are expected;
bool arrays only where bools are. Fortran-ordered and strided arrays are read in their logical
order. Paths are str or os.PathLike.
"""

from os import PathLike
from pathlib import Path
from typing import Any, Callable, Dict, Iterator, List, Optional, Tuple, Union

import numpy as np
import numpy.typing as npt

__version__: str
LASERS: int
SENSORS: Dict[str, int]
"""Every built-in sensor (``project(sensor=...)``, ``convert --sensor``) with its beam count."""
MAX_RANGE_M: float
PRESETS: Dict[str, Dict[str, Any]]
"""Every map preset by name (squeezeseg, rangenet, full): rows, cols, fov_deg, fov_up_deg,
fov_down_deg, row_mode; the library's table, the one the CLI's --preset reads."""

_Path = Union[str, "PathLike[str]"]
_Array = npt.NDArray[Any]
Frame = Dict[str, Any]
"""A loaded frame: id, file_len, points (N, 4) float32, file_index (N,) uint32, ring (N,) uint8 or None,
column (N,) uint16 or None (Ouster's own columns, with ouster_columns), label (N,) uint8, instance (N,) uint16,
annotated, boxes, rgb (N, 3) float32 or None,
rgb_valid (N,) bool or None."""
MapDict = Dict[str, Any]
"""A projected map: map (H, W, C) float32, channels, mask (H, W) bool, label (H, W) uint8,
instance (H, W) uint16, rgb_valid (H, W) bool or None, row / col (N,) int32 or None,
point_index (H, W) int32 or None, stats."""

def project(
    points: _Array,
    *,
    preset: Optional[str] = None,
    rows: Optional[int] = None,
    cols: Optional[int] = None,
    fov_deg: Optional[float] = None,
    fov_up_deg: Optional[float] = None,
    fov_down_deg: Optional[float] = None,
    row_mode: Optional[str] = None,
    rings: Optional[_Array] = None,
    beams: Optional[int] = None,
    sensor: Optional[str] = None,
    sensor_pose: Optional[str] = None,
    ouster_columns: bool = False,
    labels: Optional[_Array] = None,
    instance: Optional[_Array] = None,
    rgb: Optional[_Array] = None,
    rgb_valid: Optional[_Array] = None,
    rotate_deg: float = 0.0,
    scale: float = 1.0,
    flip: bool = False,
    jitter: float = 0.0,
    drop: float = 0.0,
    seed: int = 0,
    point_cells: bool = True,
    threads: int = 1,
) -> MapDict:
    """The map of ``preset`` (squeezeseg when None; ``PRESETS`` holds the numbers), each value
    given in its place."""
def rings(points: _Array) -> Optional[npt.NDArray[np.uint8]]: ...
def unproject(
    pred: _Array,
    row: _Array,
    col: _Array,
    points: _Array,
    cell_range: Optional[_Array] = None,
    *,
    method: str = "knn",
    class_map: str = "semantic-kitti",
    k: int = 5,
    window: int = 5,
    sigma: float = 1.0,
    cutoff: float = 1.0,
    wrap_columns: bool = False,
) -> npt.NDArray[np.int16]: ...
def point_prediction_path(out: _Path, frame: str) -> Path: ...
def write_point_predictions(
    out: _Path, frame: str, classes: _Array, *, class_map: str
) -> Tuple[Path, int]: ...
def label_points(
    points: _Array,
    boxes: List[Dict[str, Any]],
    *,
    background: int = 0,
    class_map: Optional[str] = None,
    unknown_class: Optional[str] = None,
    margin: float = 0.0,
) -> Tuple[npt.NDArray[np.uint8], npt.NDArray[np.uint16]]: ...
def read_scan(path: _Path, *, with_file_index: bool = False) -> Any: ...
def read_cloud(path: _Path, *, fields: Optional[str] = None) -> Dict[str, Any]: ...
def read_boxes(
    path: _Path,
    format: str,
    *,
    origin: Optional[str] = None,
    sizes: Optional[str] = None,
    angles: Optional[str] = None,
    sensor_pose: Optional[str] = None,
) -> Dict[str, Any]: ...
def bag_topics(path: _Path) -> List[Dict[str, Any]]: ...

class BagFrames:
    """The frames of one PointCloud2 topic of a ROS 2 bag, streamed: each a dict like
    read_cloud's with index, stamp (header stamp, ns) and frame_id."""

    messages_total: int
    def __iter__(self) -> "BagFrames": ...
    def __next__(self) -> Dict[str, Any]: ...
    def __len__(self) -> int: ...

def read_bag(path: _Path, topic: Optional[str] = None) -> BagFrames: ...
def read_point_labels(path: _Path) -> npt.NDArray[np.uint32]: ...
def read_calibration(date_dir: _Path) -> Dict[str, Any]: ...
def read_frame_calibration(path: _Path) -> Dict[str, Any]: ...
def read_tracklets(path: _Path) -> Any: ...
def read_object_labels(path: _Path) -> List[Dict[str, Any]]: ...
def class_map(name: str = "kitti-paper-4") -> Dict[str, Any]: ...

MODEL_METADATA_KEY: str
"""The ONNX metadata key of the map record a model carries (``kitti2pgm infer`` reads it)."""

def model_metadata(
    map: str,
    channels: List[str],
    producer: str = "",
    *,
    input: str = "tensor",
    labels_output: Optional[str] = "labels",
    logits_output: Optional[str] = "logits",
) -> Tuple[str, str]: ...

class Model:
    """A trained ONNX model opened in ONNX Runtime with the map it records."""

    def __init__(self, path: _Path, *, onnxruntime: Optional[_Path] = None, threads: int = 0) -> None: ...
    @property
    def digest(self) -> str: ...
    @property
    def spec(self) -> Dict[str, Any]: ...
    @staticmethod
    def from_record(record: str, *, name: str = "record") -> "Model":
        """The record alone (model_metadata's value), without a graph: run its maps with runner=."""
        ...
    def predict_file(
        self, path: _Path, *, method: str = "knn", runner: Optional[Callable[[np.ndarray], Any]] = None
    ) -> Dict[str, Any]:
        """{"classes": (N,) int16 per point in file order (-1 outside the map), "map": (H, W) uint8}."""
        ...
    def predict(
        self,
        points: np.ndarray,
        *,
        ring: Optional[np.ndarray] = None,
        method: str = "knn",
        runner: Optional[Callable[[np.ndarray], Any]] = None,
    ) -> Dict[str, Any]:
        """points (N, 4) float32 x y z intensity, ring (N,) uint16: as predict_file, in the points' order."""
        ...

class Dataset:
    def __init__(
        self,
        root: _Path,
        *,
        dataset: Optional[str] = None,
        class_map: Optional[str] = None,
        rgb_camera: Optional[int] = None,
        sampling: str = "nearest",
        all_frames: bool = False,
        sensor: Optional[str] = None,
        ring_order: str = "bottom-up",
        sensor_pose: Optional[str] = None,
        ouster_columns: bool = False,
        fields: Optional[str] = None,
        source: Optional[str] = None,
    ) -> None: ...
    @property
    def frames(self) -> List[str]: ...
    @property
    def layout(self) -> str: ...
    @property
    def class_map(self) -> Dict[str, Any]: ...
    @property
    def failed(self) -> List[Tuple[str, str]]: ...
    def __len__(self) -> int: ...
    def __getitem__(self, frame: Union[int, str]) -> Frame: ...
    def __iter__(self) -> Iterator[Frame]: ...
    def load(self, frame: Union[int, str]) -> Frame: ...
    def project(
        self,
        frame: Union[int, str],
        *,
        preset: Optional[str] = None,
        rows: Optional[int] = None,
        cols: Optional[int] = None,
        fov_deg: Optional[float] = None,
        fov_up_deg: Optional[float] = None,
        fov_down_deg: Optional[float] = None,
        row_mode: Optional[str] = None,
    ) -> MapDict:
        """The frame projected as ``kitti2pgm convert`` projects it: ``preset`` defaults to
        convert's for the source (full for SemanticKITTI, squeezeseg otherwise)."""
