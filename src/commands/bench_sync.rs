//! `gelgrip bench sync [--json]`: the paper's synchronization experiment. One sensor
//! captures late (`[[hub.sim.faults]] capture_delay_us`, 0–60 ms) while the gripper
//! grasps a deformable object gently, once with the gate on (the configured limits) and
//! once with it off (any spread, any age). Each run is a fresh runtime in this process on
//! the virtual clock, through the library's session: the code path `gelgrip run --task
//! gentle-grasp` runs.
//!
//! Overshoot is the simulator's true peak finger force against the target: what the object
//! felt, whatever the controller believed. A gated run whose sets all fail the gate never
//! squeezes, and its row says so (`grasped: false` and the reason).

use crate::cli::parse_force_n;
use clap::Args;
use std::path::Path;
use std::path::PathBuf;

use anyhow::Context;
use serde::Serialize;
use serde_json::Value;

use crate::cli::UsageError;
use crate::commands::bench_grasp::gentle_grasp;
use gelgrip::bench_config::{BenchDir, load_config, section};

/// The configuration every run starts from.
const BASE_CONFIG: &str = "configs/gelgripper-sim.toml";

/// One row of the bench.
#[derive(Debug, Clone, Serialize)]
pub struct SyncRow {
    /// Capture delay injected into the sensor, ms.
    pub delay_ms: f64,
    /// The gate was on.
    pub gating: bool,
    /// The grasp succeeded (and held through the hold test).
    pub grasped: bool,
    /// The object was crushed.
    pub crushed: bool,
    /// Why the grasp ended, or why it never squeezed.
    pub reason: String,
    /// (True peak finger force − target) / target, % (null if nothing was squeezed).
    pub overshoot_pct: Option<f64>,
    /// Total fused force when the grasp ended, N (null if it never ended).
    pub final_force_n: Option<f64>,
    /// The simulator's peak finger force, N.
    pub true_peak_force_n: Option<f64>,
    /// Sets that passed the gate.
    pub sets: u64,
    /// Sets the gate refused.
    pub sets_rejected: u64,
}

/// `base` with the gate opened (`gating == false`) and a capture delay on `sensor`.
fn run_config(
    base: &toml::Table,
    sensor: &str,
    delay_ms: f64,
    gating: bool,
) -> anyhow::Result<toml::Table> {
    let mut table = base.clone();
    if !gating {
        let gate = section(&mut table, "gate")?;
        gate.insert("max_spread_us".into(), 1_000_000.into());
        gate.insert("max_age_ms".into(), 60_000.0.into());
    }
    let sim = section(section(&mut table, "hub")?, "sim")?;
    let mut fault = toml::Table::new();
    fault.insert("sensor".into(), sensor.into());
    fault.insert(
        "capture_delay_us".into(),
        ((delay_ms * 1000.0).round() as i64).into(),
    );
    sim.insert("faults".into(), toml::Value::Array(vec![fault.into()]));
    Ok(table)
}

fn rejected(report: &Value) -> u64 {
    report["sets_rejected"]
        .as_object()
        .map_or(0, |m| m.values().filter_map(Value::as_u64).sum())
}

fn row(delay_ms: f64, gating: bool, target_n: f64, report: &Value) -> SyncRow {
    let sets = report["sets"].as_u64().unwrap_or(0);
    let true_peak = report["true_peak_force_n"].as_f64();
    let squeezed = true_peak.is_some_and(|p| p > 0.0);
    let reason = if sets == 0 {
        format!(
            "never squeezed: no set passed the gate ({} refused); {}",
            rejected(report),
            report["faults"][0].as_str().unwrap_or("the run ended")
        )
    } else {
        report["reason"].as_str().unwrap_or("").to_string()
    };
    SyncRow {
        delay_ms,
        gating,
        grasped: report["grasped"].as_bool().unwrap_or(false),
        crushed: report["crushed"].as_bool().unwrap_or(false),
        reason,
        overshoot_pct: true_peak
            .filter(|_| squeezed)
            .map(|p| 100.0 * (p - target_n) / target_n),
        final_force_n: report["final_force_n"].as_f64(),
        true_peak_force_n: true_peak,
        sets,
        sets_rejected: rejected(report),
    }
}

