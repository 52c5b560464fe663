//! `calibrate train` as a library call: a LUT or an MLP trained on a press dataset, and the
//! report whose fields are `calibrate train --json`'s.

use std::path::PathBuf;

use serde::Serialize;

use gelgrip_plugins::calibrate::{self, EvalReport};
use gelgrip_plugins::dataset::PressDataset;
use gelgrip_plugins::gradient::{GradientModel, MlpMode};
use gelgrip_plugins::lut::{DEFAULT_BINS, Input, LutModel, LutSpec};
use gelgrip_plugins::mlp::MlpModel;
use gelgrip_plugins::mlp::train::{
    DEFAULT_EPOCHS, DEFAULT_LEARNING_RATE, DEFAULT_PATIENCE, InputNorm, Loss, TrainOptions,
    ValidationSummary,
};
use gelgrip_plugins::poisson::Solver;

use crate::UsageError;

/// Which model `train` fits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ModelChoice {
    /// Binned colour → mean gradient.
    Lut,
    /// The network.
    Mlp,
}

/// `calibrate train`'s options, by their CLI names.
#[derive(Debug, Clone)]
pub struct TrainRequest {
    /// The press dataset's directory.
    pub data: PathBuf,
    /// The model kind.
    pub model: ModelChoice,
    /// The colour key. `None`: the model's default ([`TrainRequest::input`]).
    pub input: Option<Input>,
    /// LUT bins per channel.
    pub bins: usize,
    /// LUT box-blur radius, px (`None`: chosen from the presses' noise).
    pub blur_px: Option<usize>,
    /// MLP hidden width.
    pub hidden: usize,
    /// MLP epochs, at most.
    pub epochs: usize,
    /// MLP dropout.
    pub dropout: f64,
    /// MLP initial learning rate.
    pub learning_rate: f64,
    /// MLP early-stopping patience, epochs (0: never).
    pub patience: usize,
    /// MLP seed.
    pub seed: u64,
    /// The training loss: the MLP's, and what a LUT's bins minimise (`l1`: each bin's
    /// median; `l2`: its mean; `huber`: between). `None`: the model's default
    /// ([`TrainRequest::loss`]).
    pub loss: Option<Loss>,
    /// MLP input scaling.
    pub input_norm: InputNorm,
}

impl TrainRequest {
    /// The CLI's defaults for `data` and `model`.
    pub fn new(data: PathBuf, model: ModelChoice) -> Self {
        Self {
            data,
            model,
            input: None,
            bins: DEFAULT_BINS,
            blur_px: None,
            hidden: 32,
            epochs: DEFAULT_EPOCHS,
            dropout: 0.0,
            learning_rate: DEFAULT_LEARNING_RATE,
            patience: DEFAULT_PATIENCE,
            seed: 1,
            loss: None,
            input_norm: InputNorm::Standard,
        }
    }

    /// The colour key trained on: the one asked for, else the model's default, `relative`
    /// for a LUT ([`LutSpec::calibrate_default`] says why) and `diff` for an MLP (which
    /// also sees each pixel's position, so it learns the LEDs' falloff).
    pub fn input(&self) -> Input {
        self.input.unwrap_or(match self.model {
            ModelChoice::Mlp => Input::Diff,
            ModelChoice::Lut => LutSpec::calibrate_default().input,
        })
    }

    /// The loss trained with: the one asked for, else the model's default, `l1` for an MLP
    /// and `huber` for a LUT ([`LutSpec::calibrate_default`] says why).
    pub fn loss(&self) -> Loss {
        self.loss.unwrap_or(match self.model {
            ModelChoice::Mlp => TrainOptions::default().loss,
            ModelChoice::Lut => LutSpec::calibrate_default().loss,
        })
    }
}

/// `calibrate train --json`.
#[derive(Debug, Clone, Serialize)]
pub struct TrainReport {
    /// `lut` or `mlp`.
    pub model: &'static str,
    /// The colour key.
    pub input: &'static str,
    /// MLP hidden width.
    pub hidden: Option<usize>,
    /// MLP parameters.
    pub parameters: Option<usize>,
    /// MLP epochs asked for.
    pub epochs: Option<usize>,
    /// LUT blur radius, px.
    pub blur_px: Option<usize>,
    /// The training loss (a LUT's: what its bins minimise).
    pub loss: Option<&'static str>,
    /// MLP: the input scaling.
    pub input_norm: Option<&'static str>,
    /// Presses trained on.
    pub train_presses: usize,
    /// Presses held out.
    pub test_presses: usize,
    /// Train MAE.
    pub train_gx_mae: f64,
    /// Train MAE.
    pub train_gy_mae: f64,
    /// Test MAE.
    pub test_gx_mae: f64,
    /// Test MAE.
    pub test_gy_mae: f64,
    /// The ball's radius, mm.
    pub ball_radius_mm: f64,
    /// Median radius of the spheres fitted to the held-out presses (DST), mm.
    pub test_sphere_radius_mm_median: Option<f64>,
    /// Training time, s.
    pub train_s: f64,
    /// MLP: the validation split and curve.
    pub validation: Option<ValidationReport>,
}

