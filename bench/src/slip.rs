//! `gelgrip bench slip [--config FILE] [--scene FILE]… [--friction LIST] [--load-time-s
//! LIST] [--trials N] [--seed S] [--plot FIG] [--json]`: how early the marker gels feel an
//! object start to slide. Each trial holds an object at 1.5× the least grip that holds its
//! weight, then pulls it along its `slip_dir` by a ramp that reaches the grip's holding
//! limit in the load time, on the virtual clock, until it slides ([`trial`]). The rows
//! give the simulator's truth (incipient and gross slip), the first set a sensor read slip,
//! the sets between detection and gross slip and the false alarms; the summary gives the
//! shares the acceptance names (docs/slip.md). Trial `k` of a cell runs with simulator seed
//! `S + k` (other camera units and noise, and another phase of the load against the sets).
//!
//! `--reflex on` puts the grasp controller and its slip reflex in the loop ([`reflex`]):
//! the rows then say whether the object was kept (its motion, a drop) and with how much
//! more grip than the least that holds the final load.

pub mod plot;
pub mod reflex;
pub mod trial;

use std::path::{Path, PathBuf};

use anyhow::Context;
use clap::Args;
use serde::Serialize;

use gelgrip_controller::clock::VirtualClock;
use gelgrip_controller::config::AppConfig;
use gelgrip_controller::hub::HubTransport;
use gelgrip_plugins::pipeline::SensorPipeline;
use gelgrip_plugins::sensing::REFERENCE_FRAMES;
use gelgrip_sim::config::SimConfig;
use gelgrip_sim::hub::SimHub;
use gelgrip_sim::press_camera::sensor_camera;
use gelgrip_sim::scene_spec::SceneSpec;

use crate::config_files::{BenchDir, load_config, scene_files, section};
use crate::rig::Rig;
use trial::{Rigging, SlipRow, TraceSet, TrialSpec};

/// The marker configuration `bench slip` runs on unless `--config` says otherwise.
pub const MARKER_CONFIG: &str = "configs/gelgripper-sim-markers.toml";

/// A list of positive numbers, for `--friction` and `--load-time-s`.
fn parse_positive(s: &str, what: &str, max: f64) -> Result<f64, String> {
    let v: f64 = s
        .trim()
        .parse()
        .map_err(|_| format!("`{s}` is not a number ({what})"))?;
    if v.is_finite() && v > 0.0 && v <= max {
        Ok(v)
    } else {
        Err(format!("{what} must be in (0, {max}]; got {s}"))
    }
}

fn parse_friction(s: &str) -> Result<f64, String> {
    parse_positive(s, "a friction coefficient", 10.0)
}

fn parse_load_time(s: &str) -> Result<f64, String> {
    parse_positive(s, "a load time in seconds", 600.0)
}

/// Arguments of `gelgrip bench slip`.
#[derive(Debug, Clone, Args)]
pub struct BenchSlipArgs {
    /// The configuration whose hand, cameras and pipelines run the trials.
    #[arg(long, default_value = MARKER_CONFIG)]
    pub config: PathBuf,
    /// A scene file with an object (repeatable; default: the six of configs/scenes).
    #[arg(long = "scene")]
    pub scenes: Vec<PathBuf>,
    /// Friction coefficients μ to run each object at (comma-separated).
    #[arg(long, value_delimiter = ',', default_value = "0.3,0.6,1.0", value_parser = parse_friction)]
    pub friction: Vec<f64>,
    /// Seconds for the ramp to reach the holding limit (comma-separated).
    #[arg(long = "load-time-s", value_delimiter = ',', default_value = "0.5,1.5,5", value_parser = parse_load_time)]
    pub load_time_s: Vec<f64>,
    /// Trials per object, friction and load time.
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub trials: u32,
    /// The first trial's simulator seed (default: the config's `hub.sim.seed`).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Draw the first trial (load, true and estimated stick ratio, detection), .svg or .png.
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// The slip reflex: `on` puts the grasp controller in the loop and the ramp stops at
    /// 80% of what `[grasp] max_force_n` can hold; `off` (the default) measures the
    /// sensing alone, the object pulled until it slides.
    #[arg(long, value_enum, default_value = "off")]
    pub reflex: OnOff,
    /// Print `{"rows": […], "summary": {…}}` on one line.
    #[arg(long)]
    pub json: bool,
}

