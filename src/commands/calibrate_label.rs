//! `gelgrip calibrate label`: label a folder of real presses automatically. Each press's
//! contact circle is detected against the folder's `background.png`; the labelled presses
//! become a press dataset (CONTRACTS.md), the others are listed in `rejected.csv` with the
//! reason, and `contact-sheet.png` shows every press with its circle for a person to check.

use std::path::PathBuf;

use clap::Args;

use gelgrip::calibration::label::{LabelReport, LabelRequest, label};

use crate::cli::parse_within;

/// `gelgrip calibrate label`.
#[derive(Debug, Args)]
pub struct LabelArgs {
    /// Folder holding `background.png` and the press images (`*.png`).
    #[arg(long = "in")]
    pub input: PathBuf,
    /// Output press dataset folder (with `rejected.csv` and `contact-sheet.png`).
    #[arg(long)]
    pub out: PathBuf,
    /// Diameter of the ball pressed, mm.
    #[arg(long, value_parser = parse_ball_mm)]
    pub ball_mm: f64,
    /// Pixel size on the gel, mm.
    #[arg(long, value_parser = parse_mm_per_px)]
    pub mm_per_px: f64,
    /// Print one JSON object on stdout.
    #[arg(long)]
    pub json: bool,
}

pub(crate) fn parse_ball_mm(s: &str) -> Result<f64, String> {
    parse_within(s, "a ball diameter", "mm", 0.5..=100.0)
}

pub(crate) fn parse_mm_per_px(s: &str) -> Result<f64, String> {
    parse_within(s, "a pixel size", "mm", 1e-4..=10.0)
}

/// Run `calibrate label`; returns the exit code.
pub fn run(args: LabelArgs) -> anyhow::Result<u8> {
    let out = label(&LabelRequest {
        input: args.input.clone(),
        out: args.out.clone(),
        ball_mm: args.ball_mm,
        mm_per_px: args.mm_per_px,
    })?;
    for r in &out.rejected {
        eprintln!("{}: rejected: {}", r.file, r.reason);
    }
    report(&args, &out)
}

fn report(args: &LabelArgs, out: &LabelReport) -> anyhow::Result<u8> {
    if args.json {
        println!("{}", serde_json::to_string(out)?);
        return Ok(0);
    }
    println!(
        "{}: {} presses labelled, {} rejected (rejected.csv); check contact-sheet.png",
        args.out.display(),
        out.labelled,
        out.rejected.len()
    );
    for p in &out.presses {
        println!(
            "  {}: centre ({:.1}, {:.1}) px, radius {:.1} px, score {:.2}",
            p.file, p.center_x_px, p.center_y_px, p.contact_radius_px, p.score
        );
    }
    for r in &out.rejected {
        println!("  {}: rejected: {}", r.file, r.reason);
    }
    Ok(0)
}
