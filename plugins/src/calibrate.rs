//! Calibration from a press dataset: train a LUT or MLP gradient model, gather a press for
//! zero-shot transfer, and evaluate any model with the contract's metrics (`gx_mae`,
//! `gy_mae` over inside pixels of all presses, `depth_mae_mm` from the ball geometry).

use thiserror::Error;

pub mod collect;
pub mod label;
pub mod sheet;
pub mod sphere;
pub mod window;

use crate::dataset::{DatasetError, Press, PressDataset, PressTruth};
use crate::gradient::{GradientModel, background_key, frame_key};
use crate::lut::{Input, LutModel, LutSpec, LutTrainer, RIM_BAND_PX, RimPixels};
use crate::mlp::train::{EpochReport, Samples, TrainOptions, ValidationSummary};
use crate::mlp::transfer::PressPixels;
use crate::mlp::{MlpError, MlpModel};
use crate::model_file::{Slopes, to_forward_differences};
use crate::poisson::{PoissonPlan, Solver};

/// Calibration failed: reading the dataset, or the network.
#[derive(Debug, Error)]
pub enum CalibrateError {
    /// The dataset.
    #[error(transparent)]
    Dataset(#[from] DatasetError),
    /// The MLP.
    #[error(transparent)]
    Mlp(#[from] MlpError),
    /// The runtime pipeline (windowed depth).
    #[error(transparent)]
    Pipeline(#[from] crate::pipeline::PipelineError),
    /// Too few presses to leave one for validation.
    #[error(
        "{path}: {presses} presses leave no validation press: the MLP's validation split \
         needs at least {needed} (one to train on, one to validate, the last 10% to test)"
    )]
    TooFewPresses {
        /// The dataset.
        path: String,
        /// Presses it has.
        presses: usize,
        /// Presses needed.
        needed: usize,
    },
}

/// Share of `presses.csv` rows (the last ones) held out for the test MAE.
pub const TEST_SHARE: f64 = 0.1;

/// Split point: rows before it train, rows from it test (at least one test row when there
/// are two or more).
pub fn split_index(rows: usize) -> usize {
    let test = ((rows as f64 * TEST_SHARE).round() as usize).max(usize::from(rows >= 2));
    rows - test
}

/// Share of the training rows (the last ones, just before the test rows) held out to
/// validate the MLP on: its early stopping and the choice of its defaults.
pub const VALIDATION_SHARE: f64 = 0.1;

/// A dataset's rows: training, validation (from the training rows of [`split_index`]) and
/// the untouched test rows (the last 10%, CONTRACTS.md).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Split {
    /// Rows trained on.
    pub train: std::ops::Range<usize>,
    /// Rows validated on.
    pub validation: std::ops::Range<usize>,
    /// Rows tested on.
    pub test: std::ops::Range<usize>,
}

/// The validation split of `rows` rows: the last [`VALIDATION_SHARE`] of the training rows
/// (at least one) validate; `None` when that would leave no row to train or to test on.
pub fn validation_split(rows: usize) -> Option<Split> {
    let test_from = split_index(rows);
    if test_from == rows {
        return None;
    }
    let validation = ((test_from as f64 * VALIDATION_SHARE).round() as usize).max(1);
    let train_to = test_from.checked_sub(validation).filter(|t| *t >= 1)?;
    Some(Split {
        train: 0..train_to,
        validation: train_to..test_from,
        test: test_from..rows,
    })
}

/// [`validation_split`] of a dataset's presses, or [`CalibrateError::TooFewPresses`].
pub fn validation_split_of(ds: &PressDataset) -> Result<Split, CalibrateError> {
    validation_split(ds.presses.len()).ok_or_else(|| CalibrateError::TooFewPresses {
        path: ds.dir.display().to_string(),
        presses: ds.presses.len(),
        needed: min_presses_for_validation(),
    })
}

/// The fewest rows [`validation_split`] accepts.
pub fn min_presses_for_validation() -> usize {
    (1..64)
        .find(|n| validation_split(*n).is_some())
        .unwrap_or(64)
}

