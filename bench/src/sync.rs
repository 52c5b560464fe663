//! `gelgrip bench sync [--json]`: the paper's synchronization experiment. One sensor is
//! desynchronized (`[[hub.sim.faults]]`: a capture skew, a stale delivery or a capture
//! jitter of 0–60 ms, or a drifting board clock) while the gripper grasps an object gently
//! (the paper cup by default), under each gate policy asked for: `trigger` with its window
//! limits (gating on) and without (gating off: any spread, any age), `approximate` with its
//! limits, and `latest`, the unsynchronized baseline, which applies no limit. Each run is a
//! fresh runtime in this process on the virtual clock, through the library's session: the
//! code path `gelgrip run --task gentle-grasp` runs.
//!
//! Overshoot is the simulator's true peak finger force against the target: what the object
//! felt, whatever the controller believed. A gated run whose sets all fail the gate never
//! squeezes, and its row says so (`grasped: false` and the reason); a sensor the gate left
//! out of the sets is named in the row's `excluded_sensors`, with why.

mod plot;
mod report;

use crate::args::{parse_force_n, parse_within};
use clap::{Args, ValueEnum};
use std::path::{Path, PathBuf};

use anyhow::Context;
use serde::Serialize;
use serde_json::Value;

use crate::args::UsageError;
use crate::config_files::{BenchDir, load, load_config, section};
use crate::rig::Rig;
use gelgrip_controller::actuator::XM430_W350;
use gelgrip_controller::clock::ClockKind;
use gelgrip_controller::gate::ExcludedSensor;
use gelgrip_controller::runtime::control::MAX_CLOCK_DRIFT_PPM;
use gelgrip_controller::runtime::gentle_grasp::GraspOptions;
use gelgrip_controller::runtime::options::RunOptions;

/// The configuration every run starts from.
const BASE_CONFIG: &str = "configs/gelgripper-sim.toml";
/// Where `--objects` looks up a name that is not a path.
const SCENES_DIR: &str = "configs/scenes";
/// Gating off: limits no fault of this bench reaches (a second of spread, a minute of age).
const OPEN_SPREAD_US: i64 = 1_000_000;
const OPEN_AGE_MS: f64 = 60_000.0;

/// A gate policy (`[gate] policy`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Policy {
    /// Sets grouped by trigger: rows with the window limits (gating on) and without.
    Trigger,
    /// Sets matched by capture time, with the window limits.
    Approximate,
    /// Each sensor's latest frame, unmatched and unlimited (gating off).
    Latest,
}

impl Policy {
    fn name(self) -> &'static str {
        match self {
            Self::Trigger => "trigger",
            Self::Approximate => "approximate",
            Self::Latest => "latest",
        }
    }

    /// The gating of this policy's rows: `trigger` on and off, `approximate` on, `latest`
    /// off (it never applies the spread limit, and the bench opens its age limit too).
    fn gatings(self) -> &'static [bool] {
        match self {
            Self::Trigger => &[true, false],
            Self::Approximate => &[true],
            Self::Latest => &[false],
        }
    }
}

/// A timing fault on the sensor (`[[hub.sim.faults]]`, docs/sim.md).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Fault {
    /// Capture skew: `capture_delay_us` = the row's delay.
    Capture,
    /// Stale delivery: `delivery_delay_us` = the row's delay.
    Delivery,
    /// Capture jitter: `capture_jitter_us` = the row's delay (the bound of a uniform draw).
    Jitter,
    /// A drifting board clock: `clock_drift_ppm` = the row's drift (`--drift-ppm`).
    Drift,
}

impl Fault {
    fn name(self) -> &'static str {
        match self {
            Self::Capture => "capture",
            Self::Delivery => "delivery",
            Self::Jitter => "jitter",
            Self::Drift => "drift",
        }
    }

    /// The fault's key in `[[hub.sim.faults]]`.
    fn key(self) -> &'static str {
        match self {
            Self::Capture => "capture_delay_us",
            Self::Delivery => "delivery_delay_us",
            Self::Jitter => "capture_jitter_us",
            Self::Drift => "clock_drift_ppm",
        }
    }
}

