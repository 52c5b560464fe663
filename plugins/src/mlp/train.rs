//! Training an [`MlpModel`] with candle-nn: Adam (AdamW without decay), an L1 (or L2,
//! Huber) loss, dropout after each hidden layer, a cosine learning-rate decay over the
//! epochs, optionally standardised inputs (folded into the first layer afterwards), and
//! seeded initialisation, shuffling and dropout masks, so a run is reproducible.
//!
//! With validation samples ([`train_validated`]) the L1 loss on them (dropout off) is
//! measured after every epoch; training stops when it has not improved for
//! [`TrainOptions::patience`] epochs, and the returned weights are the best epoch's.

use candle_core::{DType, Device, Tensor, Var};
use candle_nn::{AdamW, Optimizer, ParamsAdamW};
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;

use super::net::FastTanh;
use super::{DEFAULT_HIDDEN, INPUTS, Layer, MlpError, MlpModel};
use crate::lut::Input;

/// Labelled pixels: features (`n × 5`, transfer not applied) and targets (`n × 2`).
#[derive(Debug, Clone, Default)]
pub struct Samples {
    /// Row-major features.
    pub features: Vec<f32>,
    /// Row-major (gx, gy).
    pub targets: Vec<f32>,
}

impl Samples {
    /// Rows.
    pub fn len(&self) -> usize {
        self.targets.len() / 2
    }

    /// No rows.
    pub fn is_empty(&self) -> bool {
        self.targets.is_empty()
    }

    /// Add one row.
    pub fn push(&mut self, features: [f32; INPUTS], gx: f32, gy: f32) {
        self.features.extend_from_slice(&features);
        self.targets.extend_from_slice(&[gx, gy]);
    }
}

/// Training settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrainOptions {
    /// Hidden layer width.
    pub hidden: usize,
    /// Dropout probability after each hidden layer (training only).
    pub dropout: f32,
    /// Initial learning rate (decays to 5 % of it by the last epoch).
    pub learning_rate: f64,
    /// Rows per step.
    pub batch: usize,
    /// Passes over the samples.
    pub epochs: usize,
    /// Seed of initialisation, shuffling and dropout.
    pub seed: u64,
    /// Early stopping: stop after this many epochs without a lower validation loss (0:
    /// never). Used only with validation samples.
    pub patience: usize,
    /// The training loss (the validation loss that stops training is L1 whatever it is).
    pub loss: Loss,
    /// How the inputs are scaled for training.
    pub input_norm: InputNorm,
}

/// Training loss of an MLP.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Loss {
    /// Mean absolute error.
    #[default]
    L1,
    /// Mean squared error.
    L2,
    /// Huber with δ = [`HUBER_DELTA`]: squared below it, absolute above.
    Huber,
}

/// Huber's δ, gradient units.
pub const HUBER_DELTA: f64 = 0.1;

impl Loss {
    /// The CLI's name.
    pub fn as_str(&self) -> &'static str {
        match self {
            Self::L1 => "l1",
            Self::L2 => "l2",
            Self::Huber => "huber",
        }
    }
}

/// Input scaling while training.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum InputNorm {
    /// The model's fixed scaling ([`super::MlpModel::features`]: colour / 128, position / size).
    #[default]
    Fixed,
    /// Each input further standardised by the training samples' mean and standard
    /// deviation; the scaling is folded into the first layer afterwards, so the saved model
    /// takes the fixed features like any other.
    Standard,
}

impl InputNorm {
    /// The CLI's name.
    pub fn as_str(&self) -> &'static str {
        match self {
            Self::Fixed => "fixed",
            Self::Standard => "standard",
        }
    }
}

/// Epochs without a lower validation loss before training stops, unless told otherwise.
pub const DEFAULT_PATIENCE: usize = 20;
/// Passes over the samples unless told otherwise.
pub const DEFAULT_EPOCHS: usize = 80;
/// Initial learning rate unless told otherwise.
pub const DEFAULT_LEARNING_RATE: f64 = 5e-3;

// The defaults (dropout 0, learning rate 5·10⁻³, 80 epochs with patience 20, L1,
// standardised inputs) were chosen on the validation split of 50 realistic-optics presses;
// docs/calibration.md has what each alternative measured.

impl Default for TrainOptions {
    fn default() -> Self {
        Self {
            hidden: DEFAULT_HIDDEN,
            dropout: 0.0,
            learning_rate: DEFAULT_LEARNING_RATE,
            batch: 1024,
            epochs: DEFAULT_EPOCHS,
            seed: 1,
            patience: DEFAULT_PATIENCE,
            loss: Loss::L1,
            input_norm: InputNorm::Standard,
        }
    }
}