/// The labelled pixels of a press, as every trainer and the transfer use them: each inside
/// pixel with its gradient ([`PressTruth::gradients`], its footprint's mean slope), and
/// background pixels (untouched, one for every five inside pixels, evenly spaced) with
/// zero gradient; with `reached`, also every outside pixel that the contact reaches into,
/// with the rise it covers. Labels are `(pixel, gx, gy)`, possibly non-finite (callers
/// skip those).
fn labelled_pixels(
    truth: &PressTruth,
    (w, h): (usize, usize),
    reached: bool,
) -> Vec<(usize, f32, f32)> {
    let (gx, gy) = truth.gradients(w, h);
    let inside = truth.inside.iter().filter(|v| **v).count().max(1);
    let stride = ((w * h - inside).max(1) * 5 / inside).max(1);
    (0..w * h)
        .filter_map(|p| {
            let sloped = gx[p] != 0.0 || gy[p] != 0.0;
            if truth.inside[p] || (reached && sloped) {
                Some((p, gx[p] as f32, gy[p] as f32))
            } else if p % stride == 0 && !sloped {
                Some((p, 0.0, 0.0))
            } else {
                None
            }
        })
        .collect()
}

/// Whether pixel `(x, y)` is within `band_px` of `press`'s contact circle, inside or out.
fn on_rim(press: &Press, (x, y): (usize, usize), band_px: f64) -> bool {
    let rho = (x as f64 - press.center_x_px).hypot(y as f64 - press.center_y_px);
    (rho - press.contact_radius_px).abs() < band_px
}

/// Train a LUT on the dataset's training rows (every row but the held-out last 10%).
/// Background pixels are added with zero gradient, one in five of the contact pixels' count,
/// so that the no-contact colours map to zero.
pub fn train_lut(ds: &PressDataset, spec: LutSpec) -> Result<LutModel, CalibrateError> {
    train_lut_on(&[ds], spec)
}

/// Train one LUT on the training rows of several datasets of the same sensor (for example
/// presses of a small and of a broad ball, so that both steep and shallow gradients are
/// learnt). Every dataset must have the first one's image size.
///
/// When the presses are noisy ([`BLUR_ABOVE_NOISE`]) the frames are read through a box
/// blur whose radius is chosen on the data ([`choose_blur`], [`best_blur`]): a table read
/// through heavy pixel noise learns gradients shrunk toward zero, and a blur too wide
/// smears the contact's rim.
pub fn train_lut_on(datasets: &[&PressDataset], spec: LutSpec) -> Result<LutModel, CalibrateError> {
    let choice = blur_choice(datasets, spec)?;
    Ok(train_lut_blurred(datasets, spec, choice.blur_px)?)
}

/// How a LUT's blur was chosen: the presses' measured noise, the radius sweep (empty when
/// the noise is at most [`BLUR_ABOVE_NOISE`]) and the radius kept.
#[derive(Debug, Clone, PartialEq)]
pub struct BlurChoice {
    /// [`pixel_noise`] of the training presses, grey levels RMS.
    pub noise: f64,
    /// [`choose_blur`]'s sweep, when the noise called for one.
    pub sweep: Vec<(usize, f64)>,
    /// The radius kept, px.
    pub blur_px: usize,
}

/// Choose a LUT's blur for `datasets`: none for presses no noisier than
/// [`BLUR_ABOVE_NOISE`], else [`best_blur`] of [`choose_blur`]'s sweep.
pub fn blur_choice(
    datasets: &[&PressDataset],
    spec: LutSpec,
) -> Result<BlurChoice, CalibrateError> {
    let noise = pixel_noise(datasets)?;
    let sweep = if noise > BLUR_ABOVE_NOISE {
        choose_blur(datasets, spec)?
    } else {
        Vec::new()
    };
    Ok(BlurChoice {
        noise,
        blur_px: best_blur(&sweep),
        sweep,
    })
}

