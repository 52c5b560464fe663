//! gelgrip's typed errors as Python exceptions: one class per kind, all under
//! `gelgrip.GelgripError`, so a caller can catch one kind or every gelgrip failure.
//! Bad arguments (a wrong dtype, shape or size) are Python's own `ValueError`, and a
//! missing file its `FileNotFoundError`.

use std::path::Path;

use pyo3::exceptions::{PyException, PyFileNotFoundError, PyValueError};
use pyo3::prelude::*;

use gelgrip_plugins::decode::DecodeError as RustDecodeError;
use gelgrip_plugins::image::ImageError;
use gelgrip_plugins::pipeline::PipelineError as RustPipelineError;
use gelgrip_plugins::reconstruct::ReconstructError;

pyo3::create_exception!(
    gelgrip,
    GelgripError,
    PyException,
    "Every error gelgrip raises of its own."
);
pyo3::create_exception!(
    gelgrip,
    ConfigError,
    GelgripError,
    "A configuration, scene, task or option gelgrip cannot use."
);
pyo3::create_exception!(
    gelgrip,
    ModelError,
    GelgripError,
    "A gradient model file that cannot be read, or a model that cannot run."
);
pyo3::create_exception!(
    gelgrip,
    DecodeError,
    GelgripError,
    "An image (JPEG or PNG) that cannot be decoded."
);
pyo3::create_exception!(
    gelgrip,
    PipelineError,
    GelgripError,
    "A frame the tactile pipeline could not process."
);
pyo3::create_exception!(
    gelgrip,
    DataError,
    GelgripError,
    "A press dataset or calibration input that cannot be used."
);
pyo3::create_exception!(
    gelgrip,
    RecordingError,
    GelgripError,
    "A recording that cannot be read."
);
pyo3::create_exception!(
    gelgrip,
    DeviceError,
    GelgripError,
    "The hub, a sensor or a servo failed."
);
pyo3::create_exception!(
    gelgrip,
    GripperError,
    GelgripError,
    "A gripper command that cannot be carried out: the gripper is closed or its run \
     loop has stopped, a task owns it, or the request is out of range."
);

/// Add the exception classes to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("GelgripError", py.get_type::<GelgripError>())?;
    m.add("ConfigError", py.get_type::<ConfigError>())?;
    m.add("ModelError", py.get_type::<ModelError>())?;
    m.add("DecodeError", py.get_type::<DecodeError>())?;
    m.add("PipelineError", py.get_type::<PipelineError>())?;
    m.add("DataError", py.get_type::<DataError>())?;
    m.add("RecordingError", py.get_type::<RecordingError>())?;
    m.add("DeviceError", py.get_type::<DeviceError>())?;
    m.add("GripperError", py.get_type::<GripperError>())?;
    Ok(())
}

/// `FileNotFoundError` naming `what` when `path` is not a file.
pub fn require_file(path: &Path, what: &str) -> PyResult<()> {
    if path.is_file() {
        Ok(())
    } else {
        Err(PyFileNotFoundError::new_err(format!(
            "{what} {}: no such file",
            path.display()
        )))
    }
}

/// `FileNotFoundError` naming `what` when `path` is not a directory.
pub fn require_dir(path: &Path, what: &str) -> PyResult<()> {
    if path.is_dir() {
        Ok(())
    } else {
        Err(PyFileNotFoundError::new_err(format!(
            "{what} {}: no such directory",
            path.display()
        )))
    }
}

/// A decode failure of the pipeline or of an image file.
pub fn decode(e: &RustDecodeError) -> PyErr {
    DecodeError::new_err(e.to_string())
}

/// The pipeline's errors: a corrupt frame is a `DecodeError`, a frame of the wrong size a
/// `ValueError`, the model's failure a `ModelError`.
pub fn pipeline(e: &RustPipelineError) -> PyErr {
    match e {
        RustPipelineError::Decode(d) => decode(d),
        RustPipelineError::FrameSize { .. } => PyValueError::new_err(e.to_string()),
        RustPipelineError::Model(_) => ModelError::new_err(e.to_string()),
        RustPipelineError::NoReference => PipelineError::new_err(e.to_string()),
    }
}

/// A reconstruction's errors: sizes and pixel sizes are `ValueError`s.
pub fn reconstruct(e: &ReconstructError) -> PyErr {
    match e {
        ReconstructError::Pipeline(p) => pipeline(p),
        ReconstructError::BackgroundSize { .. }
        | ReconstructError::ImageSize { .. }
        | ReconstructError::PixelSize(_) => PyValueError::new_err(e.to_string()),
    }
}

/// An image that could not be read or decoded.
pub fn image(e: &ImageError) -> PyErr {
    match e {
        ImageError::Io { source, .. } if source.kind() == std::io::ErrorKind::NotFound => {
            PyFileNotFoundError::new_err(e.to_string())
        }
        _ => DecodeError::new_err(e.to_string()),
    }
}

/// The library's errors, by the part that failed; the message is the whole chain.
pub fn gelgrip(e: &gelgrip::Error) -> PyErr {
    use gelgrip::Error as E;
    let message = chain(e);
    match root(e) {
        E::Usage(_) | E::Config(_) | E::TaskRunning { .. } | E::NoSensor { .. } => {
            ConfigError::new_err(message)
        }
        E::Open(_) | E::Hub(_) | E::Servo(_) | E::Capture(_) | E::Runtime(_) => {
            DeviceError::new_err(message)
        }
        E::Dataset(_) | E::Calibrate(_) | E::Collect(_) | E::SensorCamera(_) => {
            DataError::new_err(message)
        }
        E::ModelFile(_) | E::Mlp(_) | E::ModelKind { .. } => ModelError::new_err(message),
        E::Pipeline(p) => pipeline(p),
        E::Record(_) | E::Recording(_) | E::RecordingStart(_) => RecordingError::new_err(message),
        E::Io { source, .. } if source.kind() == std::io::ErrorKind::NotFound => {
            PyFileNotFoundError::new_err(message)
        }
        E::Io { .. } => pyo3::exceptions::PyOSError::new_err(message),
        _ => GelgripError::new_err(message),
    }
}

/// The error under every context.
fn root(e: &gelgrip::Error) -> &gelgrip::Error {
    match e {
        gelgrip::Error::Context { source, .. } => root(source),
        other => other,
    }
}

/// `e` and its sources, joined by `: `.
fn chain(e: &dyn std::error::Error) -> String {
    let mut text = e.to_string();
    let mut source = e.source();
    while let Some(s) = source {
        let next = s.to_string();
        if !text.ends_with(&next) {
            text = format!("{text}: {next}");
        }
        source = s.source();
    }
    text
}