/// A switch on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum OnOff {
    /// On.
    On,
    /// Off.
    Off,
}

/// The sweep's shares, as the acceptance names them.
#[derive(Debug, Clone, Serialize)]
pub struct SlipSummary {
    /// Trials run.
    pub trials: usize,
    /// Trials that slid (the truth's gross slip within the trial).
    pub slid: usize,
    /// Trials where slip was detected.
    pub detected: usize,
    /// Share of trials detected at least 2 sets before gross slip.
    pub lead_2_sets_share: f64,
    /// Share of trials with no detection before the true incipient slip.
    pub not_early_share: f64,
    /// Rows with a false alarm.
    pub rows_with_false_alarms: usize,
    /// False alarms over all rows.
    pub false_alarms: u64,
    /// The median of `lead_sets` over the detected trials.
    pub lead_sets_median: Option<f64>,
    /// The median true stick ratio at detection.
    pub true_stick_ratio_at_detect_median: Option<f64>,
    /// Trials whose object was dropped.
    pub dropped: usize,
    /// Share of trials whose object moved less than 1 mm against the fingers.
    pub motion_under_1mm_share: f64,
    /// The largest `final_grip_n / least_grip_n` over the trials that were not dropped.
    pub grip_over_least_max: Option<f64>,
    /// Its median.
    pub grip_over_least_median: Option<f64>,
}

fn median(mut v: Vec<f64>) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    Some(v[v.len() / 2])
}

/// The summary of `rows`.
pub fn summarize(rows: &[SlipRow]) -> SlipSummary {
    let n = rows.len().max(1) as f64;
    let share = |f: &dyn Fn(&SlipRow) -> bool| rows.iter().filter(|r| f(r)).count() as f64 / n;
    SlipSummary {
        trials: rows.len(),
        slid: rows.iter().filter(|r| r.t_gross_s.is_some()).count(),
        detected: rows.iter().filter(|r| r.t_detect_s.is_some()).count(),
        lead_2_sets_share: share(&|r| r.lead_sets.is_some_and(|l| l >= 2)),
        not_early_share: share(&|r| match (r.t_detect_s, r.t_incipient_s) {
            (None, _) => true,
            (Some(d), Some(i)) => d >= i,
            (Some(_), None) => false,
        }),
        rows_with_false_alarms: rows.iter().filter(|r| r.false_alarms > 0).count(),
        false_alarms: rows.iter().map(|r| u64::from(r.false_alarms)).sum(),
        lead_sets_median: median(
            rows.iter()
                .filter_map(|r| r.lead_sets.map(|l| l as f64))
                .collect(),
        ),
        true_stick_ratio_at_detect_median: median(
            rows.iter()
                .filter_map(|r| r.true_stick_ratio_at_detect)
                .collect(),
        ),
        dropped: rows.iter().filter(|r| r.dropped).count(),
        motion_under_1mm_share: share(&|r| r.motion_mm < 1.0),
        grip_over_least_max: grip_over_least(rows).reduce(f64::max),
        grip_over_least_median: median(grip_over_least(rows).collect()),
    }
}

/// `final_grip_n / least_grip_n` of each row kept with a load on it.
fn grip_over_least(rows: &[SlipRow]) -> impl Iterator<Item = f64> + '_ {
    rows.iter()
        .filter(|r| !r.dropped && r.least_grip_n > 0.0)
        .map(|r| r.final_grip_n / r.least_grip_n)
}