/// Pixel noise (RMS grey levels, [`pixel_noise`]) above which a LUT is read through a
/// blur. The simulated sensors at their nominal noise measure 8.4: there the blur with the
/// best gradient error (radius 4) spreads a small contact's rim (a 6 mm probe's area read
/// 57% large and its volume 25%), so below this the frames are read as they are; at 5×
/// the nominal noise (44.7) the unblurred table reads forces at a third of the truth.
pub const BLUR_ABOVE_NOISE: f64 = 16.0;

/// The presses' pixel noise: RMS difference of the training presses from the background
/// (every channel, every seventh pixel) over pixels at least two contact radii plus 8 px
/// from the contact, grey levels; 0 when no pixel qualifies.
pub fn pixel_noise(datasets: &[&PressDataset]) -> Result<f64, DatasetError> {
    let (mut sum, mut n) = (0.0f64, 0usize);
    for ds in datasets {
        let (w, h) = (ds.background.width, ds.background.height);
        for press in &ds.presses[..split_index(ds.presses.len())] {
            let img = ds.press_image(press)?;
            let far = 2.0 * press.contact_radius_px + 8.0;
            for p in (0..w * h).step_by(7) {
                let (x, y) = ((p % w) as f64, (p / w) as f64);
                if (x - press.center_x_px).hypot(y - press.center_y_px) < far {
                    continue;
                }
                for c in 0..3 {
                    let d =
                        f64::from(img.data[3 * p + c]) - f64::from(ds.background.data[3 * p + c]);
                    sum += d * d;
                    n += 1;
                }
            }
        }
    }
    Ok(if n == 0 { 0.0 } else { (sum / n as f64).sqrt() })
}

/// Box-blur radii [`choose_blur`] tries, px.
pub const BLUR_CANDIDATES_PX: [usize; 7] = [0, 1, 2, 3, 4, 6, 8];

/// The blur radius sweep: for each of [`BLUR_CANDIDATES_PX`], a LUT trained on the first 80%
/// of each dataset's training rows and its mean gradient error (`(gx_mae + gy_mae) / 2`) on
/// the other 20% (the held-out test rows are not touched).
pub fn choose_blur(
    datasets: &[&PressDataset],
    spec: LutSpec,
) -> Result<Vec<(usize, f64)>, CalibrateError> {
    let (w, h) = same_size(datasets)?;
    // With fewer than two training rows there is nothing to validate on: every radius
    // scores 0 and the sweep keeps 0.
    let fit_rows = |ds: &PressDataset| {
        let train = split_index(ds.presses.len());
        0..if train >= 2 {
            (train * 4 / 5).max(1)
        } else {
            train
        }
    };
    let mut sweep = Vec::new();
    for r in BLUR_CANDIDATES_PX {
        let lut = GradientModel::lut(train_rows(datasets, &fit_rows, spec, r, (w, h))?);
        let (mut sum, mut pixels) = (0.0, 0usize);
        for ds in datasets {
            let rows = fit_rows(ds).end..split_index(ds.presses.len());
            let e = evaluate(&lut, ds, rows, None)?;
            sum += (e.gx_mae + e.gy_mae) / 2.0 * e.pixels as f64;
            pixels += e.pixels;
        }
        sweep.push((
            r,
            if pixels == 0 {
                0.0
            } else {
                sum / pixels as f64
            },
        ));
    }
    Ok(sweep)
}

/// Share by which a blur's validation error may exceed the sweep's best and still be
/// preferred for being smaller: a wider blur spreads a small contact's rim (a 6 mm probe's
/// area read 57% large, its volume 25%, at the radius with the very best gradient error).
pub const BLUR_TOLERANCE: f64 = 0.1;

