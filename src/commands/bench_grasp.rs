//! `gelgrip bench grasp [--scene FILE]… [--target-force N] [--json]`: the gentle grasp on
//! every scene object, each in its own `gelgrip run --task gentle-grasp --clock virtual`
//! process (the same code path users run, isolated per object), one row per object with
//! the task fields of `run --json`.

use std::path::PathBuf;
use std::process::Command;

use anyhow::Context;
use serde_json::Value;

use crate::cli::BenchGraspArgs;

/// Fields copied from each run's report into the row.
const FIELDS: [&str; 16] = [
    "object",
    "grasped",
    "crushed",
    "peak_force_n",
    "true_peak_force_n",
    "hold_test_peak_force_n",
    "target_force_n",
    "time_to_stable_s",
    "loop_latency_ms_p50",
    "loop_latency_ms_p99",
    "capture_to_command_ms_p99",
    "pipeline_ms_p99",
    "reason",
    "hold_slip_mm",
    "end_reason",
    "sets",
];

fn scenes(args: &BenchGraspArgs) -> anyhow::Result<Vec<PathBuf>> {
    if !args.scenes.is_empty() {
        return Ok(args.scenes.clone());
    }
    let dir = PathBuf::from("configs/scenes");
    let mut out: Vec<PathBuf> = std::fs::read_dir(&dir)
        .with_context(|| {
            format!(
                "listing {} (run from the repository, or pass --scene)",
                dir.display()
            )
        })?
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    out.sort();
    Ok(out)
}

fn row(scene: &std::path::Path, report: &Value) -> Value {
    let mut row = serde_json::Map::new();
    row.insert(
        "scene".into(),
        Value::String(
            scene
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default(),
        ),
    );
    for k in FIELDS {
        row.insert(k.into(), report.get(k).cloned().unwrap_or(Value::Null));
    }
    let truth = report["scene"]["peak_force_n"]
        .as_object()
        .map(|m| m.values().filter_map(Value::as_f64).fold(0.0, f64::max));
    row.insert(
        "peak_true_pad_force_n".into(),
        truth.map_or(Value::Null, Value::from),
    );
    Value::Object(row)
}

/// Run the bench; returns the exit code.
pub fn run(args: BenchGraspArgs) -> anyhow::Result<u8> {
    let exe = std::env::current_exe().context("locating the gelgrip binary")?;
    let mut rows = Vec::new();
    let scenes = scenes(&args)?;
    for (i, scene) in scenes.iter().enumerate() {
        eprintln!(
            "[{}/{}] gentle grasp on {}",
            i + 1,
            scenes.len(),
            scene.display()
        );
        let out = Command::new(&exe)
            .args([
                "run",
                "--headless",
                "--json",
                "--clock",
                "virtual",
                "--task",
                "gentle-grasp",
            ])
            .arg("--scene")
            .arg(scene)
            .arg("--duration")
            .arg(args.duration.to_string())
            .arg("--target-force")
            .arg(args.target_force.to_string())
            .output()
            .with_context(|| format!("running the grasp on {}", scene.display()))?;
        let report: Value = serde_json::from_slice(&out.stdout).with_context(|| {
            format!(
                "{}: no report (exit {:?}): {}",
                scene.display(),
                out.status.code(),
                String::from_utf8_lossy(&out.stderr)
                    .lines()
                    .last()
                    .unwrap_or("")
            )
        })?;
        rows.push(row(scene, &report));
    }
    if args.json {
        println!("{}", serde_json::to_string(&rows)?);
        return Ok(0);
    }
    println!(
        "{:<12} {:>7} {:>7} {:>8} {:>8} {:>8} {:>8} {:>9} {:>9} {:>8}  reason",
        "scene",
        "grasped",
        "crushed",
        "peak N",
        "true N",
        "hold N",
        "stable s",
        "loop p99",
        "pipe p99",
        "slip mm"
    );
    let num = |v: &Value, d: usize| v.as_f64().map_or("-".to_string(), |x| format!("{x:.d$}"));
    for r in &rows {
        println!(
            "{:<12} {:>7} {:>7} {:>8} {:>8} {:>8} {:>8} {:>9} {:>9} {:>8}  {}",
            r["scene"].as_str().unwrap_or(""),
            r["grasped"],
            r["crushed"],
            num(&r["peak_force_n"], 2),
            num(&r["true_peak_force_n"], 2),
            num(&r["hold_test_peak_force_n"], 2),
            num(&r["time_to_stable_s"], 1),
            num(&r["loop_latency_ms_p99"], 1),
            num(&r["pipeline_ms_p99"], 1),
            num(&r["hold_slip_mm"], 2),
            r["reason"].as_str().unwrap_or("")
        );
    }
    Ok(0)
}