/// One run of the bench.
#[derive(Debug, Clone)]
struct Case {
    policy: Policy,
    gating: bool,
    fault: Fault,
    /// The delay of a delay fault, ms (0 for drift).
    delay_ms: f64,
    /// The drift of a drift fault, ppm.
    drift_ppm: Option<f64>,
    /// The sensor desynchronized.
    sensor: String,
    scene: PathBuf,
    speed_deg_s: f64,
}

impl Case {
    fn label(&self) -> String {
        let amount = match self.drift_ppm {
            Some(ppm) => format!("{ppm} ppm"),
            None => format!("{} ms", self.delay_ms),
        };
        format!(
            "{} {} {amount} on {}, {}, {} at {} deg/s",
            self.policy.name(),
            self.fault.name(),
            self.sensor,
            if self.gating {
                "gating on"
            } else {
                "gating off"
            },
            object_name(&self.scene),
            self.speed_deg_s
        )
    }
}

/// One row of the bench.
#[derive(Debug, Clone, Serialize)]
pub struct SyncRow {
    /// The gate policy.
    pub policy: Policy,
    /// The fault injected into the sensor.
    pub fault: Fault,
    /// The sensor desynchronized.
    pub sensor: String,
    /// The fault's delay, ms (the jitter's bound for `jitter`; 0 for `drift`).
    pub delay_ms: f64,
    /// The board clock's drift, ppm (`drift` rows; null otherwise).
    pub drift_ppm: Option<f64>,
    /// The gate's window limits (`max_spread_us`, `max_age_ms`) applied.
    pub gating: bool,
    /// The scene grasped (its file's name: `paper-cup`).
    pub object: String,
    /// The approach speed, deg/s.
    pub speed_deg_s: f64,
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
    /// Sensors the gate left out of the sets at the end of the run, with why and since when
    /// (the run report's `excluded_sensors`).
    pub excluded_sensors: Vec<ExcludedSensor>,
    /// On marker gels (a sensor read slip as known): readings of slip on a sensor whose
    /// contacts truly stuck (`run --json`'s `slip.false_alarms`); absent on plain gels.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub slip_false_alarms: Option<u64>,
}

/// `scene`'s name: its file's stem (`paper-cup`).
fn object_name(scene: &Path) -> String {
    scene
        .file_stem()
        .map_or_else(String::new, |s| s.to_string_lossy().into_owned())
}

/// `base` with `case`'s gate and its fault.
fn run_config(base: &toml::Table, case: &Case) -> anyhow::Result<toml::Table> {
    let mut table = base.clone();
    let gate = section(&mut table, "gate")?;
    gate.insert("policy".into(), case.policy.name().into());
    if !case.gating {
        gate.insert("max_spread_us".into(), OPEN_SPREAD_US.into());
        gate.insert("max_age_ms".into(), OPEN_AGE_MS.into());
    }
    let sim = section(section(&mut table, "hub")?, "sim")?;
    let mut fault = toml::Table::new();
    fault.insert("sensor".into(), case.sensor.as_str().into());
    let value: toml::Value = match case.drift_ppm {
        Some(ppm) => ppm.into(),
        None => ((case.delay_ms * 1000.0).round() as i64).into(),
    };
    fault.insert(case.fault.key().into(), value);
    sim.insert("faults".into(), toml::Value::Array(vec![fault.into()]));
    Ok(table)
}

/// The gentle grasp of `case` on `config`.
async fn grasp(
    rig: &dyn Rig,
    case: &Case,
    config: &Path,
    args: &BenchSyncArgs,
) -> anyhow::Result<Value> {
    let defaults = RunOptions::default();
    let options = RunOptions {
        config: Some(config.to_path_buf()),
        scene: Some(case.scene.clone()),
        clock: ClockKind::Virtual,
        task: Some("gentle-grasp".into()),
        grasp: GraspOptions {
            target_force: gelgrip_controller::grasp::TargetForce::Newtons(args.target_force),
            speed_deg_s: case.speed_deg_s,
            ..defaults.grasp.clone()
        },
        headless: true,
        duration_s: Some(args.duration),
        ..defaults
    };
    Ok(rig.run_to_end(&options).await?.report)
}

