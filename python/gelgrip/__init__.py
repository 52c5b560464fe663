"""gelgrip from Python: the tactile pipeline, calibration, the gripper and recordings.

A thin layer over gelgrip's Rust crates (built with maturin from ``python/``): numpy
arrays in and out, the GIL released while anything processes, trains, waits or reads.
See ``docs/python.md`` in the repository.
"""

from gelgrip._gelgrip import (
    ConfigError,
    DataError,
    DecodeError,
    DeviceError,
    Frames,
    GelgripError,
    GraspHandle,
    Gripper,
    GripperError,
    GripperSet,
    Model,
    ModelError,
    PipelineError,
    Reconstruction,
    RecordedFrame,
    Recording,
    RecordingError,
    Sensor,
    SetIterator,
    __version__,
    evaluate,
    label,
    poisson,
    read_image,
    train,
)

__all__ = [
    "ConfigError",
    "DataError",
    "DecodeError",
    "DeviceError",
    "Frames",
    "GelgripError",
    "GraspHandle",
    "Gripper",
    "GripperError",
    "GripperSet",
    "Model",
    "ModelError",
    "PipelineError",
    "Reconstruction",
    "RecordedFrame",
    "Recording",
    "RecordingError",
    "Sensor",
    "SetIterator",
    "__version__",
    "evaluate",
    "label",
    "poisson",
    "read_image",
    "train",
]
