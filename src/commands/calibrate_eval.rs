//! `gelgrip calibrate eval`: a model on a press dataset with the contract's metrics
//! (`gx_mae`, `gy_mae`, `depth_mae_mm`, `window_depth_mae_mm`) and the ball as the truth:
//! per press the radius of a sphere fitted to the reconstructed contact, and their median,
//! beside the ball's radius (docs/calibration.md, "The sphere check").

use clap::Args;
use serde::Serialize;
use std::path::PathBuf;

use gelgrip_plugins::calibrate::window::window_depth;
use gelgrip_plugins::calibrate::{self, EvalReport};
use gelgrip_plugins::dataset::PressDataset;
use gelgrip_plugins::gradient::{GradientModel, MlpMode};
use gelgrip_plugins::poisson::Solver;

#[derive(Serialize)]
struct EvalJson {
    gx_mae: f64,
    gy_mae: f64,
    depth_mae_mm: Option<f64>,
    window_depth_mae_mm: Option<f64>,
    mean_peak_depth_mm: Option<f64>,
    window_missed_presses: Option<usize>,
    presses: usize,
    pixels: usize,
    solver: &'static str,
    /// The ball's radius, mm: what `sphere_radius_mm` should read.
    ball_radius_mm: f64,
    /// Median of the presses' fitted sphere radii, mm (null with solver `none` or when no
    /// press had a sphere).
    sphere_radius_mm_median: Option<f64>,
    /// Each press evaluated, in `presses.csv` order.
    per_press: Vec<PressJson>,
}

#[derive(Serialize)]
struct PressJson {
    file: String,
    /// Radius of the sphere fitted to the press's reconstructed surface, mm (null when
    /// none fits, or with solver `none`).
    sphere_radius_mm: Option<f64>,
}

/// Run `calibrate eval`; returns the exit code.
pub fn run(args: EvalArgs) -> anyhow::Result<u8> {
    let model = GradientModel::load(&args.model, MlpMode::Dense)?;
    let ds = PressDataset::load(&args.data)?;
    let solver = Solver::parse(&args.solver);
    let r: EvalReport = calibrate::evaluate(&model, &ds, 0..ds.presses.len(), solver)?;
    let window = solver
        .map(|s| window_depth(&model, &ds, 0..ds.presses.len(), s))
        .transpose()?;
    let out = EvalJson {
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
            .map(|p| PressJson {
                file: p.file.clone(),
                sphere_radius_mm: p.sphere_radius_mm,
            })
            .collect(),
    };
    if args.json {
        println!("{}", serde_json::to_string(&out)?);
        return Ok(0);
    }
    let depth = match (out.depth_mae_mm, window) {
        (Some(d), Some(w)) => format!(
            "{d:.4} mm full frame, {:.4} mm in the contact window (mean peak depth {:.4} mm, {} presses without a window)",
            w.depth_mae_mm, w.mean_peak_depth_mm, w.missed_presses
        ),
        _ => "n/a (solver none)".into(),
    };
    println!(
        "{} on {}: gx_mae {:.4}, gy_mae {:.4}, depth_mae {} ({} presses, {} px, solver {})",
        args.model.display(),
        args.data.display(),
        out.gx_mae,
        out.gy_mae,
        depth,
        out.presses,
        out.pixels,
        out.solver
    );
    if solver.is_some() {
        println!("  {}", sphere_line(&r, out.ball_radius_mm));
    }
    Ok(0)
}

/// The sphere check as one line: the median fitted radius against the ball's, and how many
/// presses had a sphere.
pub fn sphere_line(r: &EvalReport, ball_radius_mm: f64) -> String {
    let fitted = r
        .per_press
        .iter()
        .filter(|p| p.sphere_radius_mm.is_some())
        .count();
    match r.sphere_radius_mm_median {
        Some(m) => format!(
            "sphere radius median {m:.3} mm (ball {ball_radius_mm:.3} mm, {:+.1}%; {fitted} of {} presses fitted)",
            (m / ball_radius_mm - 1.0) * 100.0,
            r.per_press.len()
        ),
        None => format!(
            "sphere radius: no press had a sphere (ball {ball_radius_mm:.3} mm, {} presses)",
            r.per_press.len()
        ),
    }
}

/// `gelgrip calibrate eval`.
#[derive(Debug, Args)]
pub struct EvalArgs {
    /// Model file.
    #[arg(long)]
    pub model: PathBuf,
    /// Press dataset directory.
    #[arg(long)]
    pub data: PathBuf,
    /// Depth solver for depth_mae_mm, window_depth_mae_mm and the sphere radii (`none`
    /// skips depth).
    #[arg(long, default_value = "dst", value_parser = ["dst", "dct", "none"])]
    pub solver: String,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}