/// The sum of a report's reason counts (`sets_rejected`, `drops`), and the nonzero ones
/// as `late 3, out_of_window 9`.
fn counts(report: &Value, key: &str) -> (u64, String) {
    let Some(map) = report[key].as_object() else {
        return (0, String::new());
    };
    let nonzero: Vec<(&String, u64)> = map
        .iter()
        .filter_map(|(k, v)| v.as_u64().filter(|&n| n > 0).map(|n| (k, n)))
        .collect();
    let text: Vec<String> = nonzero.iter().map(|(k, n)| format!("{k} {n}")).collect();
    (nonzero.iter().map(|(_, n)| n).sum(), text.join(", "))
}

/// Why the run ended: the task's reason, or why it never squeezed; a run stopped by a fault
/// before the grasp ended names the fault.
fn reason(report: &Value, sets: u64, grasped: bool) -> String {
    let fault = report["faults"][0].as_str();
    if sets == 0 {
        let (refused, refused_by) = counts(report, "sets_rejected");
        let (dropped, dropped_by) = counts(report, "drops");
        let mut why = format!("{refused} refused");
        if refused > 0 {
            why += &format!(": {refused_by}");
        }
        if dropped > 0 {
            why += &format!("; {dropped} frames dropped: {dropped_by}");
        }
        return format!(
            "never squeezed: no set passed the gate ({why}); {}",
            fault.unwrap_or("the run ended")
        );
    }
    let reason = report["reason"].as_str().unwrap_or("").to_string();
    match fault {
        Some(f) if !grasped && !reason.contains(f) => format!("{reason}; {f}"),
        _ => reason,
    }
}

fn row(case: &Case, target_n: f64, report: &Value) -> anyhow::Result<SyncRow> {
    let sets = report["sets"].as_u64().unwrap_or(0);
    let grasped = report["grasped"].as_bool().unwrap_or(false);
    let true_peak = report["true_peak_force_n"].as_f64();
    let squeezed = true_peak.is_some_and(|p| p > 0.0);
    Ok(SyncRow {
        policy: case.policy,
        fault: case.fault,
        sensor: case.sensor.clone(),
        delay_ms: case.delay_ms,
        drift_ppm: case.drift_ppm,
        gating: case.gating,
        object: object_name(&case.scene),
        speed_deg_s: case.speed_deg_s,
        grasped,
        crushed: report["crushed"].as_bool().unwrap_or(false),
        reason: reason(report, sets, grasped),
        overshoot_pct: true_peak
            .filter(|_| squeezed)
            .map(|p| 100.0 * (p - target_n) / target_n),
        final_force_n: report["final_force_n"].as_f64(),
        true_peak_force_n: true_peak,
        sets,
        sets_rejected: counts(report, "sets_rejected").0,
        excluded_sensors: serde_json::from_value(report["excluded_sensors"].clone())
            .context("the run report's excluded_sensors")?,
        slip_false_alarms: marker_false_alarms(&report["slip"]),
    })
}

/// `slip.false_alarms` of a run whose sensors read slip as known (a marker gel).
fn marker_false_alarms(slip: &Value) -> Option<u64> {
    let known: u64 = ["readings_none", "readings_incipient", "readings_gross"]
        .iter()
        .filter_map(|k| slip[k].as_u64())
        .sum();
    (known > 0).then(|| slip["false_alarms"].as_u64()).flatten()
}

/// `--sensor`, or the first sensor `scene` expects in contact (`expect_contact`).
fn sensor_for(scene: &Path, args: &BenchSyncArgs) -> anyhow::Result<String> {
    if let Some(sensor) = &args.sensor {
        return Ok(sensor.clone());
    }
    let table = load(scene)?;
    table
        .get("expect_contact")
        .and_then(|v| v.as_array())
        .and_then(|a| a.first())
        .and_then(|v| v.as_str())
        .map(str::to_string)
        .ok_or_else(|| {
            UsageError(format!(
                "{}: no expect_contact to choose the sensor from (pass --sensor)",
                scene.display()
            ))
            .into()
        })
}

/// The scenes of `--objects` (a name in `configs/scenes`, or a path), else `--scene`,
/// each with the sensor to desynchronize.
fn scenes(args: &BenchSyncArgs) -> anyhow::Result<Vec<(PathBuf, String)>> {
    let scenes: Vec<PathBuf> = if args.objects.is_empty() {
        vec![args.scene.clone()]
    } else {
        args.objects
            .iter()
            .map(|o| {
                if o.ends_with(".toml") || o.contains('/') {
                    PathBuf::from(o)
                } else {
                    Path::new(SCENES_DIR).join(format!("{o}.toml"))
                }
            })
            .collect()
    };
    for scene in &scenes {
        if !scene.exists() {
            return Err(UsageError(format!(
                "{}: no such scene (run the bench from the repository; --objects takes \
                 names in {SCENES_DIR}, such as paper-cup, or paths)",
                scene.display()
            ))
            .into());
        }
    }
    scenes
        .into_iter()
        .map(|scene| {
            let sensor = sensor_for(&scene, args)?;
            Ok((scene, sensor))
        })
        .collect()
}

