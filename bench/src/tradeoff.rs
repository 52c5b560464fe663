//! `gelgrip bench tradeoff`: what accuracy each millisecond buys.
//!
//! The gripper's seven simulated sensors are calibrated once, each on its own presses: a
//! LUT, an MLP, and that MLP baked into a tiled LUT (the transfer's effect is `bench
//! calibration`'s subject; here models are compared like for like). Then every combination of decode resolution (full, 1/2, 1/4 by
//! scaled JPEG decode), gradient model (lut, dense mlp, contact-only mlp, baked mlp) and
//! depth solver (dst, dct, none) runs the same sets: each sensor pressed by its built-in
//! ball. A row gives the median wall-clock time per set of 7 (rayon across sensors) and the
//! errors against the simulator's truth at that resolution, over the pixels where the true
//! depth is positive (CONTRACTS.md): `gx_mae`, `gy_mae` (px per px), `depth_mae_mm`, and
//! `area_iou` of the contact mask. With solver `none` the pipeline stops at the gradients:
//! depth is null and the contact mask comes from block activity.

use clap::Args;
use std::path::Path;
use std::path::PathBuf;
use std::time::Instant;

use serde::Serialize;

use gelgrip_plugins::config::{PipelineConfig, SensorStages};
use gelgrip_plugins::contact::ContactSummary;
use gelgrip_plugins::gradient::{GradientModel, MlpMode};
use gelgrip_plugins::mlp::bake::{BakeOptions, bake};
use gelgrip_plugins::mlp::train::TrainOptions;
use gelgrip_plugins::pipeline::{Needs, SensorPipeline, StageChoice, process_set};
use gelgrip_plugins::poisson::Solver;
use gelgrip_sim::pool::SensorCamera;
use gelgrip_sim::scene::HeightMap;

use crate::plot::{Figure, Series};
use crate::rig::Rig;
use crate::sensor_models::{self, MlpPlan};

/// One configuration's result.
#[derive(Debug, Clone, Serialize)]
pub struct Row {
    /// `full`, `1/2` or `1/4`.
    pub resolution: &'static str,
    /// `lut`, `mlp-dense`, `mlp-contact` or `baked-mlp`.
    pub model: &'static str,
    /// `dst`, `dct` or `none`.
    pub solver: &'static str,
    /// Median wall-clock time per set of all sensors, ms.
    pub ms_per_set: f64,
    /// Mean |gx − truth| where the true depth is positive.
    pub gx_mae: Option<f64>,
    /// Mean |gy − truth| there.
    pub gy_mae: Option<f64>,
    /// Mean |depth − truth| there, mm (null without a solver).
    pub depth_mae_mm: Option<f64>,
    /// Intersection over union of the contact mask with the true contact.
    pub area_iou: Option<f64>,
    /// On the Pareto front of (ms_per_set, depth_mae_mm) among rows with depth.
    pub pareto: bool,
}

const NOISE_FRAMES: u64 = 20;
const FRAMES: u64 = 8;
const WARMUP_SETS: usize = 3;

/// A sensor's truth at one decode scale.
struct Truth {
    depth_mm: Vec<f64>,
    gx: Vec<f64>,
    gy: Vec<f64>,
}

fn truth_at(map: &HeightMap, scale: usize, mm_per_px: f64) -> Truth {
    let (w, h) = (map.width_px / scale, map.height_px / scale);
    let mut depth_mm = vec![0.0; w * h];
    for y in 0..h {
        for x in 0..w {
            let mut s = 0.0;
            for dy in 0..scale {
                for dx in 0..scale {
                    s += f64::from(map.depth_mm[(y * scale + dy) * map.width_px + x * scale + dx]);
                }
            }
            depth_mm[y * w + x] = s / (scale * scale) as f64;
        }
    }
    let px = mm_per_px * scale as f64;
    let (mut gx, mut gy) = (vec![0.0; w * h], vec![0.0; w * h]);
    for y in 0..h {
        for x in 0..w {
            let z = depth_mm[y * w + x] / px;
            if x + 1 < w {
                gx[y * w + x] = depth_mm[y * w + x + 1] / px - z;
            }
            if y + 1 < h {
                gy[y * w + x] = depth_mm[(y + 1) * w + x] / px - z;
            }
        }
    }
    Truth { depth_mm, gx, gy }
}