/// Run the bench; returns the exit code.
pub async fn run(args: BenchSyncArgs) -> anyhow::Result<u8> {
    if let Some(plot) = &args.plot {
        gelgrip::plot::Format::of(plot)?;
    }
    if !args.scene.exists() {
        return Err(UsageError(format!(
            "{}: no such scene (run the bench from the repository, or pass --scene)",
            args.scene.display()
        ))
        .into());
    }
    let dir = BenchDir::new("bench-sync")?;
    let base = load_config(Path::new(BASE_CONFIG))?;
    let total = 2 * args.delays_ms.len();
    let mut rows = Vec::with_capacity(total);
    for gating in [true, false] {
        for &delay_ms in &args.delays_ms {
            eprintln!(
                "[{}/{total}] {} capture delay {delay_ms} ms, gating {}",
                rows.len() + 1,
                args.sensor,
                if gating { "on" } else { "off" }
            );
            let config = dir.write(
                &format!("d{delay_ms}-{gating}.toml"),
                &run_config(&base, &args.sensor, delay_ms, gating)?,
            )?;
            let report = gentle_grasp(&args.scene, Some(&config), args.duration, args.target_force)
                .await
                .with_context(|| format!("delay {delay_ms} ms, gating {gating}"))?;
            rows.push(row(delay_ms, gating, args.target_force, &report));
        }
    }
    if let Some(plot) = &args.plot {
        gelgrip::plot::save(&figure(&rows, &args), plot)?;
        eprintln!("plot: {}", plot.display());
    }
    if args.json {
        println!("{}", serde_json::to_string(&rows)?);
    } else {
        print!("{}", table(&rows));
    }
    Ok(0)
}

fn figure(rows: &[SyncRow], args: &BenchSyncArgs) -> gelgrip::plot::Figure {
    let series = |gating: bool, name: &str| gelgrip::plot::Series {
        name: name.to_string(),
        points: rows
            .iter()
            .filter(|r| r.gating == gating)
            .map(|r| (r.delay_ms, r.overshoot_pct))
            .collect(),
    };
    gelgrip::plot::Figure {
        title: format!(
            "Gentle grasp ({}, {} N) with {} capturing late: true force overshoot",
            args.scene
                .file_stem()
                .map_or_else(String::new, |s| s.to_string_lossy().into_owned()),
            args.target_force,
            args.sensor
        ),
        x_label: "injected capture delay (ms)".into(),
        y_label: "overshoot of the true peak force (%)".into(),
        x_unit: "ms".into(),
        y_unit: "%".into(),
        series: vec![
            series(false, "gating off"),
            series(true, "gating on (gaps: never squeezed)"),
        ],
        bands: Vec::new(),
        markers: true,
        legend: Some(plotters::prelude::SeriesLabelPosition::UpperLeft),
    }
}

fn table(rows: &[SyncRow]) -> String {
    let num = |v: Option<f64>, d: usize| v.map_or("-".to_string(), |x| format!("{x:.d$}"));
    let mut s = format!(
        "{:>8} {:>6} {:>7} {:>7} {:>10} {:>8} {:>8} {:>5} {:>8}  reason\n",
        "delay ms",
        "gating",
        "grasped",
        "crushed",
        "overshoot%",
        "final N",
        "true N",
        "sets",
        "rejected"
    );
    for r in rows {
        s += &format!(
            "{:>8} {:>6} {:>7} {:>7} {:>10} {:>8} {:>8} {:>5} {:>8}  {}\n",
            r.delay_ms,
            if r.gating { "on" } else { "off" },
            r.grasped,
            r.crushed,
            num(r.overshoot_pct, 1),
            num(r.final_force_n, 2),
            num(r.true_peak_force_n, 2),
            r.sets,
            r.sets_rejected,
            r.reason
        );
    }
    s
}

/// `gelgrip bench sync`.
#[derive(Debug, Args)]
pub struct BenchSyncArgs {
    /// The deformable object to grasp.
    #[arg(long, default_value = "configs/scenes/paper-cup.toml")]
    pub scene: PathBuf,
    /// The sensor that captures late.
    #[arg(long, default_value = "f1.middle")]
    pub sensor: String,
    /// Capture delays to inject, ms (comma-separated, each in [0, 60]).
    #[arg(long, value_delimiter = ',', default_values_t = [0.0, 1.0, 2.0, 5.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0], value_parser = parse_delay_ms)]
    pub delays_ms: Vec<f64>,
    /// Force per finger, N.
    #[arg(long, default_value_t = 1.5, value_parser = parse_force_n)]
    pub target_force: f64,
    /// Simulated seconds per run at most.
    #[arg(long, default_value_t = 25.0)]
    pub duration: f64,
    /// Also draw overshoot against delay, gating on and off (`.svg` or `.png`).
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Print one JSON array on stdout.
    #[arg(long)]
    pub json: bool,
}

fn parse_delay_ms(s: &str) -> Result<f64, String> {
    let v: f64 = s.parse().map_err(|e| format!("{s:?}: {e}"))?;
    if v.is_finite() && (0.0..=60.0).contains(&v) {
        Ok(v)
    } else {
        Err(format!("{v} ms: expected a delay in [0, 60] ms"))
    }
}