/// The smallest radius whose error in a [`choose_blur`] sweep is within
/// [`BLUR_TOLERANCE`] of the sweep's best (0 for an empty sweep).
pub fn best_blur(sweep: &[(usize, f64)]) -> usize {
    let best = sweep
        .iter()
        .map(|(_, e)| *e)
        .filter(|e| e.is_finite())
        .fold(f64::INFINITY, f64::min);
    sweep
        .iter()
        .filter(|(_, e)| e.is_finite() && *e <= best * (1.0 + BLUR_TOLERANCE))
        .map(|(r, _)| *r)
        .min()
        .unwrap_or(0)
}

/// [`train_lut_on`] with a given blur radius, px, on every training row.
pub fn train_lut_blurred(
    datasets: &[&PressDataset],
    spec: LutSpec,
    blur_px: usize,
) -> Result<LutModel, DatasetError> {
    let size = same_size(datasets)?;
    let all = |ds: &PressDataset| 0..split_index(ds.presses.len());
    train_rows(datasets, &all, spec, blur_px, size)
}

fn train_rows(
    datasets: &[&PressDataset],
    rows: &dyn Fn(&PressDataset) -> std::ops::Range<usize>,
    spec: LutSpec,
    blur_px: usize,
    (w, h): (usize, usize),
) -> Result<LutModel, DatasetError> {
    let input = spec.input;
    let fallback_rim = spec.rim == RimPixels::Fallback;
    let band_px = RIM_BAND_PX + blur_px as f64;
    let mut trainer = LutTrainer::for_spec(spec);
    let mut rim = RimSamples::default();
    for ds in datasets {
        let r = ds.ball_radius_px();
        let background = ds.background.blurred(blur_px);
        for press in ds.presses.get(rows(ds)).unwrap_or(&[]) {
            let img = ds.press_image(press)?.blurred(blur_px);
            let truth = PressTruth::new(press, r, w, h);
            for (p, gx, gy) in labelled_pixels(&truth, (w, h), fallback_rim) {
                let key = frame_key(&img, &background, p, input);
                if fallback_rim && on_rim(press, (p % w, p / w), band_px) {
                    rim.samples.push((key, gx, gy));
                    continue;
                }
                if !truth.inside[p] {
                    rim.see_flat(key);
                }
                trainer.add(key, gx, gy);
            }
        }
    }
    let mut model = if fallback_rim {
        trainer.finish_with_fallback(rim.trainer(spec), w, h)
    } else {
        trainer.finish(w, h)
    };
    model.blur_px = blur_px;
    model.mm_per_px = shared_mm_per_px(datasets);
    model.slopes = Slopes::Footprint;
    Ok(model)
}

/// The rim's labelled pixels of a LUT with [`RimPixels::Fallback`], and how far from zero
/// the keys of the untouched gel's labelled pixels (off every rim) reach per channel: the
/// camera's noise around the flat gel, measured on the training presses themselves.
#[derive(Default)]
struct RimSamples {
    samples: Vec<([f32; 3], f32, f32)>,
    flat_reach: [f32; 3],
}

impl RimSamples {
    fn see_flat(&mut self, key: [f32; 3]) {
        for (reach, k) in self.flat_reach.iter_mut().zip(key) {
            if k.is_finite() {
                *reach = reach.max(k.abs());
            }
        }
    }

    /// The fallback trainer: the rim's pixels whose colour is outside the untouched gel's
    /// reach (one within it may be a frame's noise on flat gel, which must read flat: a
    /// rim pixel mostly outside the contact has the flat colour and a steep label).
    fn trainer(self, spec: LutSpec) -> LutTrainer {
        let mut trainer = LutTrainer::for_spec(spec);
        for (key, gx, gy) in self.samples {
            if key.iter().zip(&self.flat_reach).any(|(k, r)| k.abs() > *r) {
                trainer.add(key, gx, gy);
            }
        }
        trainer
    }
}

/// The labelled pixels of the training rows of `datasets` as MLP samples (transfer not
/// applied): every inside pixel, and background pixels with zero target, one in five of the
/// inside count, as for the LUT.
pub fn mlp_samples(
    datasets: &[&PressDataset],
    input: Input,
) -> Result<(Samples, (usize, usize)), CalibrateError> {
    mlp_samples_of(datasets, input, |ds| 0..split_index(ds.presses.len()))
}

