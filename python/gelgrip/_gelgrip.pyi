"""Type stubs of gelgrip's Rust extension module (re-exported by ``gelgrip``)."""

from typing import Iterator, List, Literal, Optional, Sequence, Tuple, TypedDict, Union

import numpy as np
import numpy.typing as npt

__version__: str

Frame = Union[npt.NDArray[np.uint8], bytes, bytearray, memoryview]
"""An H×W×3 uint8 array (any strides, in the sensor's colour order) or JPEG bytes."""

class GelgripError(Exception): ...
class ConfigError(GelgripError): ...
class ModelError(GelgripError): ...
class DecodeError(GelgripError): ...
class PipelineError(GelgripError): ...
class DataError(GelgripError): ...
class RecordingError(GelgripError): ...
class DeviceError(GelgripError): ...
class GripperError(GelgripError): ...

class ValidationReport(TypedDict):
    presses: int
    gx_mae: float
    gy_mae: float
    best_epoch: int
    train_loss: float
    validation_loss: float
    stopped_at_epoch: int
    epochs: int
    patience: int

class TrainReport(TypedDict):
    """``calibrate train --json``."""

    model: str
    input: str
    hidden: Optional[int]
    parameters: Optional[int]
    epochs: Optional[int]
    blur_px: Optional[int]
    loss: Optional[str]
    input_norm: Optional[str]
    train_presses: int
    test_presses: int
    train_gx_mae: float
    train_gy_mae: float
    test_gx_mae: float
    test_gy_mae: float
    ball_radius_mm: float
    test_sphere_radius_mm_median: Optional[float]
    train_s: float
    validation: Optional[ValidationReport]

class LabelledPress(TypedDict):
    file: str
    center_x_px: float
    center_y_px: float
    contact_radius_px: float
    score: float

class RejectedPress(TypedDict):
    file: str
    code: str
    reason: str

class LabelReport(TypedDict):
    """``calibrate label --json``."""

    labelled: int
    camera_noise: Optional[float]
    rejected: List[RejectedPress]
    presses: List[LabelledPress]

class PressSphere(TypedDict):
    file: str
    sphere_radius_mm: Optional[float]

class EvalReport(TypedDict):
    """``calibrate eval --json``."""

    gx_mae: float
    gy_mae: float
    depth_mae_mm: Optional[float]
    window_depth_mae_mm: Optional[float]
    mean_peak_depth_mm: Optional[float]
    window_missed_presses: Optional[int]
    presses: int
    pixels: int
    solver: str
    ball_radius_mm: float
    sphere_radius_mm_median: Optional[float]
    per_press: List[PressSphere]

class RecordingInfo(TypedDict):
    """``record info --json``."""

    records: int
    segments: int
    frames: int
    duration_s: float
    truncated_tail_bytes: int
    crc_errors: int
    dropped_records: int
    clean_end: bool
    transport: str
    sensors: List[str]
    format_version: int


class GraspResult(TypedDict):
    """The grasp's outcome: the HTTP API's ``POST /api/grasp`` answer."""

    grasped: bool
    status: List[str]
    final_force_n: float
    reason: str
    settled_force_n: Optional[float]  # under target_force_n="auto": the force it settled on

class SensorSlip(TypedDict):
    state: str  # "none", "incipient" or "gross"
    stick_ratio: float
    shear_mm: List[float]

class SensorReading(TypedDict):
    id: str
    in_contact: bool
    area_mm2: float
    max_depth_mm: float
    volume_mm3: float
    force_n: float
    slip: Optional[SensorSlip]  # None: unknown (a plain gel, or no marker dots under the contact)

class FingerState(TypedDict):
    phase: str
    force_n: float
    target_force_n: float

class ServoState(TypedDict):
    position_deg: float
    velocity_rpm: float
    current_ma: float
    temperature_c: float
    hardware_error: int
    moving: bool

class ReasonCounts(TypedDict):
    late: int
    incomplete: int
    out_of_window: int
    corrupt: int
    duplicate: int

class GateStats(TypedDict):
    sets: int
    set_rate_hz: float
    frames_in: int
    frames_out: int
    frames_reused: int
    drops: ReasonCounts
    sets_rejected: ReasonCounts

class Model:
    """A gradient model (a LUT or an MLP), as ``calibrate train``, ``transfer`` or
    ``bake`` wrote it."""

    @staticmethod
    def load(path: str) -> Model: ...
    def save(self, path: str) -> None: ...
    @property
    def kind(self) -> str: ...
    @property
    def input(self) -> str: ...
    @property
    def size(self) -> Tuple[int, int]: ...
    @property
    def mm_per_px(self) -> Optional[float]: ...
    @property
    def report(self) -> Optional[TrainReport]: ...

