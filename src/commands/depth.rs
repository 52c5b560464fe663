//! `gelgrip depth --gradients G.npy --out D.npy [--solver dst|dct]`: integrate an H×W×2
//! gradient array (channel 0 = Gx, 1 = Gy, pixel units) into an H×W depth map (`<f4`).

use clap::Args;
use gelgrip_plugins::npy;
use gelgrip_plugins::poisson::{PoissonPlan, Solver};
use std::path::PathBuf;

/// Run the command; returns the exit code.
pub fn run(args: DepthArgs) -> anyhow::Result<u8> {
    let solver = Solver::parse(&args.solver).unwrap_or(Solver::Dst);
    let array = npy::read(&args.gradients)?;
    let (gx, gy, h, w) = npy::split_gradients(&args.gradients, &array)?;
    let mut z = vec![0.0f64; h * w];
    PoissonPlan::new(solver, h, w).solve(&gx, &gy, &mut z);
    let z32: Vec<f32> = z.iter().map(|v| *v as f32).collect();
    npy::write_f32(&args.out, &[h, w], &z32)?;
    eprintln!(
        "{}: {h}x{w} depth ({} solver) written to {}",
        args.gradients.display(),
        solver.as_str(),
        args.out.display()
    );
    Ok(0)
}

/// `gelgrip depth`.
#[derive(Debug, Args)]
pub struct DepthArgs {
    /// Gradients, H×W×2 `<f4` or `<f8` in C order.
    #[arg(long)]
    pub gradients: PathBuf,
    /// Output depth map (H×W `<f4`, pixel units).
    #[arg(long)]
    pub out: PathBuf,
    /// Solver: dst (zero border) or dct (zero mean).
    #[arg(long, default_value = "dst", value_parser = ["dst", "dct"])]
    pub solver: String,
}
