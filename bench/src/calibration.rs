//! `gelgrip bench calibration`: the paper's Table II on simulated sensors.
//!
//! Seven simulated sensors (the gripper's layout, each with its own unit-to-unit variation:
//! LED gains, colour offsets, vignetting) each get a press dataset; the last 10% of every
//! dataset is held out. Columns:
//! - individual LUT, individual raw MLP, individual diff MLP: trained on each sensor's own
//!   presses;
//! - zero-shot raw, zero-shot diff: the first sensor's MLPs, transferred to each other
//!   sensor with a per-channel offset fitted on that sensor's first press (the paper);
//! - zero-shot raw/diff with offset and gain: the same with a per-channel gain as well (an
//!   extension; reported beside, not instead).
//!
//! Every column is scored on the same presses: the held-out presses of the six target
//! sensors (every sensor but the source), pixel-weighted, with the contract's `gx_mae` and
//! `gy_mae`. Nothing about the ordering is assumed; the table is what the data gives.
//!
//! Beside the table, rows on the realistic optics (`[hub.sim] optics = "realistic"`, the
//! simulated GelSight Mini): the first sensor's presses rendered with them, a LUT and an MLP
//! trained as `calibrate train` does with its defaults (the MLP with its validation split and
//! early stopping), each with its held-out MAE and training time.

use clap::Args;
use serde::Serialize;

use gelgrip_plugins::calibrate::{self, EvalReport};
use gelgrip_plugins::dataset::PressDataset;
use gelgrip_plugins::gradient::{GradientModel, MlpMode};
use gelgrip_plugins::lut::{DEFAULT_BINS, Input, LutSpec};
use gelgrip_plugins::mlp::MlpModel;
use gelgrip_plugins::mlp::train::TrainOptions;
use gelgrip_plugins::mlp::transfer::{Fit, transfer};
use gelgrip_sim::config::SimConfig;

use gelgrip_sim::press_camera::sensor_camera;

use crate::progress;
use crate::rig::Rig;
use crate::sensor_models::sim_presses;

#[derive(Debug, Serialize)]
struct Column {
    name: &'static str,
    data_used_presses: usize,
    gx_mae: f64,
    gy_mae: f64,
    pixels: usize,
}