/// Every run asked for, in the order of the rows: by policy, gating (on first), object,
/// speed and fault; a delay fault over `--delays-ms`, `drift` over `--drift-ppm`.
fn cases(args: &BenchSyncArgs, scenes: &[(PathBuf, String)]) -> Vec<Case> {
    let mut faults = args.faults.clone();
    if !args.drift_ppm.is_empty() && !faults.contains(&Fault::Drift) {
        faults.push(Fault::Drift);
    }
    let drifts = if args.drift_ppm.is_empty() {
        DEFAULT_DRIFT_PPM.to_vec()
    } else {
        args.drift_ppm.clone()
    };
    let mut cases = Vec::new();
    for &policy in &args.policies {
        for &gating in policy.gatings() {
            for (scene, sensor) in scenes {
                for &speed_deg_s in &args.speeds {
                    for &fault in &faults {
                        let base = Case {
                            policy,
                            gating,
                            fault,
                            delay_ms: 0.0,
                            drift_ppm: None,
                            sensor: sensor.clone(),
                            scene: scene.clone(),
                            speed_deg_s,
                        };
                        if fault == Fault::Drift {
                            cases.extend(drifts.iter().map(|&ppm| Case {
                                drift_ppm: Some(ppm),
                                ..base.clone()
                            }));
                        } else {
                            cases.extend(args.delays_ms.iter().map(|&delay_ms| Case {
                                delay_ms,
                                ..base.clone()
                            }));
                        }
                    }
                }
            }
        }
    }
    cases
}

/// `--plot`'s format, checked before the runs: a PNG holds one panel, and these cases
/// plot into as many panels as [`plot::save`] splits their rows into.
fn check_plot(args: &BenchSyncArgs, cases: &[Case]) -> anyhow::Result<()> {
    let Some(out) = &args.plot else {
        return Ok(());
    };
    if crate::plot::Format::of(out)? == crate::plot::Format::Svg {
        return Ok(());
    }
    let mut object_speeds = Vec::new();
    let mut faults = Vec::new();
    for case in cases.iter().filter(|c| c.drift_ppm.is_none()) {
        let key = (case.scene.clone(), case.speed_deg_s.to_bits());
        if !object_speeds.contains(&key) {
            object_speeds.push(key);
        }
        if !faults.contains(&case.fault) {
            faults.push(case.fault);
        }
    }
    let panels = if object_speeds.len() > 1 {
        object_speeds.len()
    } else {
        faults.len()
    };
    if panels > 1 {
        return Err(UsageError(plot::multi_panel_png(out, panels)).into());
    }
    Ok(())
}

/// Run the bench; returns the exit code.
pub async fn run(rig: &dyn Rig, args: BenchSyncArgs) -> anyhow::Result<u8> {
    let scenes = scenes(&args)?;
    let cases = cases(&args, &scenes);
    check_plot(&args, &cases)?;
    let dir = BenchDir::new("bench-sync")?;
    let base = load_config(args.config.as_deref().unwrap_or(Path::new(BASE_CONFIG)))?;
    let total = cases.len();
    let mut rows = Vec::with_capacity(total);
    for (i, case) in cases.iter().enumerate() {
        let label = case.label();
        eprintln!("[{}/{total}] {label}", i + 1);
        let config = dir.write(&format!("run-{i}.toml"), &run_config(&base, case)?)?;
        let report = grasp(rig, case, &config, &args)
            .await
            .with_context(|| label.clone())?;
        rows.push(row(case, args.target_force, &report)?);
    }
    if let Some(plot) = &args.plot {
        plot::save(&rows, args.target_force, plot)?;
        eprintln!("plot: {}", plot.display());
    }
    if args.json {
        println!("{}", serde_json::to_string(&rows)?);
    } else {
        print!("{}", report::table(&rows));
    }
    Ok(0)
}