/// The scene at `path` for `config`'s hand.
fn read_scene(path: &Path, config: &AppConfig) -> anyhow::Result<SceneSpec> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    Ok(SceneSpec::from_toml(
        &path.display().to_string(),
        &text,
        &config.layout,
    )?)
}

/// The bus's set period under `config`, µs (the simulated hub's model).
fn set_period_us(config: &AppConfig, sim: &SimConfig) -> anyhow::Result<u64> {
    let hub = SimHub::new(
        &config.layout,
        config.hub.trigger,
        sim.clone(),
        VirtualClock::new(),
    )
    .context("the simulated hub")?;
    Ok(hub.describe().prediction.set_period_us.round().max(1.0) as u64)
}

/// One seed's configuration, the run's pipelines for it and their no-contact frames.
struct Seeded {
    config: AppConfig,
    sim: SimConfig,
    pipes: Vec<SensorPipeline>,
    quiet: Vec<Vec<Vec<u8>>>,
}

impl Seeded {
    /// Reference every pipeline afresh on its no-contact frames (its drift tracking and
    /// dot tracking start over), as a new run's would be.
    fn reference(&mut self) -> anyhow::Result<()> {
        for (pipe, frames) in self.pipes.iter_mut().zip(&self.quiet) {
            let frames: Vec<&[u8]> = frames.iter().map(Vec::as_slice).collect();
            pipe.calibrate(&frames)?;
        }
        Ok(())
    }
}

fn seeded(rig: &dyn Rig, base: &Path, dir: &BenchDir, seed: u64) -> anyhow::Result<Seeded> {
    let mut table = load_config(base)?;
    section(section(&mut table, "hub")?, "sim")?.insert("seed".into(), (seed as i64).into());
    let path = dir.write(&format!("seed-{seed}.toml"), &table)?;
    let config = rig.load_config(Some(&path))?;
    let sim = SimConfig::from_section(&config.hub.section, &config.layout)?;
    let quiet = config
        .layout
        .sensors
        .iter()
        .map(|spec| {
            let (cam, _) = sensor_camera(&config, &spec.id.to_string())?;
            Ok(cam.untouched_frames(QUIET_FIRST_FRAME, REFERENCE_FRAMES)?)
        })
        .collect::<anyhow::Result<_>>()?;
    let pipes = rig.sensor_pipelines(&config)?;
    Ok(Seeded {
        config,
        sim,
        pipes,
        quiet,
    })
}

/// The no-contact frames' numbers start here (frames the trials' sets never use).
const QUIET_FIRST_FRAME: u64 = 7_000_000;

