//! Zero-shot transfer of an [`MlpModel`] to a sibling sensor from a single labelled press.
//!
//! The network's weights stay fixed. A per-channel offset on the key colour (the paper's
//! method) — and, with [`Fit::OffsetGain`], a per-channel gain as well — is fitted by
//! gradient descent (Adam, L1 loss) so that the model's gradients on the press match the
//! press's geometric labels. Background pixels take part with zero target, so the fit
//! cannot buy the press at the price of false gradients elsewhere. A small ridge penalty
//! keeps the offset near zero and the gain near one unless the press clearly asks for
//! more: one press is little data, and unpenalised fits found offsets of ±150 grey levels
//! that matched that press a little better and held-out presses worse
//! (docs/calibration.md).

use candle_core::{Device, Tensor, Var};
use candle_nn::{AdamW, Optimizer, ParamsAdamW};

use super::net::FastTanh;
use super::{KEY_SCALE, MlpError, MlpModel};

/// What the transfer fits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fit {
    /// A constant per channel (the paper).
    Offset,
    /// A gain and a constant per channel.
    OffsetGain,
}

impl Fit {
    /// `offset` or `offset-gain`.
    pub fn as_str(self) -> &'static str {
        match self {
            Fit::Offset => "offset",
            Fit::OffsetGain => "offset-gain",
        }
    }
}

/// One press's labelled pixels, as the transfer consumes them.
#[derive(Debug, Clone, Default)]
pub struct PressPixels {
    /// Key colour per pixel (difference or raw, as the model's input).
    pub keys: Vec<[f32; 3]>,
    /// The background's key at the same pixel (zero for a difference model).
    pub background_keys: Vec<[f32; 3]>,
    /// Pixel positions.
    pub positions: Vec<(usize, usize)>,
    /// Labelled (gx, gy).
    pub targets: Vec<[f32; 2]>,
}

/// What the fit found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TransferReport {
    /// Offset stored in the model, grey levels.
    pub offset_rgb: [f32; 3],
    /// Gain stored in the model.
    pub gain_rgb: [f32; 3],
    /// Mean |error| over gx and gy on the press before the fit.
    pub mae_before: f64,
    /// After the fit.
    pub mae_after: f64,
    /// Pixels fitted on.
    pub pixels: usize,
}

/// Adam steps of the fit (full batch: a press is a few thousand pixels).
const STEPS: usize = 400;
/// Pixels of the press the fit uses at most (evenly strided).
const MAX_PIXELS: usize = 1024;
/// Ridge weight on the squared offset (in network input units, 128 grey levels) and on the
/// squared gain change: an offset of 10 grey levels costs 3·10⁻⁴ of mean |error|, one of
/// 100 levels 0.03.
const RIDGE: f64 = 0.05;