/// Sums of errors over frames and sensors.
#[derive(Default)]
struct Score {
    gx: f64,
    gy: f64,
    depth: f64,
    n: usize,
    iou: f64,
    frames: usize,
}

impl Score {
    fn add(
        &mut self,
        pipe: &SensorPipeline,
        truth: &Truth,
        with_depth: bool,
        mask: &mut Vec<bool>,
    ) {
        let (w, _) = pipe.size();
        let (gx, gy, (x0, y0, ww, wh)) = pipe.last_gradients();
        let (depth, _) = pipe.last_depth_mm();
        let inside = |x: usize, y: usize| x >= x0 && y >= y0 && x < x0 + ww && y < y0 + wh;
        pipe.last_contact_mask(mask);
        let (mut inter, mut union) = (0usize, 0usize);
        for (p, d) in truth.depth_mm.iter().enumerate() {
            let (x, y) = (p % w, p / w);
            let touched = *d > 0.0;
            inter += usize::from(touched && mask[p]);
            union += usize::from(touched || mask[p]);
            if !touched {
                continue;
            }
            let k = (inside(x, y)).then(|| (y - y0) * ww + (x - x0));
            let at = |v: &[f32]| k.map_or(0.0, |k| f64::from(v[k]));
            self.gx += (at(gx) - truth.gx[p]).abs();
            self.gy += (at(gy) - truth.gy[p]).abs();
            if with_depth {
                self.depth += (at(depth) - d).abs();
            }
            self.n += 1;
        }
        self.iou += if union == 0 {
            1.0
        } else {
            inter as f64 / union as f64
        };
        self.frames += 1;
    }
}

/// Run the command; returns the exit code.
pub fn run(rig: &dyn Rig, args: BenchTradeoffArgs) -> anyhow::Result<u8> {
    if let Some(path) = &args.plot {
        crate::plot::Format::of(path)?;
    }
    let config = rig.load_config(None)?;
    let pipeline_config = PipelineConfig::from_section(&config.pipeline, &config.layout)?;
    let sensors = bench_sensors(&config, &args)?;
    let mut rows = Vec::new();
    for (scale, resolution) in [(1usize, "full"), (2, "1/2"), (4, "1/4")] {
        let truths: Vec<Truth> = sensors
            .iter()
            .map(|s| truth_at(&s.map, scale, s.cam.mm_per_px))
            .collect();
        for model_index in 0..4 {
            for solver in [Some(Solver::Dst), Some(Solver::Dct), None] {
                let stages = SensorStages {
                    decode_scale: scale,
                    solver,
                    ..pipeline_config.sensors[0].clone()
                };
                let case = Case {
                    resolution,
                    model_index,
                    stages,
                };
                rows.push(measure(&sensors, &truths, &case, &args)?);
            }
        }
    }
    mark_pareto(&mut rows);
    if let Some(path) = &args.plot {
        plot(&rows, path)?;
        eprintln!("wrote {}", path.display());
    }
    if args.json {
        println!("{}", serde_json::to_string(&rows)?);
    } else {
        print_table(&rows);
    }
    Ok(0)
}

/// One simulated sensor of the bench: its camera, the press it sees, that press's frames,
/// its untouched frames and its four gradient models (LUT, dense MLP, contact-only MLP,
/// baked LUT).
struct BenchSensor {
    cam: SensorCamera,
    map: HeightMap,
    frames: Vec<Vec<u8>>,
    quiet: Vec<Vec<u8>>,
    models: [GradientModel; 4],
}

