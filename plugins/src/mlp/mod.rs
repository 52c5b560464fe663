//! Gradient model `mlp`: a per-pixel multi-layer perceptron from colour and position to
//! (Gx, Gy), as in the paper's section III.
//!
//! Inputs per pixel are the key colour (the difference image, or the raw capture with
//! `input = raw`) after the model's per-channel transfer (`key × gain_rgb + offset_rgb`),
//! scaled to about ±1, and the normalised position x/W, y/H. Three hidden layers of
//! `hidden` units with tanh; two outputs. The gradient of a pixel is the network's output
//! minus its output for the background at that pixel (difference 0, or the reference
//! colour), so a pixel that matches the background has zero gradient exactly, whatever the
//! network's bias (gs_sdk removes the background in gradient space the same way).
//!
//! - [`net`]: batched CPU inference with candle and a fast tanh;
//! - [`train`]: training with candle-nn (Adam, L1 loss, dropout);
//! - [`transfer`]: zero-shot transfer to a sibling sensor from one press;
//! - [`bake`]: the network baked into a (tiled) LUT.

pub mod bake;
mod file;
pub mod net;
pub mod train;
pub mod transfer;

use thiserror::Error;

use crate::lut::Input;
use crate::model_file::ModelFileError;

pub use net::MlpNet;

/// Hidden layer width used unless told otherwise (gs_sdk's, and the fastest that matches
/// the 64-wide network's accuracy on simulated presses; docs/calibration.md).
pub const DEFAULT_HIDDEN: usize = 32;
/// Inputs per pixel: three colour channels and x, y.
pub const INPUTS: usize = 5;

/// MLP training, inference or transfer failed.
#[derive(Debug, Error)]
pub enum MlpError {
    /// The tensor library failed (shapes, allocation).
    #[error("mlp: {0}")]
    Candle(#[from] candle_core::Error),
    /// Reading or writing the model file.
    #[error(transparent)]
    File(#[from] ModelFileError),
    /// Nothing to train or fit on.
    #[error("mlp: {0}")]
    NoData(String),
}

/// One dense layer: `out × in` weights (row-major) and `out` biases.
#[derive(Debug, Clone, PartialEq)]
pub struct Layer {
    /// Inputs.
    pub inputs: usize,
    /// Outputs.
    pub outputs: usize,
    /// Weights, `outputs × inputs`, row-major (candle-nn's `Linear` layout).
    pub weight: Vec<f32>,
    /// Biases.
    pub bias: Vec<f32>,
}

/// A trained MLP gradient model.
#[derive(Debug, Clone, PartialEq)]
pub struct MlpModel {
    /// Key kind.
    pub input: Input,
    /// Image size it was trained at (positions are normalised by it).
    pub width: usize,
    /// Image size it was trained at.
    pub height: usize,
    /// Hidden layer width.
    pub hidden: usize,
    /// Input → hidden → hidden → hidden → output.
    pub layers: Vec<Layer>,
    /// Per-channel offset added to the key, grey levels (zero-shot transfer).
    pub offset_rgb: [f32; 3],
    /// Per-channel gain applied to the key before the offset (1 unless transferred with
    /// `--fit offset-gain`).
    pub gain_rgb: [f32; 3],
    /// Pixel size on the gel of the presses it was trained on, mm (metadata `mm_per_px`;
    /// `None` for a file written before it was recorded).
    pub mm_per_px: Option<f64>,
    /// Which slope its output at a pixel is (metadata `slopes`).
    pub slopes: crate::model_file::Slopes,
}

/// Grey levels per unit of network input.
pub const KEY_SCALE: f32 = 128.0;

impl MlpModel {
    /// The network input for key colour `rgb` at pixel `(x, y)`.
    #[inline]
    pub fn features(&self, rgb: [f32; 3], x: usize, y: usize) -> [f32; INPUTS] {
        let centre = self.input.centre();
        let k = |c: usize| {
            let v = rgb[c] * self.gain_rgb[c] + self.offset_rgb[c];
            // A NaN key (never from u8 frames) must not reach the network.
            if v.is_finite() {
                ((v - centre) / KEY_SCALE).clamp(-4.0, 4.0)
            } else {
                0.0
            }
        };
        [
            k(0),
            k(1),
            k(2),
            x as f32 / self.width.max(1) as f32,
            y as f32 / self.height.max(1) as f32,
        ]
    }

    /// Parameters in the network.
    pub fn parameters(&self) -> usize {
        self.layers
            .iter()
            .map(|l| l.weight.len() + l.bias.len())
            .sum()
    }

    /// The candle network for inference.
    pub fn net(&self) -> Result<MlpNet, MlpError> {
        MlpNet::new(self)
    }
}

#[cfg(test)]
mod tests;