/// Fit the transfer on `press` and store it in a copy of `model`.
pub fn transfer(
    model: &MlpModel,
    press: &PressPixels,
    fit: Fit,
) -> Result<(MlpModel, TransferReport), MlpError> {
    if press.keys.is_empty() {
        return Err(MlpError::NoData(
            "the first press has no labelled pixels to fit the transfer on".into(),
        ));
    }
    let press = &subsample(press);
    let n = press.keys.len();
    let dev = Device::Cpu;
    let centre = model.input.centre();
    let scaled = |keys: &[[f32; 3]]| -> candle_core::Result<Tensor> {
        let v: Vec<f32> = keys.iter().flat_map(|k| k.map(|c| c / KEY_SCALE)).collect();
        Tensor::from_vec(v, (n, 3), &dev)
    };
    let keys = scaled(&press.keys)?;
    let bg = scaled(&press.background_keys)?;
    let xy = positions(model, press, &dev)?;
    let target: Vec<f32> = press.targets.iter().flatten().copied().collect();
    let target = Tensor::from_vec(target, (n, 2), &dev)?;
    let layers = frozen_layers(model, &dev)?;
    let net = |x: &Tensor| -> candle_core::Result<Tensor> {
        let mut h = x.clone();
        for (i, (w, b)) in layers.iter().enumerate() {
            h = h.matmul(w)?.broadcast_add(b)?;
            if i + 1 < layers.len() {
                h = h.apply_op1(FastTanh)?;
            }
        }
        Ok(h)
    };
    let start_off: Vec<f32> = model.offset_rgb.iter().map(|o| o / KEY_SCALE).collect();
    let offset = Var::from_tensor(&Tensor::from_vec(start_off, (1, 3), &dev)?)?;
    let gain = Var::from_tensor(&Tensor::from_slice(&model.gain_rgb, (1, 3), &dev)?)?;
    let c = centre / KEY_SCALE;
    let predict = |k: &Tensor| -> candle_core::Result<Tensor> {
        let col = ((k
            .broadcast_mul(gain.as_tensor())?
            .broadcast_add(offset.as_tensor())?)
            - f64::from(c))?
        .clamp(-4f32, 4f32)?;
        net(&Tensor::cat(&[&col, &xy], 1)?)
    };
    let error_of = || -> candle_core::Result<Tensor> {
        let g = (predict(&keys)? - predict(&bg)?)?;
        (g - &target)?.abs()?.mean_all()
    };
    let loss_of = || -> candle_core::Result<Tensor> {
        let ridge =
            (offset.as_tensor().sqr()?.sum_all()? + (gain.as_tensor() - 1.0)?.sqr()?.sum_all()?)?;
        error_of()? + (ridge * RIDGE)?
    };
    let before = f64::from(error_of()?.to_scalar::<f32>()?);
    let vars = match fit {
        Fit::Offset => vec![offset.clone()],
        Fit::OffsetGain => vec![offset.clone(), gain.clone()],
    };
    let mut opt = AdamW::new(
        vars,
        ParamsAdamW {
            lr: 0.01,
            weight_decay: 0.0,
            ..Default::default()
        },
    )?;
    for step in 0..STEPS {
        if step == STEPS / 2 {
            opt.set_learning_rate(0.003);
        }
        opt.backward_step(&loss_of()?)?;
    }
    let after = f64::from(error_of()?.to_scalar::<f32>()?);
    let to3 = |t: &Tensor, scale: f32| -> candle_core::Result<[f32; 3]> {
        let v = t.flatten_all()?.to_vec1::<f32>()?;
        Ok([v[0] * scale, v[1] * scale, v[2] * scale])
    };
    let offset_rgb = to3(offset.as_tensor(), KEY_SCALE)?;
    let gain_rgb = to3(gain.as_tensor(), 1.0)?;
    if offset_rgb.iter().chain(&gain_rgb).any(|v| !v.is_finite()) {
        return Err(MlpError::NoData(
            "the transfer fit diverged (non-finite offset or gain)".into(),
        ));
    }
    let mut out = model.clone();
    out.offset_rgb = offset_rgb;
    out.gain_rgb = gain_rgb;
    Ok((
        out,
        TransferReport {
            offset_rgb,
            gain_rgb,
            mae_before: before,
            mae_after: after,
            pixels: n,
        },
    ))
}

/// Every k-th pixel of `press`, at most `MAX_PIXELS`: six parameters need far fewer, and
/// each step costs two forward and backward passes over them.
fn subsample(press: &PressPixels) -> PressPixels {
    let stride = press.keys.len().div_ceil(MAX_PIXELS);
    let pick = |v: &[[f32; 3]]| v.iter().step_by(stride).copied().collect::<Vec<_>>();
    PressPixels {
        keys: pick(&press.keys),
        background_keys: pick(&press.background_keys),
        positions: press.positions.iter().step_by(stride).copied().collect(),
        targets: press.targets.iter().step_by(stride).copied().collect(),
    }
}

/// The model's layers as constant tensors `(weightᵀ, bias)`: the transfer fits only the
/// key's offset and gain.
fn frozen_layers(model: &MlpModel, dev: &Device) -> candle_core::Result<Vec<(Tensor, Tensor)>> {
    model
        .layers
        .iter()
        .map(|l| {
            Ok((
                Tensor::from_slice(&l.weight, (l.outputs, l.inputs), dev)?
                    .t()?
                    .contiguous()?,
                Tensor::from_slice(&l.bias, (1, l.outputs), dev)?,
            ))
        })
        .collect()
}

/// The press pixels' positions as the model takes them (fractions of its image size),
/// one row per pixel.
fn positions(model: &MlpModel, press: &PressPixels, dev: &Device) -> candle_core::Result<Tensor> {
    let xy: Vec<f32> = press
        .positions
        .iter()
        .flat_map(|(x, y)| {
            [
                *x as f32 / model.width.max(1) as f32,
                *y as f32 / model.height.max(1) as f32,
            ]
        })
        .collect();
    Tensor::from_vec(xy, (press.positions.len(), 2), dev)
}