/// Progress after an epoch.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EpochReport {
    /// Epochs done (1-based).
    pub epoch: usize,
    /// Epochs in all.
    pub epochs: usize,
    /// Mean L1 loss over the epoch's batches.
    pub loss: f64,
    /// L1 loss on the validation samples after the epoch (dropout off), when there are any.
    pub validation_loss: Option<f64>,
}

/// The validation curve of a run.
#[derive(Debug, Clone, PartialEq)]
pub struct ValidationSummary {
    /// The epoch (1-based) of the lowest validation loss: the returned weights are its.
    pub best_epoch: usize,
    /// Mean training L1 loss over that epoch's batches (dropout on).
    pub train_loss: f64,
    /// Validation L1 loss after that epoch.
    pub validation_loss: f64,
    /// The last epoch run (less than `epochs` when stopped early).
    pub stopped_at: usize,
    /// Epochs planned.
    pub epochs: usize,
    /// Per epoch run: (training loss, validation loss).
    pub curve: Vec<(f64, f64)>,
}

/// The model being trained: candle variables for each layer.
struct Params {
    layers: Vec<(Var, Var)>,
}

fn init(hidden: usize, rng: &mut Pcg64Mcg) -> Result<Params, MlpError> {
    let sizes = [INPUTS, hidden, hidden, hidden, 2];
    let mut layers = Vec::new();
    for i in 0..4 {
        let (inp, out) = (sizes[i], sizes[i + 1]);
        // Xavier (Glorot) uniform, suited to tanh.
        let bound = (6.0 / (inp + out) as f32).sqrt();
        let w: Vec<f32> = (0..inp * out)
            .map(|_| rng.random_range(-bound..bound))
            .collect();
        let w = Var::from_tensor(&Tensor::from_vec(w, (out, inp), &Device::Cpu)?)?;
        let b = Var::from_tensor(&Tensor::zeros((1, out), DType::F32, &Device::Cpu)?)?;
        layers.push((w, b));
    }
    Ok(Params { layers })
}

fn forward(
    p: &Params,
    x: &Tensor,
    dropout: f32,
    rng: &mut Pcg64Mcg,
) -> candle_core::Result<Tensor> {
    let last = p.layers.len() - 1;
    let mut h = x.clone();
    for (i, (w, b)) in p.layers.iter().enumerate() {
        h = h
            .matmul(&w.as_tensor().t()?)?
            .broadcast_add(b.as_tensor())?;
        if i < last {
            h = h.apply_op1(FastTanh)?;
            if dropout > 0.0 {
                let keep = 1.0 / (1.0 - dropout);
                let mask: Vec<f32> = (0..h.elem_count())
                    .map(|_| {
                        if rng.random::<f32>() < dropout {
                            0.0
                        } else {
                            keep
                        }
                    })
                    .collect();
                h = h.mul(&Tensor::from_vec(mask, h.shape(), &Device::Cpu)?)?;
            }
        }
    }
    Ok(h)
}

/// Train a model on `samples` for images of `width × height`; `progress` is called after
/// every epoch. Dropout is off in the returned model (it is used for training only).
pub fn train(
    samples: &Samples,
    input: Input,
    size: (usize, usize),
    opts: &TrainOptions,
    progress: impl FnMut(&EpochReport),
) -> Result<MlpModel, MlpError> {
    run(samples, None, input, size, opts, progress).map(|(m, _)| m)
}

/// [`train`] with a validation set: the validation loss after every epoch, early stopping
/// after [`TrainOptions::patience`] epochs without improvement, and the best epoch's
/// weights returned with the curve's summary.
pub fn train_validated(
    samples: &Samples,
    validation: &Samples,
    input: Input,
    size: (usize, usize),
    opts: &TrainOptions,
    progress: impl FnMut(&EpochReport),
) -> Result<(MlpModel, ValidationSummary), MlpError> {
    if validation.is_empty() {
        return Err(MlpError::NoData(
            "no labelled validation pixels to stop training on".into(),
        ));
    }
    let (model, summary) = run(samples, Some(validation), input, size, opts, progress)?;
    let summary = summary.ok_or_else(|| {
        MlpError::NoData("no finite validation loss in any epoch; lower --learning-rate".into())
    })?;
    Ok((model, summary))
}