/// Drifts of `--faults drift` without `--drift-ppm`, ppm.
const DEFAULT_DRIFT_PPM: [f64; 2] = [100.0, 1000.0];

/// `gelgrip bench sync`.
#[derive(Debug, Args)]
pub struct BenchSyncArgs {
    /// The simulated gripper's config every case starts from (default:
    /// `configs/gelgripper-sim.toml`; `configs/gelgripper-sim-markers.toml` for marker gels).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// The deformable object to grasp (a scene file; `--objects` for several).
    #[arg(long, default_value = "configs/scenes/paper-cup.toml")]
    pub scene: PathBuf,
    /// Objects to grasp, each a scene of configs/scenes by name (paper-cup,egg) or a path;
    /// every policy runs on each (default: `--scene`).
    #[arg(long, value_delimiter = ',', conflicts_with = "scene")]
    pub objects: Vec<String>,
    /// Approach speeds, deg/s; every policy runs at each.
    #[arg(long, value_delimiter = ',', default_values_t = [15.0], value_parser = parse_speed_deg_s)]
    pub speeds: Vec<f64>,
    /// The sensor to desynchronize (default: the first the scene expects in contact,
    /// `expect_contact`: f1.middle on the paper cup, f1.tip on the egg).
    #[arg(long)]
    pub sensor: Option<String>,
    /// Gate policies: `trigger` (rows with gating on and off), `approximate` (on), `latest`
    /// (the unsynchronized baseline: off).
    #[arg(long, value_delimiter = ',', default_values_t = [Policy::Trigger])]
    pub policies: Vec<Policy>,
    /// Faults on the sensor: `capture` (capture_delay_us), `delivery` (delivery_delay_us),
    /// `jitter` (capture_jitter_us), each set to every delay of `--delays-ms`; `drift`
    /// (clock_drift_ppm, over `--drift-ppm`).
    #[arg(long, value_delimiter = ',', default_values_t = [Fault::Capture])]
    pub faults: Vec<Fault>,
    /// Delays of the delay faults, ms (comma-separated, each in [0, 60]).
    #[arg(long, value_delimiter = ',', default_values_t = [0.0, 1.0, 2.0, 5.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0], value_parser = parse_delay_ms)]
    pub delays_ms: Vec<f64>,
    /// Board clock drifts, ppm (each in ±1000): adds `drift` rows (delay 0). `--faults
    /// drift` alone runs 100 and 1000.
    #[arg(long, value_delimiter = ',', value_parser = parse_drift_ppm, allow_negative_numbers = true)]
    pub drift_ppm: Vec<f64>,
    /// Force per finger, N.
    #[arg(long, default_value_t = 1.5, value_parser = parse_force_n)]
    pub target_force: f64,
    /// Simulated seconds per run at most.
    #[arg(long, default_value_t = 25.0)]
    pub duration: f64,
    /// Also draw overshoot against delay, one line per policy, gating, fault, object and
    /// speed (`.svg` or `.png`).
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Print one JSON array on stdout.
    #[arg(long)]
    pub json: bool,
}

impl std::fmt::Display for Policy {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::fmt::Display for Fault {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

fn parse_delay_ms(s: &str) -> Result<f64, String> {
    let v: f64 = s.parse().map_err(|e| format!("{s:?}: {e}"))?;
    if v.is_finite() && (0.0..=60.0).contains(&v) {
        Ok(v)
    } else {
        Err(format!("{v} ms: expected a delay in [0, 60] ms"))
    }
}

fn parse_drift_ppm(s: &str) -> Result<f64, String> {
    parse_within(
        s,
        "a drift",
        "ppm",
        -MAX_CLOCK_DRIFT_PPM..=MAX_CLOCK_DRIFT_PPM,
    )
}

fn parse_speed_deg_s(s: &str) -> Result<f64, String> {
    let max = XM430_W350.no_load_deg_s();
    let v: f64 = s
        .parse()
        .map_err(|_| format!("`{s}` is not a speed in deg/s"))?;
    if v.is_finite() && v > 0.0 && v <= max {
        Ok(v)
    } else {
        Err(format!(
            "{s} deg/s is outside (0, {max}] deg/s: {}",
            XM430_W350.no_load_speed_text()
        ))
    }
}
