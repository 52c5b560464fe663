//! Calibration from Python: `label`, `train` and `evaluate`, with the CLI's option names
//! and its `--json` fields (the library's reports, as dicts).

use std::path::PathBuf;

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use gelgrip::calibration::label::{LabelRequest, label as label_presses};
use gelgrip::calibration::train::{ModelChoice, TrainRequest, train as train_model};
use gelgrip_plugins::gradient::{GradientModel, MlpMode};
use gelgrip_plugins::lut::Input;
use gelgrip_plugins::mlp::train::{InputNorm, Loss};

use crate::errors;
use crate::sensor::{Model, solver};

/// A report (anything serializable) as a Python dict, through JSON.
pub fn to_py<'py>(py: Python<'py>, value: &impl serde::Serialize) -> PyResult<Bound<'py, PyAny>> {
    let text = serde_json::to_string(value)
        .map_err(|e| errors::GelgripError::new_err(format!("report: {e}")))?;
    py.import("json")?.call_method1("loads", (text,))
}

/// Label the presses of `in_dir` (its `background.png` and `*.png` presses) into the press
/// dataset `out_dir`, as `calibrate label` does; its `--json` report as a dict.
#[pyfunction]
pub fn label<'py>(
    py: Python<'py>,
    in_dir: PathBuf,
    out_dir: PathBuf,
    ball_mm: f64,
    mm_per_px: f64,
) -> PyResult<Bound<'py, PyAny>> {
    errors::require_dir(&in_dir, "in_dir")?;
    let request = LabelRequest {
        input: in_dir,
        out: out_dir,
        ball_mm,
        mm_per_px,
    };
    let report = py.detach(|| label_presses(&request).map_err(|e| errors::gelgrip(&e)))?;
    to_py(py, &report)
}

/// A name from `names`, or a `ValueError` listing them.
fn one_of<T: Copy>(what: &str, name: &str, names: &[(&str, T)]) -> PyResult<T> {
    names
        .iter()
        .find(|(n, _)| *n == name)
        .map(|(_, v)| *v)
        .ok_or_else(|| {
            let listed: Vec<String> = names.iter().map(|(n, _)| format!("{n:?}")).collect();
            PyValueError::new_err(format!(
                "{what}={name:?}: expected one of {}",
                listed.join(", ")
            ))
        })
}

/// A count within `lo..=hi`, or a `ValueError`.
fn within(what: &str, v: i64, lo: i64, hi: i64) -> PyResult<usize> {
    if (lo..=hi).contains(&v) {
        Ok(v as usize)
    } else {
        Err(PyValueError::new_err(format!(
            "{what}={v}: expected {lo} to {hi}"
        )))
    }
}

/// A number within `lo..=hi`, or a `ValueError`.
fn within_f(what: &str, v: f64, lo: f64, hi: f64) -> PyResult<f64> {
    if v.is_finite() && (lo..=hi).contains(&v) {
        Ok(v)
    } else {
        Err(PyValueError::new_err(format!(
            "{what}={v}: expected {lo} to {hi}"
        )))
    }
}

/// Train a model on the press dataset `data_dir`, as `calibrate train` does, with its
/// options and their limits; the model (its `report` the `--json` object). A bar shows the
/// MLP's epochs when stderr is a terminal.
#[pyfunction]
#[pyo3(signature = (data_dir, model="lut", *, input=None, bins=64, blur_px=None, hidden=32,
    epochs=80, dropout=0.0, learning_rate=5e-3, patience=20, seed=1, loss=None,
    input_norm="standard"))]
#[allow(clippy::too_many_arguments)]
pub fn train(
    py: Python<'_>,
    data_dir: PathBuf,
    model: &str,
    input: Option<&str>,
    bins: i64,
    blur_px: Option<i64>,
    hidden: i64,
    epochs: i64,
    dropout: f64,
    learning_rate: f64,
    patience: i64,
    seed: u64,
    loss: Option<&str>,
    input_norm: &str,
) -> PyResult<Model> {
    errors::require_dir(&data_dir, "data_dir")?;
    let kind = one_of(
        "model",
        model,
        &[("lut", ModelChoice::Lut), ("mlp", ModelChoice::Mlp)],
    )?;
    let request = TrainRequest {
        input: input
            .map(|i| {
                Input::parse(i).ok_or_else(|| {
                    PyValueError::new_err(format!(
                        "input={i:?}: expected one of {:?}",
                        Input::NAMES
                    ))
                })
            })
            .transpose()?,
        bins: within("bins", bins, 2, 256)?,
        blur_px: blur_px.map(|b| within("blur_px", b, 0, 8)).transpose()?,
        hidden: within("hidden", hidden, 1, 1024)?,
        epochs: within("epochs", epochs, 1, 100_000)?,
        dropout: within_f("dropout", dropout, 0.0, 0.9)?,
        learning_rate: within_f("learning_rate", learning_rate, 1e-6, 1.0)?,
        patience: within("patience", patience, 0, 100_000)?,
        seed,
        loss: loss
            .map(|l| {
                one_of(
                    "loss",
                    l,
                    &[("l1", Loss::L1), ("l2", Loss::L2), ("huber", Loss::Huber)],
                )
            })
            .transpose()?,
        input_norm: one_of(
            "input_norm",
            input_norm,
            &[
                ("fixed", InputNorm::Fixed),
                ("standard", InputNorm::Standard),
            ],
        )?,
        ..TrainRequest::new(data_dir, kind)
    };
    let trained = py.detach(|| train_model(&request).map_err(|e| errors::gelgrip(&e)))?;
    let inner = match trained.model {
        gelgrip::calibration::train::TrainedModel::Lut(l) => GradientModel::lut(l),
        gelgrip::calibration::train::TrainedModel::Mlp(m) => {
            GradientModel::mlp(m, MlpMode::ContactOnly)
                .map_err(|e| errors::ModelError::new_err(e.to_string()))?
        }
    };
    let report = serde_json::to_string(&trained.report)
        .map_err(|e| errors::GelgripError::new_err(format!("report: {e}")))?;
    Ok(Model::trained(inner, report))
}

/// `model` on every press of the dataset `data_dir`, as `calibrate eval` does (`solver`
/// `"dst"`, `"dct"` or None for gradients only); its `--json` report as a dict.
#[pyfunction]
#[pyo3(signature = (model, data_dir, solver="dst"))]
pub fn evaluate<'py>(
    py: Python<'py>,
    model: &Model,
    data_dir: PathBuf,
    solver: Option<&str>,
) -> PyResult<Bound<'py, PyAny>> {
    errors::require_dir(&data_dir, "data_dir")?;
    let solver = solver.map(self::solver).transpose()?;
    let model = model.in_mode(MlpMode::Dense);
    let evaluated = py.detach(|| {
        gelgrip::calibration::evaluate(&model, &data_dir, solver).map_err(|e| errors::gelgrip(&e))
    })?;
    to_py(py, &evaluated.summary)
}