/// [`mlp_samples`] from the rows `rows(ds)` of each dataset.
pub fn mlp_samples_of(
    datasets: &[&PressDataset],
    input: Input,
    rows: impl Fn(&PressDataset) -> std::ops::Range<usize>,
) -> Result<(Samples, (usize, usize)), CalibrateError> {
    let size = same_size(datasets)?;
    let (w, h) = size;
    let shape = MlpModel {
        input,
        width: w,
        height: h,
        hidden: 0,
        layers: Vec::new(),
        offset_rgb: [0.0; 3],
        gain_rgb: [1.0; 3],
        mm_per_px: None,
        slopes: Slopes::Footprint,
    };
    let mut samples = Samples::default();
    for ds in datasets {
        let r = ds.ball_radius_px();
        for press in ds.presses.get(rows(ds)).unwrap_or(&[]) {
            let img = ds.press_image(press)?;
            let truth = PressTruth::new(press, r, w, h);
            for (p, gx, gy) in labelled_pixels(&truth, (w, h), false) {
                if gx.is_finite() && gy.is_finite() {
                    let k = frame_key(&img, &ds.background, p, input);
                    samples.push(shape.features(k, p % w, p / w), gx, gy);
                }
            }
        }
    }
    Ok((samples, size))
}

/// The pixel size the datasets share, mm, recorded in the models trained on them
/// (`None` when they differ).
pub fn shared_mm_per_px(datasets: &[&PressDataset]) -> Option<f64> {
    let first = datasets.first()?.info.mm_per_px;
    datasets
        .iter()
        .all(|ds| ds.info.mm_per_px == first)
        .then_some(first)
}

fn same_size(datasets: &[&PressDataset]) -> Result<(usize, usize), DatasetError> {
    let Some(first) = datasets.first() else {
        return Err(DatasetError::Format {
            path: String::new(),
            detail: "no dataset to train on".into(),
        });
    };
    let (w, h) = (first.background.width, first.background.height);
    for ds in datasets {
        if (ds.background.width, ds.background.height) != (w, h) {
            return Err(DatasetError::Format {
                path: ds.dir.display().to_string(),
                detail: format!(
                    "images are {}x{}, the first dataset's are {w}x{h}",
                    ds.background.width, ds.background.height
                ),
            });
        }
    }
    Ok((w, h))
}

/// Train an MLP on the training rows of `datasets` (the last 10% of each held out).
pub fn train_mlp_on(
    datasets: &[&PressDataset],
    input: Input,
    opts: &TrainOptions,
    progress: impl FnMut(&EpochReport),
) -> Result<MlpModel, CalibrateError> {
    let (samples, size) = mlp_samples(datasets, input)?;
    let mut model = crate::mlp::train::train(&samples, input, size, opts, progress)?;
    model.mm_per_px = shared_mm_per_px(datasets);
    model.slopes = Slopes::Footprint;
    Ok(model)
}

/// An MLP trained with a validation split of every dataset ([`validation_split`]): early
/// stopping on the validation presses' loss, the best epoch's weights.
#[derive(Debug, Clone)]
pub struct ValidatedMlp {
    /// The model (the best epoch's weights).
    pub model: MlpModel,
    /// The validation curve's summary.
    pub summary: ValidationSummary,
    /// The split of each dataset, in order.
    pub splits: Vec<Split>,
}

