//! `gelgrip bench grasp [--scene FILE]… [--target-force N|auto] [--lift-rise-s S] [--sweep
//! resolution] [--json]`: the gentle grasp on every scene object, each run in this process
//! on the virtual clock through the library's session (the code path `gelgrip run --task gentle-grasp` runs, a
//! fresh runtime, hub, servos and world per object), one row per object with the task fields of `run --json`, the set rate, the
//! true force's overshoot and the crush margin. `--sweep resolution` repeats every object
//! at 320×240, 160×120 and 80×60: smaller frames cross the bus faster (a higher set rate)
//! but carry less depth detail, and the rows measure what that does to the grasp.
//!
//! `--clock real` runs the grasps in real time, so that frames arrive as the bus delivers
//! them and the pipelines work on each as it arrives (streaming): the rows then measure
//! what the host adds to the bus.
//!
//! The loop-latency budget is 10% of the bus's set period (`latency_budget_ms`), and each
//! row says whether its `loop_latency_ms_p99` (set complete → servo write) is within it.
//! After the grasps, `gelgrip bench pipeline` times (in this process) the tactile pipelines
//! alone on a grasp-like press (a 30 mm ball, 1 mm deep, on every sensor), reported beside
//! it as `bench_pipeline_ms_per_set_p99`: what a whole set costs when nothing is worked on
//! ahead.

use crate::args::ClockArg;
use crate::args::{parse_force_n, parse_lift_rise_s};
use clap::{Args, ValueEnum};
use gelgrip_controller::grasp::TargetForce;
use std::path::{Path, PathBuf};

use anyhow::Context;
use serde_json::Value;

use crate::config_files::{BenchDir, load, load_config, scene_files, section};
use gelgrip_controller::runtime::options::RunOptions;

use crate::rig::Rig;
use gelgrip_controller::clock::ClockKind;
use gelgrip_controller::runtime::gentle_grasp::{GraspOptions, LIFT_RISE_S};

/// The configuration a sweep starts from.
const BASE_CONFIG: &str = "configs/gelgripper-sim.toml";
/// The resolutions of `--sweep resolution`, columns × rows.
const RESOLUTIONS: [(u32, u32); 3] = [(320, 240), (160, 120), (80, 60)];

/// One configuration of a sweep: its resolution and config file (`None`: the default).
type Variant = (Option<(u32, u32)>, Option<PathBuf>);

