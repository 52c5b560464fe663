//! gelgrip from Python: the extension module `gelgrip._gelgrip`, a thin conversion layer
//! over the library crates (the `gelgrip` package in `python/gelgrip` re-exports it with its
//! type stubs).
//!
//! - [`sensor`]: `Model`, `Sensor`, `Reconstruction` and `poisson` (the plugins' pipeline);
//! - [`calibration`]: `label`, `train` and `evaluate` (the library's calibration calls);
//! - [`recording`]: `Recording`, its frames and `record info`;
//! - [`gripper`]: `Gripper` on the runtime the CLI runs, its set reports and grasps;
//! - [`images`]: `read_image` (PNG and JPEG files through gelgrip's own decoders);
//! - [`arrays`]: numpy in (frames of any strides, JPEG bytes) and out (read-only arrays
//!   over the results' own buffers);
//! - [`errors`]: gelgrip's typed errors as Python exceptions.
//!
//! pyo3's macros expand to `unsafe` code, which the workspace denies elsewhere.
#![allow(unsafe_code)]

use pyo3::prelude::*;

pub mod arrays;
pub mod calibration;
pub mod errors;
pub mod gripper;
pub mod images;
pub mod recording;
pub mod sensor;

/// The module.
#[pymodule]
fn _gelgrip(m: &Bound<'_, PyModule>) -> PyResult<()> {
    errors::register(m)?;
    m.add_class::<sensor::Model>()?;
    m.add_class::<sensor::Sensor>()?;
    m.add_class::<sensor::Reconstruction>()?;
    m.add_function(wrap_pyfunction!(sensor::poisson, m)?)?;
    m.add_function(wrap_pyfunction!(images::read_image, m)?)?;
    m.add_function(wrap_pyfunction!(calibration::label, m)?)?;
    m.add_function(wrap_pyfunction!(calibration::train, m)?)?;
    m.add_function(wrap_pyfunction!(calibration::evaluate, m)?)?;
    m.add_class::<recording::Recording>()?;
    m.add_class::<recording::Frames>()?;
    m.add_class::<recording::RecordedFrame>()?;
    m.add_class::<gripper::Gripper>()?;
    m.add_class::<gripper::GripperSet>()?;
    m.add_class::<gripper::GraspHandle>()?;
    m.add_class::<gripper::SetIterator>()?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