/// Calibrate every sensor of `config` (a LUT and an MLP each) and render its frames.
fn bench_sensors(
    config: &gelgrip_controller::config::AppConfig,
    args: &BenchTradeoffArgs,
) -> anyhow::Result<Vec<BenchSensor>> {
    let tmp = std::env::temp_dir().join(format!("gelgrip-bench-tradeoff-{}", std::process::id()));
    let opts = TrainOptions {
        epochs: args.epochs as usize,
        ..TrainOptions::default()
    };
    let hand = sensor_models::calibrate_hand(
        config,
        args.presses as usize,
        &tmp,
        MlpPlan::Individual(&opts),
    )?;
    let _ = std::fs::remove_dir_all(&tmp);
    let mut sensors = Vec::new();
    for s in hand {
        let mlp = s
            .mlp
            .ok_or_else(|| anyhow::anyhow!("no mlp for {}", s.id))?;
        let models = [
            GradientModel::lut(s.lut),
            GradientModel::mlp(mlp.clone(), MlpMode::Dense)?,
            GradientModel::mlp(mlp.clone(), MlpMode::ContactOnly)?,
            GradientModel::lut(bake(&mlp, BakeOptions::default())?),
        ];
        let map = s.cam.builtin_press(&s.sim);
        let frames = (0..FRAMES)
            .map(|k| s.cam.jpeg(&map, 4_000_000 + k))
            .collect::<Result<Vec<_>, _>>()?;
        let quiet = s.cam.untouched_frames(3_000_000, NOISE_FRAMES)?;
        sensors.push(BenchSensor {
            cam: s.cam,
            map,
            frames,
            quiet,
            models,
        });
    }
    Ok(sensors)
}

/// One row of the trade: a resolution's name, a model (by index) and the stages.
struct Case {
    resolution: &'static str,
    model_index: usize,
    stages: SensorStages,
}

/// Every sensor's pipeline for `case`, referenced on its untouched frames.
fn pipes(
    sensors: &[BenchSensor],
    truths: &[Truth],
    case: &Case,
) -> anyhow::Result<Vec<SensorPipeline>> {
    let mut pipes = Vec::new();
    for (s, truth) in sensors.iter().zip(truths) {
        let model = s.models[case.model_index].clone();
        let mut pipe = SensorPipeline::new(
            StageChoice {
                stages: case.stages.clone(),
                model,
            },
            s.cam.width,
            s.cam.height,
            s.cam.mm_per_px,
        );
        let (w, h) = pipe.size();
        if w * h != truth.depth_mm.len() {
            anyhow::bail!(
                "decode scale {} gives {w}x{h} px, not the truth's size",
                case.stages.decode_scale
            );
        }
        let quiet: Vec<&[u8]> = s.quiet.iter().map(Vec::as_slice).collect();
        pipe.calibrate(&quiet)?;
        pipes.push(pipe);
    }
    Ok(pipes)
}

/// Time `case` on every sensor's frames and score its last frames against the truth.
fn measure(
    sensors: &[BenchSensor],
    truths: &[Truth],
    case: &Case,
    args: &BenchTradeoffArgs,
) -> anyhow::Result<Row> {
    let (resolution, solver) = (case.resolution, case.stages.solver);
    let mut pipes = pipes(sensors, truths, case)?;
    let model = sensors[0].models[case.model_index].name();
    let needs = Needs {
        depth: solver.is_some(),
        gradients: true,
    };
    let mut out = vec![Ok(ContactSummary::default()); pipes.len()];
    let mut times = Vec::new();
    let mut score = Score::default();
    let mut mask = Vec::new();
    let total = WARMUP_SETS + (args.sets as usize).max(FRAMES as usize);
    for set in 0..total {
        let frames: Vec<&[u8]> = sensors
            .iter()
            .map(|s| s.frames[set % s.frames.len()].as_slice())
            .collect();
        let t = Instant::now();
        process_set(&mut pipes, &frames, needs, &mut out);
        let ms = t.elapsed().as_secs_f64() * 1e3;
        if let Some(e) = out.iter().find_map(|r| r.as_ref().err()) {
            anyhow::bail!("{resolution} {model}: {e}");
        }
        if set >= WARMUP_SETS {
            times.push(ms);
        }
        if set + FRAMES as usize >= total {
            for (pipe, truth) in pipes.iter().zip(truths) {
                score.add(pipe, truth, solver.is_some(), &mut mask);
            }
        }
    }
    times.sort_by(f64::total_cmp);
    let n = score.n.max(1) as f64;
    let row = Row {
        resolution,
        model,
        solver: solver.map_or("none", Solver::as_str),
        ms_per_set: times[times.len() / 2],
        gx_mae: Some(score.gx / n),
        gy_mae: Some(score.gy / n),
        depth_mae_mm: solver.map(|_| score.depth / n),
        area_iou: Some(score.iou / score.frames.max(1) as f64),
        pareto: false,
    };
    eprintln!(
        "  {:<5} {:<12} {:<5} {:>8.2} ms/set  gx {:.4} gy {:.4} depth {} iou {:.3}",
        row.resolution,
        row.model,
        row.solver,
        row.ms_per_set,
        score.gx / n,
        score.gy / n,
        row.depth_mae_mm
            .map_or("-".into(), |d| format!("{d:.4} mm")),
        score.iou / score.frames.max(1) as f64
    );
    Ok(row)
}