#[derive(Debug, Serialize)]
struct SensorScores {
    sensor: String,
    role: &'static str,
    /// Per column name, (gx_mae, gy_mae) on this sensor's held-out presses.
    scores: Vec<(&'static str, f64, f64)>,
    offset_rgb_raw: Option<[f32; 3]>,
    offset_rgb_diff: Option<[f32; 3]>,
}

#[derive(Debug, Serialize)]
struct Report {
    sensors: usize,
    presses_per_sensor: usize,
    test_presses_per_sensor: usize,
    source_sensor: String,
    hidden: usize,
    epochs: usize,
    columns: Vec<Column>,
    per_sensor: Vec<SensorScores>,
    /// LUT against MLP on the realistic optics (the first sensor).
    realistic: Vec<RealisticRow>,
    seconds: f64,
}

#[derive(Debug, Serialize)]
struct RealisticRow {
    model: &'static str,
    sensor: String,
    train_presses: usize,
    test_presses: usize,
    gx_mae: f64,
    gy_mae: f64,
    train_s: f64,
    /// MLP: the epoch whose weights were kept and the last one run.
    best_epoch: Option<usize>,
    stopped_at_epoch: Option<usize>,
}

/// Pixel-weighted accumulation of a column over sensors.
#[derive(Default, Clone, Copy)]
struct Sum {
    gx: f64,
    gy: f64,
    n: usize,
}

impl Sum {
    fn add(&mut self, r: &EvalReport) {
        self.gx += r.gx_mae * r.pixels as f64;
        self.gy += r.gy_mae * r.pixels as f64;
        self.n += r.pixels;
    }
}

const NAMES: [&str; 7] = [
    "individual_lut",
    "individual_raw_mlp",
    "individual_diff_mlp",
    "zero_shot_raw",
    "zero_shot_diff",
    "zero_shot_raw_offset_gain",
    "zero_shot_diff_offset_gain",
];

/// Run the command; returns the exit code.
pub fn run(rig: &dyn Rig, args: BenchCalibrationArgs) -> anyhow::Result<u8> {
    let started = std::time::Instant::now();
    let config = rig.load_config(None)?;
    let presses = args.presses as usize;
    let tmp =
        std::env::temp_dir().join(format!("gelgrip-bench-calibration-{}", std::process::id()));
    let ids = config.layout.sensor_ids();
    let datasets = hand_datasets(&config, &ids, presses, &tmp)?;
    let opts = TrainOptions {
        hidden: usize::from(args.hidden),
        epochs: args.epochs as usize,
        ..TrainOptions::default()
    };
    let test_rows = |ds: &PressDataset| calibrate::split_index(ds.presses.len())..ds.presses.len();
    let train = |ds: &PressDataset, input: Input, what: &str| train_mlp(ds, input, what, &opts);
    let source_raw = train(&datasets[0], Input::Raw, &format!("{} (source)", ids[0]))?;
    let source_diff = train(&datasets[0], Input::Diff, &format!("{} (source)", ids[0]))?;
    let mut sums = [Sum::default(); 7];
    let mut per_sensor = Vec::new();
    for (i, ds) in datasets.iter().enumerate() {
        let role = if i == 0 { "source" } else { "target" };
        let mut scores = Vec::new();
        let (raw, diff) = if i == 0 {
            (source_raw.clone(), source_diff.clone())
        } else {
            (
                train(ds, Input::Raw, &ids[i])?,
                train(ds, Input::Diff, &ids[i])?,
            )
        };
        let lut = calibrate::train_lut(ds, LutSpec::means(Input::Diff, DEFAULT_BINS))?;
        let mut models = vec![
            GradientModel::lut(lut),
            GradientModel::mlp(raw, MlpMode::Dense)?,
            GradientModel::mlp(diff, MlpMode::Dense)?,
        ];
        let (mut off_raw, mut off_diff) = (None, None);
        if i > 0 {
            let zero_shot = zero_shot_models(ds, [&source_raw, &source_diff])?;
            (off_raw, off_diff) = (zero_shot.offset_rgb_raw, zero_shot.offset_rgb_diff);
            models.extend(zero_shot.models);
        }
        for (k, model) in models.iter().enumerate() {
            let r = calibrate::evaluate(model, ds, test_rows(ds), None)?;
            scores.push((NAMES[k], r.gx_mae, r.gy_mae));
            if i > 0 {
                sums[k].add(&r);
            }
        }
        eprintln!(
            "  {}: {}",
            ids[i],
            scores
                .iter()
                .map(|(n, x, y)| format!("{n} {x:.4}/{y:.4}"))
                .collect::<Vec<_>>()
                .join(", ")
        );
        per_sensor.push(SensorScores {
            sensor: ids[i].clone(),
            role,
            scores,
            offset_rgb_raw: off_raw,
            offset_rgb_diff: off_diff,
        });
    }
    let realistic = realistic_rows(&config, &ids[0], presses, &opts, &tmp.join("realistic"))?;
    let _ = std::fs::remove_dir_all(&tmp);
    let n = ids.len();
    let columns = columns(sums, presses, n);
    let report = Report {
        sensors: n,
        presses_per_sensor: presses,
        test_presses_per_sensor: presses - calibrate::split_index(presses),
        source_sensor: ids[0].clone(),
        hidden: opts.hidden,
        epochs: opts.epochs,
        columns,
        per_sensor,
        realistic,
        seconds: started.elapsed().as_secs_f64(),
    };
    if args.json {
        println!("{}", serde_json::to_string(&report)?);
    } else {
        print_table(&report);
    }
    Ok(0)
}

/// Table II's columns: each model's mean error over the target sensors, and the presses it
/// needed (its own sensor's for the trained ones; the source's and one per target for the
/// transferred ones).
fn columns(sums: [Sum; 7], presses: usize, sensors: usize) -> Vec<Column> {
    let zero_shot_data = presses + (sensors - 1);
    NAMES
        .iter()
        .zip(sums)
        .enumerate()
        .map(|(k, (name, s))| Column {
            name,
            data_used_presses: if k < 3 {
                presses * sensors
            } else {
                zero_shot_data
            },
            gx_mae: s.gx / s.n.max(1) as f64,
            gy_mae: s.gy / s.n.max(1) as f64,
            pixels: s.n,
        })
        .collect()
}

/// `presses` simulated presses on every sensor `ids` of `config`, each with its own press
/// positions (the camera keeps its unit variation), under `tmp`.
fn hand_datasets(
    config: &gelgrip_controller::config::AppConfig,
    ids: &[String],
    presses: usize,
    tmp: &std::path::Path,
) -> anyhow::Result<Vec<PressDataset>> {
    let mut datasets = Vec::new();
    for (i, id) in ids.iter().enumerate() {
        let (cam, sim) = sensor_camera(config, id)?;
        eprintln!("collecting {presses} presses on simulated sensor {id}");
        let presses_sim = SimConfig {
            seed: sim.seed ^ (0x5EED_0000 + i as u64),
            ..sim.clone()
        };
        datasets.push(sim_presses(&cam, &presses_sim, presses, &tmp.join(id))?);
    }
    Ok(datasets)
}

/// Train an MLP on `ds`'s training rows with `opts`, with a progress bar.
fn train_mlp(
    ds: &PressDataset,
    input: Input,
    what: &str,
    opts: &TrainOptions,
) -> anyhow::Result<MlpModel> {
    eprintln!(
        "training {what} mlp ({} input) on {} presses",
        input.as_str(),
        calibrate::split_index(ds.presses.len())
    );
    let bar = progress::epochs(opts.epochs as u64);
    let m = calibrate::train_mlp_on(&[ds], input, opts, progress::epoch_reporter(&bar))?;
    bar.finish_and_clear();
    Ok(m)
}

/// The source sensor's MLPs transferred to a target sensor from its first press.
struct ZeroShot {
    /// Offset fits of the raw and the difference MLP, then offset-and-gain fits of both.
    models: Vec<GradientModel>,
    /// The raw MLP's offset fit.
    offset_rgb_raw: Option<[f32; 3]>,
    /// The difference MLP's offset fit.
    offset_rgb_diff: Option<[f32; 3]>,
}

/// Transfer `[raw, diff]` (the source's MLPs) to `ds`'s sensor, offset then offset and gain.
fn zero_shot_models(ds: &PressDataset, [raw, diff]: [&MlpModel; 2]) -> anyhow::Result<ZeroShot> {
    let mut out = ZeroShot {
        models: Vec::new(),
        offset_rgb_raw: None,
        offset_rgb_diff: None,
    };
    for (fit, source) in [
        (Fit::Offset, raw),
        (Fit::Offset, diff),
        (Fit::OffsetGain, raw),
        (Fit::OffsetGain, diff),
    ] {
        let press = calibrate::press_pixels(ds, 0, source.input)?;
        let (m, r) = transfer(source, &press, fit)?;
        if fit == Fit::Offset {
            match source.input {
                Input::Raw => out.offset_rgb_raw = Some(r.offset_rgb),
                Input::Diff | Input::Relative => out.offset_rgb_diff = Some(r.offset_rgb),
            }
        }
        out.models.push(GradientModel::mlp(m, MlpMode::Dense)?);
    }
    Ok(out)
}

/// LUT and MLP on `presses` presses of sensor `id` under the realistic optics, trained as
/// `calibrate train` does (the MLP with `opts` and its validation split), timed.
fn realistic_rows(
    config: &gelgrip_controller::config::AppConfig,
    id: &str,
    presses: usize,
    opts: &TrainOptions,
    dir: &std::path::Path,
) -> anyhow::Result<Vec<RealisticRow>> {
    let (_, sim) = sensor_camera(config, id)?;
    let mini = gelgrip_sim::optics::realistic::MINI;
    let sim = SimConfig {
        noise_sigma: mini.noise_rgb.iter().sum::<f64>() / 3.0,
        noise_rgb: mini.noise_rgb,
        optics: gelgrip_sim::optics::Optics::Realistic(Box::new(mini)),
        ..sim
    };
    let index = config.layout.index_of(id).unwrap_or(0);
    let cam = gelgrip_sim::pool::SensorCamera::new(&config.layout, index, &sim)
        .ok_or_else(|| anyhow::anyhow!("no sensor {id}"))?;
    eprintln!("collecting {presses} realistic-optics presses on simulated sensor {id}");
    let ds = sim_presses(&cam, &sim, presses, dir)?;
    let test = calibrate::split_index(ds.presses.len())..ds.presses.len();
    let started = std::time::Instant::now();
    let lut = calibrate::train_lut(&ds, LutSpec::means(Input::Diff, DEFAULT_BINS))?;
    let lut_s = started.elapsed().as_secs_f64();
    eprintln!("training the realistic-optics mlp on {id}");
    let started = std::time::Instant::now();
    let bar = progress::epochs(opts.epochs as u64);
    let v =
        calibrate::train_mlp_validated(&[&ds], Input::Diff, opts, progress::epoch_reporter(&bar))?;
    bar.finish_and_clear();
    let mlp_s = started.elapsed().as_secs_f64();
    let split = calibrate::validation_split_of(&ds)?;
    let mut rows = Vec::new();
    for (model, name, train_presses, train_s, summary) in [
        (GradientModel::lut(lut), "lut", test.start, lut_s, None),
        (
            GradientModel::mlp(v.model, MlpMode::Dense)?,
            "mlp",
            split.train.len(),
            mlp_s,
            Some(v.summary),
        ),
    ] {
        let r = calibrate::evaluate(&model, &ds, test.clone(), None)?;
        rows.push(RealisticRow {
            model: name,
            sensor: id.to_string(),
            train_presses,
            test_presses: r.presses,
            gx_mae: r.gx_mae,
            gy_mae: r.gy_mae,
            train_s,
            best_epoch: summary.as_ref().map(|s| s.best_epoch),
            stopped_at_epoch: summary.as_ref().map(|s| s.stopped_at),
        });
    }
    let _ = std::fs::remove_dir_all(dir);
    Ok(rows)
}

fn print_table(r: &Report) {
    println!(
        "bench calibration: {} simulated sensors, {} presses each ({} held out), source {}, mlp 5-{h}-{h}-{h}-2, {} epochs ({:.0} s)",
        r.sensors,
        r.presses_per_sensor,
        r.test_presses_per_sensor,
        r.source_sensor,
        r.epochs,
        r.seconds,
        h = r.hidden
    );
    println!(
        "  scored on the held-out presses of the {} target sensors",
        r.sensors - 1
    );
    let head = [
        "",
        "indiv. LUT",
        "indiv. raw",
        "indiv. diff",
        "0-shot raw",
        "0-shot diff",
        "0-shot raw+g",
        "0-shot diff+g",
    ];
    println!(
        "  {:<14}{}",
        head[0],
        head[1..]
            .iter()
            .map(|h| format!("{h:>14}"))
            .collect::<String>()
    );
    let row = |label: &str, f: &dyn Fn(&Column) -> String| {
        println!(
            "  {label:<14}{}",
            r.columns
                .iter()
                .map(|c| format!("{:>14}", f(c)))
                .collect::<String>()
        );
    };
    row("data used", &|c| c.data_used_presses.to_string());
    row("Gx MAE", &|c| format!("{:.4}", c.gx_mae));
    row("Gy MAE", &|c| format!("{:.4}", c.gy_mae));
    println!("  realistic optics (the simulated GelSight Mini), held-out presses:");
    for row in &r.realistic {
        println!(
            "  {:<14}{} trained on {} presses in {:.1} s, tested on {}: Gx {:.4} Gy {:.4}",
            row.model,
            row.sensor,
            row.train_presses,
            row.train_s,
            row.test_presses,
            row.gx_mae,
            row.gy_mae
        );
    }
}

/// `gelgrip bench calibration`.
#[derive(Debug, Args)]
pub struct BenchCalibrationArgs {
    /// Presses per sensor (the last 10% held out).
    #[arg(long, default_value = "50", value_parser = clap::value_parser!(u32).range(4..=2000))]
    pub presses: u32,
    /// MLP training epochs.
    #[arg(long, default_value_t = crate::args::DEFAULT_EPOCHS, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    pub epochs: u32,
    /// MLP hidden layer width.
    #[arg(long, default_value = "32", value_parser = clap::value_parser!(u16).range(1..=1024))]
    pub hidden: u16,
    /// Print one JSON object on stdout.
    #[arg(long)]
    pub json: bool,
}