/// Run the command; returns the exit code.
pub fn run(rig: &dyn Rig, args: BenchSlipArgs) -> anyhow::Result<u8> {
    // A figure's format is checked before the sweep, not after it.
    if let Some(path) = &args.plot {
        crate::plot::Format::of(path)?;
    }
    let base = rig.load_config(Some(&args.config))?;
    let base_sim = SimConfig::from_section(&base.hub.section, &base.layout).with_context(|| {
        format!(
            "{}: bench slip runs on the simulated hub",
            args.config.display()
        )
    })?;
    let first_seed = args.seed.unwrap_or(base_sim.seed);
    let scenes = scene_files(&args.scenes)?
        .iter()
        .map(|p| read_scene(p, &base))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let period_us = set_period_us(&base, &base_sim)?;
    let dir = BenchDir::new("bench-slip")?;
    let max_current_ma = gelgrip_controller::grasp::Tuning::default().max_hold_current_ma;
    let cells = scenes.len() * args.friction.len() * args.load_time_s.len();
    let bar = crate::progress::bar((cells * args.trials as usize) as u64, "trials");
    let mut rows = Vec::new();
    let mut first_trace: Option<Vec<TraceSet>> = None;
    // Each object held at each friction (neither depends on the trial or the load time).
    let mut holds = std::collections::HashMap::new();
    for k in 0..args.trials as usize {
        let seed = first_seed.wrapping_add(k as u64);
        let mut s = seeded(rig, &args.config, &dir, seed)?;
        for (i, scene) in scenes.iter().enumerate() {
            for (j, &mu) in args.friction.iter().enumerate() {
                let held = holds.entry((i, j)).or_insert_with(|| {
                    let scene = trial::held_scene(scene, mu);
                    let aim = trial::grip_aim_n(&scene);
                    trial::hold(&s.config.layout, &scene, aim, max_current_ma)
                });
                for &load_time_s in &args.load_time_s {
                    s.reference()?;
                    let mut rigging = Rigging {
                        config: &s.config,
                        sim: &s.sim,
                        pipes: &mut s.pipes,
                        set_period_us: period_us,
                    };
                    let spec = TrialSpec {
                        held,
                        load_time_s,
                        trial: k,
                        seed,
                    };
                    let (row, trace) = match args.reflex {
                        OnOff::On => reflex::run(&mut rigging, &spec)?,
                        OnOff::Off => trial::run(&mut rigging, &spec)?,
                    };
                    first_trace.get_or_insert(trace);
                    rows.push(row);
                    crate::progress::advance(&bar, "trials");
                }
            }
        }
    }
    bar.finish_and_clear();
    if let (Some(path), Some(trace)) = (&args.plot, &first_trace) {
        plot::draw(&rows[0], trace, path)?;
    }
    let summary = summarize(&rows);
    if args.json {
        println!("{}", serde_json::json!({"rows": rows, "summary": summary}));
    } else {
        print_table(&rows, &summary);
    }
    Ok(0)
}

fn opt(v: Option<f64>, decimals: usize) -> String {
    v.map_or("-".into(), |v| format!("{v:.decimals$}"))
}

fn print_table(rows: &[SlipRow], s: &SlipSummary) {
    println!(
        "{:<14} {:>5} {:>6} {:>5} {:>7} {:>8} {:>9} {:>8} {:>8} {:>5} {:>6} {:>7} {:>7} {:>7} {:>4}",
        "object",
        "mu",
        "load_s",
        "trial",
        "grip_N",
        "limit_N",
        "incip_s",
        "gross_s",
        "detect_s",
        "lead",
        "false",
        "move_mm",
        "final_N",
        "least_N",
        "drop"
    );
    for r in rows {
        println!(
            "{:<14} {:>5.2} {:>6.2} {:>5} {:>7.2} {:>8.2} {:>9} {:>8} {:>8} {:>5} {:>6} {:>7.2} {:>7.2} {:>7.2} {:>4}",
            r.object,
            r.friction,
            r.load_time_s,
            r.trial,
            r.grip_n,
            r.holding_limit_n,
            opt(r.t_incipient_s, 3),
            opt(r.t_gross_s, 3),
            opt(r.t_detect_s, 3),
            r.lead_sets.map_or("-".into(), |l| l.to_string()),
            r.false_alarms,
            r.motion_mm,
            r.final_grip_n,
            r.least_grip_n,
            if r.dropped { "yes" } else { "no" }
        );
    }
    println!(
        "trials {}  slid {}  detected {}  lead >= 2 sets {:.1}%  not before incipient {:.1}%  \
         rows with false alarms {}  median lead {} sets\n\
         dropped {}  motion < 1 mm {:.1}%  final/least grip: median {}, max {}",
        s.trials,
        s.slid,
        s.detected,
        100.0 * s.lead_2_sets_share,
        100.0 * s.not_early_share,
        s.rows_with_false_alarms,
        opt(s.lead_sets_median, 0),
        s.dropped,
        100.0 * s.motion_under_1mm_share,
        opt(s.grip_over_least_median, 2),
        opt(s.grip_over_least_max, 2)
    );
}
