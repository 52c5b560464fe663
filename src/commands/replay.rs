//! `gelgrip replay DIR [--speed FACTOR|max] [--config FILE | --compare A B] [--json]`: a
//! recording's hub events go back through the same gate (its policy and the limits the run
//! used) and the emitted sets through the tactile pipeline.
//!
//! With the recorded config (the default) or `--config`, it checks the replay against the
//! recording: the gate's decisions set by set, and each sensor's fused reading (in contact,
//! area, depth, volume, force, and on a marker gel its slip) bit for bit wherever the run recorded one. With `--compare A
//! B` it runs both configs' pipelines on the same sets and reports how their depth, contact
//! area and force differ.

use clap::Args;
use std::path::PathBuf;

use gelgrip::replay::{Pipelines, ReplaySpeed, replay};

/// Run the command; returns the exit code.
pub async fn run(args: ReplayArgs) -> anyhow::Result<u8> {
    let pipelines = match (&args.config, args.compare.as_deref()) {
        (Some(p), _) => Pipelines::Config(p),
        (None, Some([a, b])) => Pipelines::Compare(a, b),
        _ => Pipelines::Recorded,
    };
    let report = replay(&args.dir, args.speed, pipelines).await?;
    if args.json {
        println!("{}", serde_json::to_string(&report)?);
    } else {
        println!(
            "replayed {} ({} sets, {:.2} s of recording in {:.2} s)",
            args.dir.display(),
            report.sets,
            report.duration_s,
            report.wall_s
        );
        println!(
            "  gate decisions: {} recorded, {} replayed, {} differ",
            report.decisions_recorded, report.decisions_replayed, report.decision_mismatches
        );
        match &report.compare {
            Some(d) => println!(
                "  B − A over {} readings: depth MAE {:.4} mm (max {:.4}), area MAE {:.3} mm² (max {:.3}), force MAE {:.4} N (max {:.4}), contact disagrees {}",
                d.readings,
                d.depth_mae_mm,
                d.depth_max_abs_mm,
                d.area_mae_mm2,
                d.area_max_abs_mm2,
                d.force_mae_n,
                d.force_max_abs_n,
                d.contact_disagreements
            ),
            None => println!(
                "  fused readings: {} sets compared, {} differ",
                report.fused_compared, report.fused_mismatches
            ),
        }
    }
    Ok(0)
}

/// `gelgrip replay`.
#[derive(Debug, Args)]
pub struct ReplayArgs {
    /// The recording's directory.
    pub dir: PathBuf,
    /// Replay speed: a factor of the recorded pace (on the real clock), or `max` (virtual
    /// time, as fast as the host can; the gate sees exactly the recorded times).
    #[arg(long, default_value = "max", value_parser = parse_speed)]
    pub speed: ReplaySpeed,
    /// Process the frames with this config's pipeline instead of the recorded one.
    #[arg(long, conflicts_with = "compare")]
    pub config: Option<PathBuf>,
    /// Run two configs' pipelines on the same sets and report how they differ.
    #[arg(long, num_args = 2, value_names = ["A", "B"])]
    pub compare: Option<Vec<PathBuf>>,
    /// Print one JSON object on stdout.
    #[arg(long)]
    pub json: bool,
}

fn parse_speed(s: &str) -> Result<ReplaySpeed, String> {
    if s == "max" {
        return Ok(ReplaySpeed::Max);
    }
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 && v <= 1000.0 => Ok(ReplaySpeed::Factor(v)),
        _ => Err(format!("`{s}`: expected `max` or a factor in (0, 1000]")),
    }
}
