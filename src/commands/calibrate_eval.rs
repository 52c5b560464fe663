//! `gelgrip calibrate eval`: a model on a press dataset with the contract's metrics
//! (`gx_mae`, `gy_mae`, `depth_mae_mm`, `window_depth_mae_mm`) and the ball as the truth:
//! per press the radius of a sphere fitted to the reconstructed contact, and their median,
//! beside the ball's radius (docs/calibration.md, "The sphere check").

use clap::Args;
use std::path::PathBuf;

use gelgrip::calibration;
use gelgrip_plugins::calibrate::EvalReport;
use gelgrip_plugins::gradient::{GradientModel, MlpMode};
use gelgrip_plugins::poisson::Solver;

/// Run `calibrate eval`; returns the exit code.
pub fn run(args: EvalArgs) -> anyhow::Result<u8> {
    let model = GradientModel::load(&args.model, MlpMode::Dense)?;
    let solver = Solver::parse(&args.solver);
    let evaluated = calibration::evaluate(&model, &args.data, solver)?;
    let (out, r) = (&evaluated.summary, &evaluated.report);
    if args.json {
        println!("{}", serde_json::to_string(&out)?);
        return Ok(0);
    }
    let window = (
        out.window_depth_mae_mm,
        out.mean_peak_depth_mm,
        out.window_missed_presses,
    );
    let depth = match (out.depth_mae_mm, window) {
        (Some(d), (Some(mae), Some(peak), Some(missed))) => format!(
            "{d:.4} mm full frame, {mae:.4} mm in the contact window (mean peak depth {peak:.4} mm, {missed} presses without a window)"
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
        println!("  {}", sphere_line(r, out.ball_radius_mm));
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