/// Train an MLP on the training rows of `datasets` less their validation rows, stopping
/// on the validation rows' loss; a dataset too small for a validation press is an error
/// ([`CalibrateError::TooFewPresses`]).
pub fn train_mlp_validated(
    datasets: &[&PressDataset],
    input: Input,
    opts: &TrainOptions,
    progress: impl FnMut(&EpochReport),
) -> Result<ValidatedMlp, CalibrateError> {
    let splits = datasets
        .iter()
        .map(|ds| validation_split_of(ds))
        .collect::<Result<Vec<_>, _>>()?;
    let of = |ds: &PressDataset| validation_split(ds.presses.len());
    let (samples, size) = mlp_samples_of(datasets, input, |ds| of(ds).map_or(0..0, |s| s.train))?;
    let (validation, _) =
        mlp_samples_of(datasets, input, |ds| of(ds).map_or(0..0, |s| s.validation))?;
    let (mut model, summary) =
        crate::mlp::train::train_validated(&samples, &validation, input, size, opts, progress)?;
    model.mm_per_px = shared_mm_per_px(datasets);
    model.slopes = Slopes::Footprint;
    Ok(ValidatedMlp {
        model,
        summary,
        splits,
    })
}

/// Press `index` of `ds` as transfer input: its inside pixels, and background pixels (one
/// in five of the inside count) with zero target.
pub fn press_pixels(
    ds: &PressDataset,
    index: usize,
    input: Input,
) -> Result<PressPixels, CalibrateError> {
    let press = ds.presses.get(index).ok_or_else(|| DatasetError::Format {
        path: ds.dir.display().to_string(),
        detail: format!("no press {index} (the dataset has {})", ds.presses.len()),
    })?;
    let (w, h) = (ds.background.width, ds.background.height);
    let img = ds.press_image(press)?;
    let truth = PressTruth::new(press, ds.ball_radius_px(), w, h);
    let mut out = PressPixels::default();
    for (p, gx, gy) in labelled_pixels(&truth, (w, h), false) {
        if gx.is_finite() && gy.is_finite() {
            out.keys.push(frame_key(&img, &ds.background, p, input));
            out.background_keys
                .push(background_key(&ds.background, p, input));
            out.positions.push((p % w, p / w));
            out.targets.push([gx, gy]);
        }
    }
    Ok(out)
}

/// One evaluated press.
#[derive(Debug, Clone, PartialEq)]
pub struct PressEval {
    /// Its image file.
    pub file: String,
    /// Radius of the sphere fitted to its reconstructed surface, mm
    /// ([`sphere::press_sphere_radius_mm`]; `None` with no solver, or when no sphere fits).
    pub sphere_radius_mm: Option<f64>,
}

/// Metrics of a model on some presses.
#[derive(Debug, Clone, PartialEq)]
pub struct EvalReport {
    /// Mean |gx − truth| over inside pixels.
    pub gx_mae: f64,
    /// Mean |gy − truth| over inside pixels.
    pub gy_mae: f64,
    /// Mean |depth − truth| over inside pixels, mm (`None` with no solver).
    pub depth_mae_mm: Option<f64>,
    /// Presses evaluated.
    pub presses: usize,
    /// Inside pixels evaluated.
    pub pixels: usize,
    /// Each press evaluated, in order.
    pub per_press: Vec<PressEval>,
    /// Median of the presses' `sphere_radius_mm` (`None` when none was fitted), mm: to
    /// compare with the ball's radius, `ball_diameter_mm / 2`.
    pub sphere_radius_mm_median: Option<f64>,
}