/// Fields copied from each run's report into the row.
const FIELDS: [&str; 23] = [
    "clock",
    "capture_to_command_ms_p50",
    "loop_own_ms_p99",
    "bus_latency_ms",
    "bus_set_period_ms",
    "set_rate_hz",
    "final_force_n",
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

/// The press `bench pipeline` is timed on for the latency budget: ball diameter and depth, mm.
const BUDGET_PRESS_MM: (f64, f64) = (30.0, 1.0);
/// The loop's latency budget, as a share of the bus's set period.
const BUDGET_SHARE_OF_PERIOD: f64 = 0.1;

/// `bench pipeline`'s `ms_per_set_p99` on the budget's press (the default configuration),
/// measured in this process.
fn pipeline_p99_ms(rig: &dyn Rig) -> anyhow::Result<f64> {
    use clap::Parser;
    #[derive(Parser)]
    struct Pipeline {
        #[command(flatten)]
        args: crate::pipeline::BenchPipelineArgs,
    }
    let parsed = Pipeline::try_parse_from([
        "bench-pipeline".to_string(),
        "--sets".into(),
        "200".into(),
        "--ball-mm".into(),
        BUDGET_PRESS_MM.0.to_string(),
        "--press-depth-mm".into(),
        BUDGET_PRESS_MM.1.to_string(),
    ])
    .context("the budget's bench pipeline arguments")?;
    crate::pipeline::ms_per_set_p99(rig, &parsed.args)
}

/// Add the latency budget to a row: `bench_pipeline_ms_per_set_p99` (null in a resolution
/// sweep), `latency_budget_ms` (10% of the bus's set period) and `latency_within_budget`.
fn add_budget(row: &mut Value, pipeline_p99_ms: Option<f64>) {
    let budget = row["bus_set_period_ms"]
        .as_f64()
        .map(|p| p * BUDGET_SHARE_OF_PERIOD);
    let within = budget
        .zip(row["loop_latency_ms_p99"].as_f64())
        .map(|(b, l)| l <= b);
    if let Value::Object(m) = row {
        m.insert(
            "bench_pipeline_ms_per_set_p99".into(),
            pipeline_p99_ms.map_or(Value::Null, Value::from),
        );
        m.insert(
            "latency_budget_ms".into(),
            budget.map_or(Value::Null, Value::from),
        );
        m.insert(
            "latency_within_budget".into(),
            within.map_or(Value::Null, Value::from),
        );
    }
}

fn row(scene: &Path, report: &Value, resolution: Option<(u32, u32)>) -> Value {
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
    // What the object felt against what was asked: the true peak finger force.
    let target = report["target_force_n"].as_f64().filter(|t| *t > 0.0);
    let overshoot = report["true_peak_force_n"]
        .as_f64()
        .zip(target)
        .map(|(p, t)| 100.0 * (p - t) / t);
    row.insert(
        "overshoot_pct".into(),
        overshoot.map_or(Value::Null, Value::from),
    );
    // How far the hardest-pressed pad stayed from the object's crush force.
    let margin = report["scene"]["crush_force_n"]
        .as_f64()
        .zip(truth)
        .map(|(c, p)| c - p);
    row.insert(
        "crush_margin_n".into(),
        margin.map_or(Value::Null, Value::from),
    );
    if let Some((w, h)) = resolution {
        row.insert("resolution".into(), Value::String(format!("{w}x{h}")));
    }
    add_slip(&mut row, &report["slip"]);
    // A grasp that found its own force (`--target-force auto`) says what it settled on.
    if report["target_force_n"].is_null() {
        row.insert("settled_force_n".into(), report["settled_force_n"].clone());
    }
    Value::Object(row)
}

/// On a marker gel (a sensor read slip as known), the run's slip readings: the false
/// alarms against the simulator's truth (`slip_false_alarms`) and the readings of
/// incipient and gross slip. Plain gels add nothing, so their rows stay as they were.
fn add_slip(row: &mut serde_json::Map<String, Value>, slip: &Value) {
    let known = ["readings_none", "readings_incipient", "readings_gross"]
        .iter()
        .filter_map(|k| slip[k].as_u64())
        .sum::<u64>();
    if known == 0 {
        return;
    }
    row.insert("slip_false_alarms".into(), slip["false_alarms"].clone());
    row.insert(
        "slip_readings_incipient".into(),
        slip["readings_incipient"].clone(),
    );
    row.insert("slip_readings_gross".into(), slip["readings_gross"].clone());
}

/// The layout of `config` at `w`×`h`: `mm_per_px` scaled so the pad keeps its size.
fn layout_at(config: &toml::Table, w: u32, h: u32) -> anyhow::Result<toml::Table> {
    let path = config
        .get("layout")
        .and_then(toml::Value::as_str)
        .context("the base configuration names no layout")?;
    let mut layout = load(Path::new(path))?;
    let defaults = section(&mut layout, "sensor_defaults")?;
    let base_w = defaults
        .get("resolution")
        .and_then(|r| r.as_array()?.first()?.as_integer())
        .unwrap_or(320) as f64;
    let base_mm = defaults
        .get("mm_per_px")
        .and_then(toml::Value::as_float)
        .unwrap_or(0.0625);
    defaults.insert(
        "resolution".into(),
        toml::Value::Array(vec![i64::from(w).into(), i64::from(h).into()]),
    );
    defaults.insert("mm_per_px".into(), (base_mm * base_w / f64::from(w)).into());
    if let Some(toml::Value::Array(sensors)) = layout.get_mut("sensors") {
        for s in sensors.iter_mut().filter_map(toml::Value::as_table_mut) {
            s.remove("resolution");
            s.remove("mm_per_px");
        }
    }
    Ok(layout)
}

/// One gentle grasp on `scene` (with `config`, else the default) on a clock of `clock`'s
/// kind, run in this process through the library's session (what `gelgrip run --task
/// gentle-grasp --clock … --headless` runs): its `run --json` report.
pub async fn gentle_grasp(
    rig: &dyn Rig,
    clock: ClockKind,
    scene: &Path,
    config: Option<&Path>,
    duration_s: f64,
    target_force: TargetForce,
    lift_rise_s: f64,
) -> anyhow::Result<Value> {
    let defaults = RunOptions::default();
    let options = RunOptions {
        config: config.map(Path::to_path_buf),
        scene: Some(scene.to_path_buf()),
        clock,
        task: Some("gentle-grasp".into()),
        grasp: GraspOptions {
            target_force,
            lift_rise_s,
            ..defaults.grasp.clone()
        },
        headless: true,
        duration_s: Some(duration_s),
        ..defaults
    };
    let end = rig
        .run_to_end(&options)
        .await
        .with_context(|| format!("running the grasp on {}", scene.display()))?;
    Ok(end.report)
}

/// Run the bench; returns the exit code.
pub async fn run(rig: &dyn Rig, args: BenchGraspArgs) -> anyhow::Result<u8> {
    if let Some(plot) = &args.plot {
        if args.sweep.is_none() {
            return Err(crate::args::UsageError("--plot needs --sweep".into()).into());
        }
        crate::plot::Format::of(plot)?;
    }
    let scenes = scene_files(&args.scenes)?;
    let dir = BenchDir::new("bench-grasp")?;
    let configs = variants(&args, &dir)?;
    let total = scenes.len() * configs.len();
    let mut rows = Vec::new();
    for (resolution, config) in &configs {
        for scene in &scenes {
            eprintln!(
                "[{}/{total}] gentle grasp on {}{}",
                rows.len() + 1,
                scene.display(),
                resolution.map_or_else(String::new, |(w, h)| format!(" at {w}x{h}"))
            );
            let report = gentle_grasp(
                rig,
                args.clock.into(),
                scene,
                config.as_deref(),
                args.duration,
                args.target_force,
                args.lift_rise_s,
            )
            .await?;
            let mut row = row(scene, &report, *resolution);
            // A grasp that found its own force was lifted: over how long its weight came on.
            if let (true, Value::Object(m)) = (args.target_force.is_auto(), &mut row) {
                m.insert("lift_rise_s".into(), Value::from(args.lift_rise_s));
            }
            rows.push(row);
        }
    }
    // The budget holds for the default configuration (bench pipeline's); a resolution
    // sweep changes the frames, so its rows carry none.
    let pipeline_p99 = if args.sweep.is_none() {
        eprintln!(
            "bench pipeline on a {} mm ball, {} mm deep (the loop-latency budget)",
            BUDGET_PRESS_MM.0, BUDGET_PRESS_MM.1
        );
        Some(pipeline_p99_ms(rig)?)
    } else {
        None
    };
    for r in &mut rows {
        add_budget(r, pipeline_p99);
    }
    if let Some(plot) = &args.plot {
        crate::plot::save(&sweep_figure(&rows, &args.target_force.to_string()), plot)?;
        eprintln!("plot: {}", plot.display());
    }
    if args.json {
        println!("{}", serde_json::to_string(&rows)?);
        return Ok(0);
    }
    print_table(&rows);
    Ok(0)
}

/// The configurations to grasp with: `--config` (else the default), or one per resolution
/// of the sweep on it (written into `dir`).
fn variants(args: &BenchGraspArgs, dir: &BenchDir) -> anyhow::Result<Vec<Variant>> {
    let mut configs: Vec<Variant> = vec![(None, args.config.clone())];
    if args.sweep == Some(GraspSweep::Resolution) {
        let base = load_config(args.config.as_deref().unwrap_or(Path::new(BASE_CONFIG)))?;
        configs.clear();
        for (w, h) in RESOLUTIONS {
            let layout = dir.write(&format!("layout-{w}x{h}.toml"), &layout_at(&base, w, h)?)?;
            let mut config = base.clone();
            config.insert("layout".into(), layout.display().to_string().into());
            let path = dir.write(&format!("config-{w}x{h}.toml"), &config)?;
            configs.push((Some((w, h)), Some(path)));
        }
    }
    Ok(configs)
}

/// The rows as a table on stdout.
fn print_table(rows: &[Value]) {
    println!(
        "{:<12} {:>9} {:>7} {:>7} {:>7} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>9} {:>9} {:>9} {:>9} {:>7} {:>9} {:>8}  reason",
        "scene",
        "res",
        "rate Hz",
        "grasped",
        "crushed",
        "peak N",
        "true N",
        "over %",
        "crush m",
        "hold N",
        "stable s",
        "loop p99",
        "pipe p99",
        "own p99",
        "cap p99",
        "bus ms",
        "budget",
        "slip mm"
    );
    let num = |v: &Value, d: usize| v.as_f64().map_or("-".to_string(), |x| format!("{x:.d$}"));
    for r in rows {
        println!(
            "{:<12} {:>9} {:>7} {:>7} {:>7} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>9} {:>9} {:>9} {:>9} {:>7} {:>9} {:>8}  {}",
            r["scene"].as_str().unwrap_or(""),
            r["resolution"].as_str().unwrap_or("config"),
            num(&r["set_rate_hz"], 1),
            r["grasped"].to_string(),
            r["crushed"].to_string(),
            num(&r["peak_force_n"], 2),
            num(&r["true_peak_force_n"], 2),
            num(&r["overshoot_pct"], 1),
            num(&r["crush_margin_n"], 2),
            num(&r["hold_test_peak_force_n"], 2),
            num(&r["time_to_stable_s"], 1),
            num(&r["loop_latency_ms_p99"], 1),
            num(&r["pipeline_ms_p99"], 1),
            num(&r["loop_own_ms_p99"], 2),
            num(&r["capture_to_command_ms_p99"], 1),
            num(&r["bus_latency_ms"], 1),
            match (
                num(&r["latency_budget_ms"], 1),
                r["latency_within_budget"].as_bool()
            ) {
                (b, Some(true)) => format!("{b} ok"),
                (b, Some(false)) => format!("{b} over"),
                _ => "-".to_string(),
            },
            num(&r["hold_slip_mm"], 2),
            r["reason"].as_str().unwrap_or("")
        );
    }
}

/// Overshoot against set rate, one line per object (its three resolutions).
fn sweep_figure(rows: &[Value], target: &str) -> crate::plot::Figure {
    let mut names: Vec<String> = rows
        .iter()
        .filter_map(|r| r["scene"].as_str().map(str::to_string))
        .collect();
    names.dedup();
    names.sort();
    names.dedup();
    let series = names
        .iter()
        .map(|name| {
            let mut points: Vec<(f64, Option<f64>)> = rows
                .iter()
                .filter(|r| r["scene"].as_str() == Some(name.as_str()))
                .filter_map(|r| Some((r["set_rate_hz"].as_f64()?, r["overshoot_pct"].as_f64())))
                .collect();
            points.sort_by(|a, b| a.0.total_cmp(&b.0));
            crate::plot::Series {
                name: name.clone(),
                points,
            }
        })
        .collect();
    crate::plot::Figure {
        title: format!(
            "Gentle grasp ({target} N) at 320x240, 160x120, 80x60: overshoot against set rate"
        ),
        x_label: "set rate (Hz)".into(),
        y_label: "overshoot of the true peak force (%)".into(),
        x_unit: "Hz".into(),
        y_unit: "%".into(),
        series,
        bands: Vec::new(),
        markers: true,
        legend: Some(plotters::prelude::SeriesLabelPosition::UpperLeft),
    }
}

/// `gelgrip bench grasp`.
#[derive(Debug, Args)]
pub struct BenchGraspArgs {
    /// The simulated gripper's config (default: the embedded `configs/gelgripper-sim.toml`;
    /// `configs/gelgripper-sim-markers.toml` grasps with marker gels).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Scene files (default: every `configs/scenes/*.toml`).
    #[arg(long = "scene")]
    pub scenes: Vec<PathBuf>,
    /// Force per finger, N, in (0, 200]; or `auto`: each grasp finds its own force (the
    /// rows gain `settled_force_n`).
    #[arg(long, default_value = "1.5", value_parser = parse_target_force)]
    pub target_force: TargetForce,
    /// Simulated seconds per object at most.
    #[arg(long, default_value_t = 25.0)]
    pub duration: f64,
    /// Under `--target-force auto`: after each grasp settles, the object is let go and its
    /// weight comes on over this many seconds (how fast the robot loads the grasp), in
    /// [0, 60]; the rows gain `lift_rise_s`.
    #[arg(long, default_value_t = LIFT_RISE_S, value_parser = parse_lift_rise_s)]
    pub lift_rise_s: f64,
    /// `virtual` (deterministic, as fast as the host can) or `real` (frames arrive as the
    /// bus delivers them: the latency figures measure the host against the bus).
    #[arg(long, value_enum, default_value_t = ClockArg::Virtual)]
    pub clock: ClockArg,
    /// Sweep a system parameter: `resolution` runs every object at 320×240, 160×120 and
    /// 80×60 (the sensors' `resolution` and `mm_per_px` scaled together, the pad unchanged).
    #[arg(long)]
    pub sweep: Option<GraspSweep>,
    /// With `--sweep`: also draw grasp quality against set rate (`.svg` or `.png`).
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Print one JSON array on stdout.
    #[arg(long)]
    pub json: bool,
}

/// What `bench grasp --sweep` varies.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum GraspSweep {
    /// Sensor resolution: 320×240, 160×120, 80×60.
    Resolution,
}

/// `auto`, or a force in N in (0, 200] (`parse_force_n`).
fn parse_target_force(s: &str) -> Result<TargetForce, String> {
    if s.trim() == "auto" {
        return Ok(TargetForce::Auto);
    }
    parse_force_n(s)
        .map(TargetForce::Newtons)
        .map_err(|e| format!("{e}; or `auto`"))
}