/// The loss of a batch's residuals `r` (prediction − target).
fn training_loss(loss: Loss, r: &Tensor) -> candle_core::Result<Tensor> {
    match loss {
        Loss::L1 => r.abs()?.mean_all(),
        Loss::L2 => r.sqr()?.mean_all(),
        Loss::Huber => {
            // δ·(|r| − δ/2) above δ, r²/2 below: with q = min(|r|, δ),
            // q·(|r| − q/2) is both.
            let a = r.abs()?;
            let q = a.clamp(0.0, HUBER_DELTA)?;
            (&q * (a - (&q * 0.5)?)?)?.mean_all()
        }
    }
}

/// Per-input affine scaling `(x − mean) / std` used while training.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Scaling {
    mean: [f32; INPUTS],
    std: [f32; INPUTS],
}

impl Scaling {
    fn identity() -> Self {
        Self {
            mean: [0.0; INPUTS],
            std: [1.0; INPUTS],
        }
    }

    fn is_identity(&self) -> bool {
        *self == Self::identity()
    }

    /// The samples' mean and standard deviation per input (a constant input keeps std 1).
    fn of(samples: &Samples) -> Self {
        let n = samples.len().max(1) as f64;
        let mut sum = [0.0f64; INPUTS];
        let mut sq = [0.0f64; INPUTS];
        for row in samples.features.chunks_exact(INPUTS) {
            for i in 0..INPUTS {
                sum[i] += f64::from(row[i]);
                sq[i] += f64::from(row[i]).powi(2);
            }
        }
        let mut out = Self::identity();
        for i in 0..INPUTS {
            let mean = sum[i] / n;
            let var = (sq[i] / n - mean * mean).max(0.0);
            out.mean[i] = mean as f32;
            out.std[i] = if var.sqrt() > 1e-6 && var.is_finite() {
                var.sqrt() as f32
            } else {
                1.0
            };
        }
        out
    }

    fn apply(&self, samples: &Samples) -> Samples {
        let mut out = samples.clone();
        for row in out.features.chunks_exact_mut(INPUTS) {
            for ((v, m), s) in row.iter_mut().zip(&self.mean).zip(&self.std) {
                *v = (*v - m) / s;
            }
        }
        out
    }

    /// Fold the scaling into a first layer trained on scaled inputs, so that it takes the
    /// unscaled ones: `W (x − m)/s + b = (W/s) x + (b − W m/s)`.
    fn fold_into(&self, layer: &mut Layer) {
        let inputs = layer.inputs.max(1);
        for (row, bias) in layer.weight.chunks_exact_mut(inputs).zip(&mut layer.bias) {
            let mut shift = 0.0f32;
            for ((w, m), s) in row.iter_mut().zip(&self.mean).zip(&self.std) {
                *w /= s;
                shift += *w * m;
            }
            *bias -= shift;
        }
    }
}

/// Mean L1 loss of the network (dropout off) on `samples`, in chunks.
fn validation_loss(p: &Params, samples: &Samples, rng: &mut Pcg64Mcg) -> Result<f64, MlpError> {
    const CHUNK: usize = 8192;
    let n = samples.len();
    let mut sum = 0.0f64;
    let mut start = 0;
    while start < n {
        let end = (start + CHUNK).min(n);
        let x = Tensor::from_slice(
            &samples.features[start * INPUTS..end * INPUTS],
            (end - start, INPUTS),
            &Device::Cpu,
        )?;
        let y = Tensor::from_slice(
            &samples.targets[start * 2..end * 2],
            (end - start, 2),
            &Device::Cpu,
        )?;
        let pred = forward(p, &x, 0.0, rng)?;
        sum += f64::from((pred - y)?.abs()?.sum_all()?.to_scalar::<f32>()?);
        start = end;
    }
    Ok(sum / (2 * n.max(1)) as f64)
}

/// The layers' current weights.
fn snapshot(p: &Params, hidden: usize) -> Result<Vec<Layer>, MlpError> {
    let sizes = [INPUTS, hidden, hidden, hidden, 2];
    Ok(p.layers
        .iter()
        .enumerate()
        .map(|(i, (w, b))| {
            Ok(Layer {
                inputs: sizes[i],
                outputs: sizes[i + 1],
                weight: w.as_tensor().flatten_all()?.to_vec1::<f32>()?,
                bias: b.as_tensor().flatten_all()?.to_vec1::<f32>()?,
            })
        })
        .collect::<Result<Vec<_>, candle_core::Error>>()?)
}