/// Evaluate `model` on `rows` of the dataset; depth uses `solver` over the whole frame, and
/// each press's reconstructed surface is fitted with a sphere ([`sphere`]).
pub fn evaluate(
    model: &GradientModel,
    ds: &PressDataset,
    rows: std::ops::Range<usize>,
    solver: Option<Solver>,
) -> Result<EvalReport, CalibrateError> {
    let (w, h) = (ds.background.width, ds.background.height);
    let r = ds.ball_radius_px();
    let mut plan = solver.map(|s| PoissonPlan::<f64>::new(s, h, w));
    let (mut ex, mut ey, mut ed, mut n, mut presses) = (0.0, 0.0, 0.0, 0usize, 0usize);
    let (mut px, mut py, mut z) = (vec![0.0; w * h], vec![0.0; w * h], vec![0.0; w * h]);
    let mut per_press = Vec::new();
    for press in ds.presses.get(rows).unwrap_or(&[]) {
        let img = ds.press_image(press)?;
        let truth = PressTruth::new(press, r, w, h);
        // The model's gradients come as forward differences, so the labels are taken the
        // same way.
        let (mut gx, mut gy) = truth.gradients(w, h);
        to_forward_differences(&mut gx, &mut gy, w);
        model.predict_frame(&img, &ds.background, &mut px, &mut py)?;
        if let Some(plan) = plan.as_mut() {
            plan.solve(&px, &py, &mut z);
            if plan.solver() == Solver::Dct {
                let border = mean_outside(&z, &truth.inside);
                z.iter_mut().for_each(|v| *v -= border);
            }
        }
        for p in (0..w * h).filter(|p| truth.inside[*p]) {
            ex += (px[p] - gx[p]).abs();
            ey += (py[p] - gy[p]).abs();
            ed += (z[p] - truth.depth_px[p]).abs() * ds.info.mm_per_px;
            n += 1;
        }
        presses += 1;
        per_press.push(PressEval {
            file: press.file.clone(),
            sphere_radius_mm: plan
                .as_ref()
                .and_then(|_| sphere::press_sphere_radius_mm(&z, w, ds.info.mm_per_px)),
        });
    }
    let d = n.max(1) as f64;
    Ok(EvalReport {
        gx_mae: ex / d,
        gy_mae: ey / d,
        depth_mae_mm: solver.map(|_| ed / d),
        presses,
        pixels: n,
        sphere_radius_mm_median: sphere::median(
            per_press.iter().filter_map(|p| p.sphere_radius_mm),
        ),
        per_press,
    })
}

fn mean_outside(z: &[f64], inside: &[bool]) -> f64 {
    let (s, n) = z
        .iter()
        .zip(inside)
        .filter(|(_, i)| !**i)
        .fold((0.0, 0usize), |(s, n), (v, _)| (s + v, n + 1));
    if n == 0 { 0.0 } else { s / n as f64 }
}

#[cfg(test)]
mod tests {
    use super::{best_blur, split_index};