/// The MLP's validation split and curve.
#[derive(Debug, Clone, Serialize)]
pub struct ValidationReport {
    /// Presses validated on.
    pub presses: usize,
    /// Validation MAE.
    pub gx_mae: f64,
    /// Validation MAE.
    pub gy_mae: f64,
    /// The epoch whose weights were kept.
    pub best_epoch: usize,
    /// Its training loss.
    pub train_loss: f64,
    /// Its validation loss.
    pub validation_loss: f64,
    /// The last epoch run.
    pub stopped_at_epoch: usize,
    /// Epochs asked for.
    pub epochs: usize,
    /// Early-stopping patience.
    pub patience: usize,
}

/// A trained model, as its file is written.
#[derive(Debug, Clone)]
pub enum TrainedModel {
    /// A LUT.
    Lut(LutModel),
    /// An MLP.
    Mlp(MlpModel),
}

impl TrainedModel {
    /// Write the model file.
    pub fn save(&self, path: &std::path::Path) -> crate::Result<()> {
        match self {
            TrainedModel::Lut(l) => l.save(path)?,
            TrainedModel::Mlp(m) => m.save(path)?,
        }
        Ok(())
    }

    /// The model as the evaluation runs it (an MLP densely).
    pub fn gradient_model(&self) -> crate::Result<GradientModel> {
        Ok(match self {
            TrainedModel::Lut(l) => GradientModel::lut(l.clone()),
            TrainedModel::Mlp(m) => GradientModel::mlp(m.clone(), MlpMode::Dense)?,
        })
    }
}

/// A model trained, its report and the evaluations the report was made of.
#[derive(Debug, Clone)]
pub struct Trained {
    /// The model.
    pub model: TrainedModel,
    /// `calibrate train --json`.
    pub report: TrainReport,
    /// On the training presses.
    pub train: EvalReport,
    /// On the held-out presses, with depth (DST) for the sphere check.
    pub test: EvalReport,
}

/// What was trained, with what its report needs.
struct Fitted {
    model: TrainedModel,
    hidden: Option<usize>,
    parameters: Option<usize>,
    blur_px: Option<usize>,
    train_rows: std::ops::Range<usize>,
    validated: Option<(std::ops::Range<usize>, ValidationSummary)>,
}

/// Train as `request` says, reporting progress on stderr (an epoch bar on a terminal, a
/// line every tenth of the epochs elsewhere).
pub fn train(request: &TrainRequest) -> crate::Result<Trained> {
    let ds = PressDataset::load(&request.data)?;
    if ds.presses.is_empty() {
        // A table or network fitted to no press predicts zero everywhere.
        return Err(UsageError(format!(
            "{}: presses.csv lists no presses, so there is nothing to train on: collect \
             (`calibrate collect`) or label (`calibrate label`) presses into it first",
            request.data.display()
        ))
        .into());
    }
    let split = calibrate::split_index(ds.presses.len());
    let started = std::time::Instant::now();
    let fitted = match request.model {
        ModelChoice::Lut => train_lut(request, &ds, split)?,
        ModelChoice::Mlp => train_mlp(request, &ds)?,
    };
    let train_s = started.elapsed().as_secs_f64();
    let model = fitted.model.gradient_model()?;
    let train = calibrate::evaluate(&model, &ds, fitted.train_rows.clone(), None)?;
    // The held-out presses are also solved for depth, for the sphere check.
    let test = calibrate::evaluate(&model, &ds, split..ds.presses.len(), Some(Solver::Dst))?;
    let validation = match &fitted.validated {
        Some((rows, v)) => Some(validation(request, &model, &ds, rows.clone(), v)?),
        None => None,
    };
    let report = report(request, &fitted, (&train, &test), &ds, train_s, validation);
    Ok(Trained {
        model: fitted.model,
        report,
        train,
        test,
    })
}

fn validation(
    request: &TrainRequest,
    model: &GradientModel,
    ds: &PressDataset,
    rows: std::ops::Range<usize>,
    v: &ValidationSummary,
) -> crate::Result<ValidationReport> {
    let r = calibrate::evaluate(model, ds, rows, None)?;
    Ok(ValidationReport {
        presses: r.presses,
        gx_mae: r.gx_mae,
        gy_mae: r.gy_mae,
        best_epoch: v.best_epoch,
        train_loss: v.train_loss,
        validation_loss: v.validation_loss,
        stopped_at_epoch: v.stopped_at,
        epochs: v.epochs,
        patience: request.patience,
    })
}