fn run(
    samples: &Samples,
    validation: Option<&Samples>,
    input: Input,
    (width, height): (usize, usize),
    opts: &TrainOptions,
    mut progress: impl FnMut(&EpochReport),
) -> Result<(MlpModel, Option<ValidationSummary>), MlpError> {
    if samples.is_empty() {
        return Err(MlpError::NoData("no labelled pixels to train on".into()));
    }
    let hidden = opts.hidden.max(1);
    let scaling = match opts.input_norm {
        InputNorm::Fixed => Scaling::identity(),
        InputNorm::Standard => Scaling::of(samples),
    };
    let scaled;
    let samples = if scaling.is_identity() {
        samples
    } else {
        scaled = scaling.apply(samples);
        &scaled
    };
    let scaled_validation;
    let validation = match validation {
        Some(v) if !scaling.is_identity() => {
            scaled_validation = scaling.apply(v);
            Some(&scaled_validation)
        }
        v => v,
    };
    let mut rng = Pcg64Mcg::seed_from_u64(opts.seed);
    let params = init(hidden, &mut rng)?;
    let mut opt = optimizer(&params, opts.learning_rate)?;
    let n = samples.len();
    let batch = opts.batch.clamp(1, n);
    let epochs = opts.epochs.max(1);
    let mut order: Vec<usize> = (0..n).collect();
    let mut stop = EarlyStop::default();
    let (mut xb, mut yb) = (
        Vec::with_capacity(batch * INPUTS),
        Vec::with_capacity(batch * 2),
    );
    for epoch in 0..epochs {
        let t = epoch as f64 / epochs as f64;
        let lr =
            opts.learning_rate * (0.05 + 0.95 * 0.5 * (1.0 + (std::f64::consts::PI * t).cos()));
        opt.set_learning_rate(lr);
        order.shuffle(&mut rng);
        let (mut loss_sum, mut steps) = (0.0, 0usize);
        for chunk in order.chunks(batch) {
            xb.clear();
            yb.clear();
            for &i in chunk {
                xb.extend_from_slice(&samples.features[i * INPUTS..(i + 1) * INPUTS]);
                yb.extend_from_slice(&samples.targets[i * 2..i * 2 + 2]);
            }
            let x = Tensor::from_slice(&xb, (chunk.len(), INPUTS), &Device::Cpu)?;
            let y = Tensor::from_slice(&yb, (chunk.len(), 2), &Device::Cpu)?;
            let pred = forward(&params, &x, opts.dropout, &mut rng)?;
            let loss = training_loss(opts.loss, &(pred - y)?)?;
            opt.backward_step(&loss)?;
            loss_sum += f64::from(loss.to_scalar::<f32>()?);
            steps += 1;
        }
        let loss = loss_sum / steps.max(1) as f64;
        let validation_loss = match validation {
            Some(v) => Some(validation_loss(&params, v, &mut rng)?),
            None => None,
        };
        progress(&EpochReport {
            epoch: epoch + 1,
            epochs,
            loss,
            validation_loss,
        });
        if let Some(v) = validation_loss {
            let since = stop.record((epoch + 1, epochs), (loss, v), &params, hidden)?;
            if opts.patience > 0 && since >= opts.patience {
                break;
            }
        }
    }
    let (layers, summary) = final_layers(stop, &params, hidden, &scaling)?;
    let model = MlpModel {
        input,
        width,
        height,
        hidden,
        layers,
        offset_rgb: [0.0; 3],
        gain_rgb: [1.0; 3],
        mm_per_px: None,
        slopes: crate::model_file::Slopes::Forward,
    };
    Ok((model, summary))
}

/// AdamW over every layer's weights and biases, without weight decay.
fn optimizer(params: &Params, learning_rate: f64) -> Result<AdamW, MlpError> {
    let vars: Vec<Var> = params
        .layers
        .iter()
        .flat_map(|(w, b)| [w.clone(), b.clone()])
        .collect();
    Ok(AdamW::new(
        vars,
        ParamsAdamW {
            lr: learning_rate,
            weight_decay: 0.0,
            ..Default::default()
        },
    )?)
}

/// The validation curve so far, and the best epoch's weights with its summary.
#[derive(Default)]
struct EarlyStop {
    /// Per epoch: the training loss and the validation loss.
    curve: Vec<(f64, f64)>,
    best: Option<(Vec<Layer>, ValidationSummary)>,
}