    /// Presses whose colour `SHARED` shows both a gentle facet inside the contact and the
    /// steep rim on its right, and `RIM` only the rim on its left: a table with the rim as a
    /// fallback reads `SHARED` as the gentle facet and still learns `RIM`; one that learns
    /// the rim alike reads `SHARED` steeper.
    #[test]
    fn the_rim_teaches_only_the_colours_nothing_else_showed() {
        use crate::dataset::{DatasetInfo, Press, PressDataset};
        use crate::image::RgbImage;
        use crate::lut::{LutSpec, RIM_BAND_PX, RimPixels, relative_key};
        const FLAT: u8 = 128;
        const SHARED: [u8; 3] = [FLAT - 30, FLAT, FLAT];
        const RIM: [u8; 3] = [FLAT, FLAT - 30, FLAT];
        const INSIDE: [u8; 3] = [FLAT, FLAT, FLAT - 60];
        let (w, h) = (64, 48);
        let mut background = RgbImage::new(w, h);
        background.data.fill(FLAT);
        let press = |i: usize| Press {
            file: format!("press_{i:03}.png"),
            center_x_px: 30.0 + i as f64,
            center_y_px: 24.0,
            contact_radius_px: 12.0,
        };
        let presses: Vec<Press> = (0..4).map(press).collect();
        let dir = std::env::temp_dir().join(format!("gelgrip-rim-test-{}", std::process::id()));
        let info = DatasetInfo {
            ball_diameter_mm: 2.0,
            mm_per_px: 0.05,
        };
        PressDataset::write_index(&dir, &info, &background, &presses).expect("index");
        for p in &presses {
            let mut img = background.clone();
            for (k, px) in img.data.chunks_exact_mut(3).enumerate() {
                let (dx, dy) = (
                    (k % w) as f64 - p.center_x_px,
                    (k / w) as f64 - p.center_y_px,
                );
                let (rho, a) = (dx.hypot(dy), p.contact_radius_px);
                let colour = if rho >= a {
                    continue;
                } else if rho > a - RIM_BAND_PX {
                    if dx > dy.abs() {
                        SHARED
                    } else if -dx > dy.abs() {
                        RIM
                    } else {
                        continue;
                    }
                } else if dx > dy.abs() && (5.0..8.0).contains(&rho) {
                    SHARED
                } else {
                    INSIDE
                };
                px.copy_from_slice(&colour);
            }
            img.write_png(&dir.join(&p.file)).expect("png");
        }
        let ds = PressDataset::load(&dir).expect("dataset");
        let read = |rim, colour: [u8; 3]| {
            let spec = LutSpec {
                loss: crate::mlp::train::Loss::L2,
                rim,
                ..LutSpec::calibrate_default()
            };
            let lut = super::train_lut_blurred(&[&ds], spec, 0).expect("lut");
            let key = colour.map(|c| relative_key(f32::from(c), f32::from(FLAT)));
            lut.predict_at(key, 0, 0)[0]
        };
        let (fallback, learnt) = (
            read(RimPixels::Fallback, SHARED),
            read(RimPixels::Learnt, SHARED),
        );
        let rim_only = read(RimPixels::Fallback, RIM);
        let _ = std::fs::remove_dir_all(&dir);
        // A ball of 20 px: the facets 5–8 px from the centre slope 0.26–0.44 (falling
        // towards +x), the rim at 10.5–12 px 0.6–0.9.
        assert!(
            (-0.45..-0.2).contains(&fallback),
            "shared, rim as fallback: gx {fallback}"
        );
        assert!(
            learnt < fallback - 0.05,
            "shared, rim learnt: gx {learnt} vs {fallback}"
        );
        assert!(
            rim_only > 0.3,
            "a colour only the rim showed: gx {rim_only}"
        );
    }

    #[test]
    fn the_smallest_blur_within_a_tenth_of_the_best_is_kept() {
        // The nominal-noise sweep of docs/calibration.md: radius 4 is best, 2 is within 10%.
        let sweep = [
            (0, 0.0653),
            (1, 0.0495),
            (2, 0.0441),
            (3, 0.0418),
            (4, 0.0414),
            (6, 0.0432),
            (8, 0.0482),
        ];
        assert_eq!(best_blur(&sweep), 2);
        assert_eq!(best_blur(&[(0, 0.2), (4, 0.09), (6, 0.087)]), 4);
        assert_eq!(best_blur(&[(0, f64::NAN), (3, 0.1)]), 3);
        assert_eq!(best_blur(&[]), 0);
        assert_eq!(best_blur(&[(0, 0.0), (2, 0.0)]), 0);
    }

    #[test]
    fn validation_comes_from_the_training_rows() {
        use super::{Split, min_presses_for_validation, validation_split};
        assert_eq!(
            validation_split(50),
            Some(Split {
                train: 0..40,
                validation: 40..45,
                test: 45..50
            })
        );
        assert_eq!(
            validation_split(3),
            Some(Split {
                train: 0..1,
                validation: 1..2,
                test: 2..3
            })
        );
        assert_eq!(validation_split(2), None);
        assert_eq!(validation_split(1), None);
        assert_eq!(validation_split(0), None);
        assert_eq!(min_presses_for_validation(), 3);
        for n in 3..200 {
            let s = validation_split(n).expect("split");
            assert_eq!(s.test.start, split_index(n), "{n}");
            assert!(!s.train.is_empty() && !s.validation.is_empty(), "{n}");
            assert_eq!(s.train.end, s.validation.start, "{n}");
        }
    }

    #[test]
    fn holds_out_the_last_tenth() {
        assert_eq!(split_index(50), 45);
        assert_eq!(split_index(10), 9);
        assert_eq!(split_index(2), 1);
        assert_eq!(split_index(1), 1);
        assert_eq!(split_index(0), 0);
    }
}