class Reconstruction:
    """One frame reconstructed (arrays read-only, over the result's own buffers)."""

    @property
    def depth_mm(self) -> npt.NDArray[np.float32]: ...
    @property
    def gradients(self) -> npt.NDArray[np.float32]: ...
    @property
    def contact(self) -> npt.NDArray[np.bool_]: ...
    @property
    def in_contact(self) -> bool: ...
    @property
    def area_mm2(self) -> float: ...
    @property
    def max_depth_mm(self) -> float: ...
    @property
    def volume_mm3(self) -> float: ...
    @property
    def centroid_px(self) -> Optional[Tuple[float, float]]: ...

class Sensor:
    """One sensor's pipeline, as ``gelgrip reconstruct`` runs it."""

    def __init__(
        self,
        model: Model,
        background: npt.NDArray[np.uint8],
        mm_per_px: Optional[float] = None,
        solver: str = "dct",
        color_order: str = "rgb",
        noise_frames: Optional[Union[npt.NDArray[np.uint8], Sequence[Frame]]] = None,
    ) -> None: ...
    def process(self, frame: Frame) -> Reconstruction: ...
    def process_many(self, frames: Union[npt.NDArray[np.uint8], Sequence[Frame]]) -> List[Reconstruction]: ...
    @property
    def mm_per_px(self) -> float: ...
    @property
    def size(self) -> Tuple[int, int]: ...

def poisson(gradients: npt.NDArray[np.floating], solver: str = "dst") -> npt.NDArray[np.float32]: ...
def read_image(path: str, color_order: str = "rgb") -> npt.NDArray[np.uint8]: ...
def label(in_dir: str, out_dir: str, ball_mm: float, mm_per_px: float) -> LabelReport: ...
def train(
    data_dir: str,
    model: str = "lut",
    *,
    input: Optional[str] = None,
    bins: int = 64,
    blur_px: Optional[int] = None,
    hidden: int = 32,
    epochs: int = 80,
    dropout: float = 0.0,
    learning_rate: float = 5e-3,
    patience: int = 20,
    seed: int = 1,
    loss: Optional[str] = None,
    input_norm: str = "standard",
) -> Model: ...
def evaluate(model: Model, data_dir: str, solver: Optional[str] = "dst") -> EvalReport: ...

class RecordedFrame:
    @property
    def sensor(self) -> int: ...
    @property
    def sensor_id(self) -> Optional[str]: ...
    @property
    def trigger_seq(self) -> int: ...
    @property
    def capture_us(self) -> int: ...
    @property
    def jpeg(self) -> bytes: ...
    def image(self, color_order: str = "rgb") -> npt.NDArray[np.uint8]: ...

class Frames(Iterator[RecordedFrame]):
    def __iter__(self) -> Frames: ...
    def __next__(self) -> RecordedFrame: ...

class Recording:
    def __init__(self, dir: str) -> None: ...
    def info(self) -> RecordingInfo: ...
    def frames(self, sensor: Optional[Union[int, str]] = None) -> Frames: ...
    @property
    def sensors(self) -> List[str]: ...

class GripperSet:
    """One gated set's report."""

    @property
    def t_s(self) -> float: ...
    @property
    def trigger_seq(self) -> Optional[int]: ...
    @property
    def dropped(self) -> int: ...
    @property
    def sensors(self) -> List[Optional[SensorReading]]: ...
    @property
    def fingers(self) -> List[FingerState]: ...
    @property
    def servos(self) -> List[ServoState]: ...
    @property
    def gate(self) -> GateStats: ...

class SetIterator(Iterator[GripperSet]):
    def __iter__(self) -> SetIterator: ...
    def __next__(self) -> GripperSet: ...

class GraspHandle:
    def wait(self, timeout: Optional[float] = None) -> GraspResult: ...
    def done(self) -> bool: ...

class Gripper:
    """The gripper on the runtime the CLI runs (``config`` None: the embedded simulated
    gripper)."""

    def __init__(
        self,
        config: Optional[str] = None,
        clock: str = "real",
        scene: Optional[str] = None,
        queue: int = 64,
    ) -> None: ...
    def __enter__(self) -> Gripper: ...
    def __exit__(self, *args: object) -> bool: ...
    def close(self) -> Optional[dict[str, object]]: ...
    def next_set(self, timeout: Optional[float] = None) -> GripperSet: ...
    def sets(self) -> SetIterator: ...
    def grasp(
        self,
        target_force_n: Union[float, Literal["auto"]] = 1.5,
        speed_deg_s: float = 15.0,
        timeout_s: float = 20.0,
        fingers: Optional[Sequence[int]] = None,
        current_limit_ma: Optional[float] = None,
    ) -> GraspResult: ...
    def start_grasp(
        self,
        target_force_n: Union[float, Literal["auto"]] = 1.5,
        speed_deg_s: float = 15.0,
        timeout_s: float = 20.0,
        fingers: Optional[Sequence[int]] = None,
        current_limit_ma: Optional[float] = None,
    ) -> GraspHandle: ...
    def release(self) -> None: ...
    def stop(self) -> None: ...
    def estop(self) -> None: ...
    @property
    def closed(self) -> bool: ...