fn report(
    request: &TrainRequest,
    fitted: &Fitted,
    (train, test): (&EvalReport, &EvalReport),
    ds: &PressDataset,
    train_s: f64,
    validation: Option<ValidationReport>,
) -> TrainReport {
    let mlp = request.model == ModelChoice::Mlp;
    TrainReport {
        model: if mlp { "mlp" } else { "lut" },
        input: request.input().as_str(),
        hidden: fitted.hidden,
        parameters: fitted.parameters,
        epochs: mlp.then_some(request.epochs),
        blur_px: fitted.blur_px,
        loss: Some(request.loss().as_str()),
        input_norm: mlp.then(|| request.input_norm.as_str()),
        train_presses: train.presses,
        test_presses: test.presses,
        train_gx_mae: train.gx_mae,
        train_gy_mae: train.gy_mae,
        test_gx_mae: test.gx_mae,
        test_gy_mae: test.gy_mae,
        ball_radius_mm: ds.info.ball_diameter_mm / 2.0,
        test_sphere_radius_mm_median: test.sphere_radius_mm_median,
        train_s,
        validation,
    }
}

/// A LUT on the training rows, through the box blur asked for or the one the presses'
/// noise calls for.
fn train_lut(request: &TrainRequest, ds: &PressDataset, split: usize) -> crate::Result<Fitted> {
    let spec = LutSpec {
        input: request.input(),
        bins: request.bins,
        loss: request.loss(),
        ..LutSpec::calibrate_default()
    };
    eprintln!(
        "training lut ({} input, {} bins, {} loss) on {} presses, testing on {}",
        spec.input.as_str(),
        spec.bins,
        spec.loss.as_str(),
        split,
        ds.presses.len() - split
    );
    let blur_px = match request.blur_px {
        Some(r) => r,
        None => {
            let choice = calibrate::blur_choice(&[ds], spec)?;
            eprintln!(
                "pixel noise {:.1} grey levels (RMS, away from the contact)",
                choice.noise
            );
            if !choice.sweep.is_empty() {
                let listed: Vec<String> = choice
                    .sweep
                    .iter()
                    .map(|(r, e)| format!("{r} px: {e:.4}"))
                    .collect();
                eprintln!(
                    "blur radius, validation error (mean of gx and gy): {}",
                    listed.join(", ")
                );
            }
            choice.blur_px
        }
    };
    eprintln!("frames read through a box blur of radius {blur_px} px");
    let lut = calibrate::train_lut_blurred(&[ds], spec, blur_px)?;
    Ok(Fitted {
        model: TrainedModel::Lut(lut),
        hidden: None,
        parameters: None,
        blur_px: Some(blur_px),
        train_rows: 0..split,
        validated: None,
    })
}

/// An MLP with early stopping on the validation rows.
fn train_mlp(request: &TrainRequest, ds: &PressDataset) -> crate::Result<Fitted> {
    let opts = TrainOptions {
        hidden: request.hidden,
        dropout: request.dropout as f32,
        learning_rate: request.learning_rate,
        epochs: request.epochs,
        seed: request.seed,
        patience: request.patience,
        loss: request.loss(),
        input_norm: request.input_norm,
        ..TrainOptions::default()
    };
    let rows = calibrate::validation_split_of(ds)?;
    eprintln!(
        "training mlp 5-{h}-{h}-{h}-2 (tanh, dropout {}, {} loss, {} inputs, learning rate {}, {} input) on {} presses, validating on {}, testing on {}, up to {} epochs (patience {})",
        request.dropout,
        opts.loss.as_str(),
        opts.input_norm.as_str(),
        request.learning_rate,
        request.input().as_str(),
        rows.train.len(),
        rows.validation.len(),
        rows.test.len(),
        request.epochs,
        request.patience,
        h = request.hidden
    );
    let bar = gelgrip_bench::progress::epochs(request.epochs as u64);
    let v = calibrate::train_mlp_validated(
        &[ds],
        request.input(),
        &opts,
        gelgrip_bench::progress::epoch_reporter(&bar),
    )?;
    bar.finish();
    let mlp = v.model;
    let (hidden, parameters) = (mlp.hidden, mlp.parameters());
    Ok(Fitted {
        model: TrainedModel::Mlp(mlp),
        hidden: Some(hidden),
        parameters: Some(parameters),
        blur_px: None,
        train_rows: rows.train,
        validated: Some((rows.validation, v.summary)),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_lut_trains_on_the_relative_key_and_an_mlp_on_the_difference_unless_asked() {
        let lut = TrainRequest::new(PathBuf::from("d"), ModelChoice::Lut);
        let mlp = TrainRequest::new(PathBuf::from("d"), ModelChoice::Mlp);
        assert_eq!(lut.input(), Input::Relative);
        assert_eq!(mlp.input(), Input::Diff);
        let asked = TrainRequest {
            input: Some(Input::Diff),
            ..lut
        };
        assert_eq!(asked.input(), Input::Diff);
        let raw = TrainRequest {
            input: Some(Input::Raw),
            ..mlp
        };
        assert_eq!(raw.input(), Input::Raw);
    }
}
