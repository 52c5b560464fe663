//! An MLP baked into a LUT: the network evaluated once at every colour bin's centre, per
//! spatial tile, so inference becomes table reads ([`LutModel::predict_at`] interpolates
//! between tiles). The table stores the network's output minus its output for a zero
//! difference at the tile centre, the same background subtraction as live inference, and
//! includes the model's transfer (offset and gain), so the baked LUT has none of its own.
//!
//! Only difference-input models can be baked: a raw-input model subtracts the background's
//! colour at each pixel, which a colour table cannot know.

use super::{INPUTS, MlpError, MlpModel};
use crate::lut::{LutModel, bin_centre, tile_centre};

/// Bake settings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BakeOptions {
    /// Bins per colour channel.
    pub bins: usize,
    /// Tiles across and down.
    pub tiles: [usize; 2],
}

impl Default for BakeOptions {
    fn default() -> Self {
        Self {
            bins: 64,
            tiles: [4, 3],
        }
    }
}

/// Rows per forward pass while baking.
const ROWS: usize = 64 * 1024;

/// Bake `model` (a difference-input MLP) into a LUT.
pub fn bake(model: &MlpModel, opts: BakeOptions) -> Result<LutModel, MlpError> {
    if !model.input.is_difference() {
        return Err(MlpError::NoData(
            "only a difference-input (`input = diff` or `relative`) MLP can be baked into a \
             LUT: a raw-input model subtracts each pixel's background colour, which a colour \
             table cannot know"
                .into(),
        ));
    }
    let net = model.net()?;
    let (bins, [tx, ty]) = (opts.bins.clamp(2, 256), opts.tiles);
    let cube = bins * bins * bins;
    let mut table = Vec::with_capacity(tx * ty * cube);
    let mut features = Vec::with_capacity(ROWS * INPUTS);
    for tile_y in 0..ty {
        for tile_x in 0..tx {
            let x = tile_centre(tile_x, tx, model.width);
            let y = tile_centre(tile_y, ty, model.height);
            let zero = net.forward(&model.features([0.0; 3], x, y))?;
            let flush = |features: &mut Vec<f32>, table: &mut Vec<[f32; 2]>| {
                let out = net.forward(features)?;
                table.extend(
                    out.chunks_exact(2)
                        .map(|g| [g[0] - zero[0], g[1] - zero[1]]),
                );
                features.clear();
                Ok::<(), MlpError>(())
            };
            for i in 0..cube {
                let (r, g, b) = (i / (bins * bins), (i / bins) % bins, i % bins);
                let rgb = [r, g, b].map(|c| bin_centre(c, model.input, bins));
                features.extend_from_slice(&model.features(rgb, x, y));
                if features.len() == ROWS * INPUTS {
                    flush(&mut features, &mut table)?;
                }
            }
            flush(&mut features, &mut table)?;
        }
    }
    LutModel::from_table(
        model.input,
        bins,
        (model.width, model.height),
        [tx, ty],
        "mlp",
        table,
    )
    .map(|mut lut| {
        lut.mm_per_px = model.mm_per_px;
        lut.slopes = model.slopes;
        lut
    })
    .ok_or_else(|| MlpError::NoData("the baked table has non-finite values".into()))
}