/// Mark the rows no other row beats on both time and depth error.
fn mark_pareto(rows: &mut [Row]) {
    let points: Vec<Option<(f64, f64)>> = rows
        .iter()
        .map(|r| r.depth_mae_mm.map(|d| (r.ms_per_set, d)))
        .collect();
    for (i, row) in rows.iter_mut().enumerate() {
        let Some((t, d)) = points[i] else { continue };
        row.pareto = !points.iter().enumerate().any(|(j, p)| {
            p.is_some_and(|(tj, dj)| j != i && tj <= t && dj <= d && (tj < t || dj < d))
        });
    }
}

fn plot(rows: &[Row], path: &Path) -> anyhow::Result<()> {
    let mut series = Vec::new();
    for model in ["lut", "mlp-dense", "mlp-contact", "baked-mlp"] {
        for solver in ["dst", "dct"] {
            let mut points: Vec<(f64, Option<f64>)> = rows
                .iter()
                .filter(|r| r.model == model && r.solver == solver)
                .map(|r| (r.ms_per_set, r.depth_mae_mm))
                .collect();
            points.sort_by(|a, b| a.0.total_cmp(&b.0));
            series.push(Series {
                name: format!("{model} + {solver} (full, 1/2, 1/4)"),
                points,
            });
        }
    }
    let mut front: Vec<(f64, Option<f64>)> = rows
        .iter()
        .filter(|r| r.pareto)
        .map(|r| (r.ms_per_set, r.depth_mae_mm))
        .collect();
    front.sort_by(|a, b| a.0.total_cmp(&b.0));
    series.push(Series {
        name: "Pareto front".into(),
        points: front,
    });
    let fig = Figure {
        title: "Speed/accuracy: 7 simulated sensors, one set".into(),
        x_label: "wall-clock time per set of 7, ms (2 cores)".into(),
        y_label: "depth MAE where touched, mm".into(),
        x_unit: "ms".into(),
        y_unit: "mm".into(),
        series,
        markers: true,
        ..Figure::default()
    };
    crate::plot::save(&fig, path)
}

fn print_table(rows: &[Row]) {
    println!(
        "bench tradeoff: 7 simulated sensors, median wall-clock ms per set; errors where the true depth is positive"
    );
    println!(
        "  {:<5} {:<12} {:<6} {:>10} {:>8} {:>8} {:>12} {:>8}  pareto",
        "res", "model", "solver", "ms/set", "gx_mae", "gy_mae", "depth_mae_mm", "area_iou"
    );
    let f = |v: Option<f64>, d: usize| v.map_or("-".to_string(), |v| format!("{v:.d$}"));
    for r in rows {
        println!(
            "  {:<5} {:<12} {:<6} {:>10.2} {:>8} {:>8} {:>12} {:>8}  {}",
            r.resolution,
            r.model,
            r.solver,
            r.ms_per_set,
            f(r.gx_mae, 4),
            f(r.gy_mae, 4),
            f(r.depth_mae_mm, 4),
            f(r.area_iou, 3),
            if r.pareto { "*" } else { "" }
        );
    }
}

/// `gelgrip bench tradeoff`.
#[derive(Debug, Args)]
pub struct BenchTradeoffArgs {
    /// Timed sets per configuration.
    #[arg(long, default_value = "30", value_parser = clap::value_parser!(u32).range(1..=10_000))]
    pub sets: u32,
    /// Presses per sensor for calibration.
    #[arg(long, default_value = "50", value_parser = clap::value_parser!(u32).range(4..=2000))]
    pub presses: u32,
    /// MLP training epochs (the source sensor's MLP; the others are transferred).
    #[arg(long, default_value_t = crate::args::DEFAULT_EPOCHS, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    pub epochs: u32,
    /// Write the Pareto plot here (.svg or .png).
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Print a JSON array of rows on stdout.
    #[arg(long)]
    pub json: bool,
}