impl EarlyStop {
    /// Epoch `epoch` (from 1) of `epochs` ended with losses `(train, validation)`: keep
    /// its weights if it validates best so far. Returns the epochs since the best.
    fn record(
        &mut self,
        (epoch, epochs): (usize, usize),
        (loss, v): (f64, f64),
        params: &Params,
        hidden: usize,
    ) -> Result<usize, MlpError> {
        self.curve.push((loss, v));
        if v.is_finite()
            && self
                .best
                .as_ref()
                .is_none_or(|(_, s)| v < s.validation_loss)
        {
            let summary = ValidationSummary {
                best_epoch: epoch,
                train_loss: loss,
                validation_loss: v,
                stopped_at: epoch,
                epochs,
                curve: Vec::new(),
            };
            self.best = Some((snapshot(params, hidden)?, summary));
        }
        Ok(self
            .best
            .as_ref()
            .map_or(epoch, |(_, s)| epoch - s.best_epoch))
    }
}

/// The weights to keep: the best validated epoch's (with the whole curve in its summary),
/// else the last epoch's; the input scaling folded into the first layer. Refused when
/// training diverged.
fn final_layers(
    stop: EarlyStop,
    params: &Params,
    hidden: usize,
    scaling: &Scaling,
) -> Result<(Vec<Layer>, Option<ValidationSummary>), MlpError> {
    let EarlyStop { curve, best } = stop;
    let (mut layers, summary) = match best {
        Some((layers, mut summary)) => {
            summary.stopped_at = curve.len();
            summary.curve = curve;
            (layers, Some(summary))
        }
        None => (snapshot(params, hidden)?, None),
    };
    if let Some(first) = layers.first_mut() {
        scaling.fold_into(first);
    }
    if layers
        .iter()
        .any(|l| l.weight.iter().chain(&l.bias).any(|v| !v.is_finite()))
    {
        return Err(MlpError::NoData(
            "training diverged (non-finite weights); lower --learning-rate".into(),
        ));
    }
    Ok((layers, summary))
}

#[cfg(test)]
mod scaling_tests {
    use super::*;

    #[test]
    fn folding_the_standardisation_gives_the_scaled_layer_on_raw_inputs() {
        let mut samples = Samples::default();
        for k in 0..50 {
            let v = k as f32;
            samples.push([v * 0.01, 0.3 - v * 0.002, 0.2, v / 50.0, 0.5], 0.0, 0.0);
        }
        let s = Scaling::of(&samples);
        assert_eq!(s.std[4], 1.0, "a constant input keeps std 1");
        assert_eq!(s.std[2], 1.0);
        assert!((s.mean[3] - 0.49).abs() < 1e-6, "{s:?}");
        let layer = Layer {
            inputs: INPUTS,
            outputs: 2,
            weight: (0..10).map(|i| i as f32 * 0.1 - 0.4).collect(),
            bias: vec![0.3, -0.2],
        };
        let mut folded = layer.clone();
        s.fold_into(&mut folded);
        let scaled = s.apply(&samples);
        let out = |l: &Layer, x: &[f32]| -> Vec<f32> {
            (0..l.outputs)
                .map(|o| {
                    l.bias[o]
                        + (0..l.inputs)
                            .map(|i| l.weight[o * l.inputs + i] * x[i])
                            .sum::<f32>()
                })
                .collect()
        };
        for (raw, x) in samples
            .features
            .chunks(INPUTS)
            .zip(scaled.features.chunks(INPUTS))
        {
            let (a, b) = (out(&folded, raw), out(&layer, x));
            for (a, b) in a.iter().zip(&b) {
                assert!((a - b).abs() < 1e-4, "{a} {b}");
            }
        }
    }

    #[test]
    fn the_losses_are_l1_l2_and_huber() -> candle_core::Result<()> {
        let r = Tensor::new(&[0.05f32, -0.3], &Device::Cpu)?;
        let v = |l| -> candle_core::Result<f32> { training_loss(l, &r)?.to_scalar::<f32>() };
        assert!((v(Loss::L1)? - 0.175).abs() < 1e-6);
        assert!((v(Loss::L2)? - (0.0025 + 0.09) / 2.0).abs() < 1e-6);
        // 0.05 ≤ δ: 0.05²/2; 0.3 > δ: δ (0.3 − δ/2).
        let huber = (0.05f32 * 0.05 / 2.0 + 0.1 * (0.3 - 0.05)) / 2.0;
        assert!((v(Loss::Huber)? - huber).abs() < 1e-6);
        Ok(())
    }
}
