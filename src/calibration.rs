//! Calibration as library calls, with the reports whose fields are the CLI's `--json`:
//! [`label`] (`calibrate label`), [`train`] (`calibrate train`) and [`evaluate`]
//! (`calibrate eval`). The CLI prints these reports; the Python package returns them.

pub mod label;
pub mod train;

use std::path::Path;

use serde::Serialize;

use gelgrip_plugins::calibrate::window::window_depth;
use gelgrip_plugins::calibrate::{self, EvalReport};
use gelgrip_plugins::dataset::PressDataset;
use gelgrip_plugins::gradient::GradientModel;
use gelgrip_plugins::poisson::Solver;

/// `calibrate eval --json`.
#[derive(Debug, Clone, Serialize)]
pub struct EvalSummary {
    /// Gradient MAE inside the contacts.
    pub gx_mae: f64,
    /// Gradient MAE inside the contacts.
    pub gy_mae: f64,
    /// Depth MAE over the whole frame integrated, mm.
    pub depth_mae_mm: Option<f64>,
    /// Depth MAE of the runtime pipeline's windowed solve, inside the contact, mm.
    pub window_depth_mae_mm: Option<f64>,
    /// Mean of the presses' deepest points in the window, mm.
    pub mean_peak_depth_mm: Option<f64>,
    /// Presses whose contact opened no window.
    pub window_missed_presses: Option<usize>,
    /// Presses evaluated.
    pub presses: usize,
    /// Pixels evaluated.
    pub pixels: usize,
    /// The solver (`none` without depth).
    pub solver: &'static str,
    /// The ball's radius, mm: what `sphere_radius_mm` should read.
    pub ball_radius_mm: f64,
    /// Median of the presses' fitted sphere radii, mm (null with solver `none` or when no
    /// press had a sphere).
    pub sphere_radius_mm_median: Option<f64>,
    /// Each press evaluated, in `presses.csv` order.
    pub per_press: Vec<PressSphere>,
}

/// One press's sphere check.
#[derive(Debug, Clone, Serialize)]
pub struct PressSphere {
    /// The image's file name.
    pub file: String,
    /// Radius of the sphere fitted to the press's reconstructed surface, mm (null when none
    /// fits, or with solver `none`).
    pub sphere_radius_mm: Option<f64>,
}

/// An evaluation: the summary and the report it was made of.
#[derive(Debug, Clone)]
pub struct Evaluated {
    /// `calibrate eval --json`.
    pub summary: EvalSummary,
    /// The metrics as computed.
    pub report: EvalReport,
}

/// `model` on every press of the dataset in `data`, solving depth with `solver` (`None`:
/// gradients only).
pub fn evaluate(
    model: &GradientModel,
    data: &Path,
    solver: Option<Solver>,
) -> crate::Result<Evaluated> {
    let ds = PressDataset::load(data)?;
    let rows = 0..ds.presses.len();
    let r = calibrate::evaluate(model, &ds, rows.clone(), solver)?;
    let window = solver
        .map(|s| window_depth(model, &ds, rows.clone(), s))
        .transpose()?;
    let summary = EvalSummary {
        gx_mae: r.gx_mae,
        gy_mae: r.gy_mae,
        depth_mae_mm: r.depth_mae_mm,
        window_depth_mae_mm: window.map(|w| w.depth_mae_mm),
        mean_peak_depth_mm: window.map(|w| w.mean_peak_depth_mm),
        window_missed_presses: window.map(|w| w.missed_presses),
        presses: r.presses,
        pixels: r.pixels,
        solver: solver.map_or("none", Solver::as_str),
        ball_radius_mm: ds.info.ball_diameter_mm / 2.0,
        sphere_radius_mm_median: r.sphere_radius_mm_median,
        per_press: r
            .per_press
            .iter()
            .map(|p| PressSphere {
                file: p.file.clone(),
                sphere_radius_mm: p.sphere_radius_mm,
            })
            .collect(),
    };
    Ok(Evaluated { summary, report: r })
}
