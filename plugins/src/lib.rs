//! gelgrip's sensing plugins: the per-sensor tactile pipeline that turns a JPEG frame into
//! gradients, depth in mm and contact.
//!
//! - [`pipeline`]: the stages wired per sensor, with their buffers;
//! - [`decode`], [`undistort`], [`lut`], [`mlp`], [`poisson`], [`contact`]: the stages
//!   ([`gradient`] holds whichever gradient model a sensor uses); [`halves`] splits a
//!   frame's row-wise stages over two cores for the frame on the critical path;
//! - [`dataset`], [`image`], [`model_file`]: the press dataset and model file formats;
//! - [`npy`]: NumPy `.npy` gradients and depth maps;
//! - [`reconstruct`]: the pipeline applied to a user's own images (`gelgrip reconstruct`);
//! - [`sensing`]: the pipelines of every sensor as the runtime's `Sensing` port.

pub mod calibrate;
pub mod config;
pub mod contact;
pub mod dataset;
pub mod decode;
pub mod gradient;
pub mod halves;
pub mod image;
pub mod lut;
pub mod markers;
pub mod mlp;
pub mod model_file;
pub mod npy;
pub mod pipeline;
pub mod poisson;
pub mod reconstruct;
pub mod sensing;
pub mod undistort;
