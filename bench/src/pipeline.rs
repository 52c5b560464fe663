//! `gelgrip bench pipeline`: the host's wall-clock cost of one synchronized set of N sensors
//! at 320×240, from JPEG bytes to contact, with the results checked against the simulator's
//! truth.
//!
//! Every sensor is pressed by a ball, 6 mm and 0.5 mm deep unless `--ball-mm` and
//! `--press-depth-mm` say otherwise (a broad press gives the large depth windows of a
//! grasp). Each sensor is calibrated first, as it
//! would be on hardware: 50 simulated presses, a LUT trained on them (none with
//! `--model-file`: every sensor uses that model), then a 20-frame no-contact capture for the
//! reference and the noise thresholds. The timed loop processes
//! the sensors of each set in parallel (`process_set`: rayon, one task per sensor) and
//! measures wall-clock time per set.

use crate::args::parse_within;
use clap::Args;
use std::path::PathBuf;
use std::time::Instant;

use serde::Serialize;

use gelgrip_controller::layout::HandLayout;
use gelgrip_plugins::config::{PipelineConfig, SensorStages};
use gelgrip_plugins::contact::ContactSummary;
use gelgrip_plugins::gradient::{GradientModel, MlpMode};
use gelgrip_plugins::mlp::bake::{BakeOptions, bake};
use gelgrip_plugins::mlp::train::TrainOptions;
use gelgrip_plugins::mlp::transfer::Fit;
use gelgrip_plugins::pipeline::{Needs, SensorPipeline, StageChoice, process_set};
use gelgrip_plugins::poisson::{PoissonPlan, Solver};
use gelgrip_sim::config::SimConfig;
use gelgrip_sim::pool::SensorCamera;
use gelgrip_sim::scene::HeightMap;

use crate::args::ModelKind;
use crate::sensor_models::{self, MlpPlan};
use gelgrip_sim::press_camera::sensor_camera;

use crate::rig::Rig;

/// Presses collected to calibrate each sensor.
const CALIBRATION_PRESSES: usize = 50;
/// No-contact frames for the reference and noise thresholds.
const NOISE_FRAMES: u64 = 20;
/// Sets processed before timing.
const WARMUP_SETS: usize = 10;

#[derive(Debug, Serialize)]
struct SensorRow {
    sensor: String,
    area_mm2: f64,
    true_area_mm2: f64,
    area_err_pct: f64,
    max_depth_mm: Option<f64>,
    true_max_depth_mm: f64,
    depth_err_mm: Option<f64>,
    volume_mm3: Option<f64>,
    true_volume_mm3: f64,
    force_n: Option<f64>,
}

#[derive(Debug, Serialize)]
struct Report {
    sensors: usize,
    model: &'static str,
    solver: &'static str,
    decode_scale: usize,
    threads: usize,
    sets: usize,
    ms_per_set: f64,
    ms_per_set_p99: f64,
    full_frame_dst_ms: f64,
    full_frame_dct_ms: f64,
    per_sensor: Vec<SensorRow>,
    /// `--markers`: what slip detection costs per frame.
    #[serde(skip_serializing_if = "Option::is_none")]
    markers: Option<crate::pipeline_markers::MarkerCost>,
}

fn quantile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return 0.0;
    }
    sorted[((sorted.len() - 1) as f64 * q).round() as usize]
}

fn full_frame_ms(solver: Solver) -> f64 {
    let (h, w) = (240, 320);
    let mut plan = PoissonPlan::<f32>::new(solver, h, w);
    let gx: Vec<f32> = (0..h * w)
        .map(|k| ((k % 97) as f32 - 48.0) * 1e-3)
        .collect();
    let gy: Vec<f32> = (0..h * w)
        .map(|k| ((k % 89) as f32 - 44.0) * 1e-3)
        .collect();
    let mut z = vec![0.0f32; h * w];
    let mut times: Vec<f64> = (0..30)
        .map(|_| {
            let t = Instant::now();
            plan.solve(&gx, &gy, &mut z);
            t.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    times.sort_by(f64::total_cmp);
    quantile(&times, 0.5)
}

fn truth(map: &HeightMap, mm_per_px: f64) -> (f64, f64, f64) {
    let px = mm_per_px * mm_per_px;
    let inside = map.depth_mm.iter().filter(|d| **d > 0.0);
    let area = inside.clone().count() as f64 * px;
    let volume = inside.map(|d| f64::from(*d)).sum::<f64>() * px;
    (area, f64::from(map.max_depth_mm()), volume)
}

/// Run the command; returns the exit code.
pub fn run(rig: &dyn Rig, args: BenchPipelineArgs) -> anyhow::Result<u8> {
    let report = measure(rig, &args)?;
    if args.json {
        println!("{}", serde_json::to_string(&report)?);
    } else {
        print_table(&report);
    }
    Ok(0)
}

/// The p99 ms per set of `args`' bench, in this process (the grasp bench's budget).
pub fn ms_per_set_p99(rig: &dyn Rig, args: &BenchPipelineArgs) -> anyhow::Result<f64> {
    Ok(measure(rig, args)?.ms_per_set_p99)
}

/// Time the pipelines as `args` ask.
fn measure(rig: &dyn Rig, args: &BenchPipelineArgs) -> anyhow::Result<Report> {
    let mut config = rig.load_config(None)?;
    config.layout = HandLayout::generated(usize::from(args.sensors))?;
    config
        .hub
        .section
        .table
        .insert("ball_diameter_mm".into(), toml::Value::Float(args.ball_mm));
    config.hub.section.table.insert(
        "press_depth_mm".into(),
        toml::Value::Float(args.press_depth_mm),
    );
    let solver = Solver::parse(&args.solver).unwrap_or(Solver::Dst);
    // The embedded default [pipeline] section, with the bench's solver and scale on top.
    let pipeline_config = PipelineConfig::from_section(&config.pipeline, &config.layout)?;
    let tmp = std::env::temp_dir().join(format!("gelgrip-bench-pipeline-{}", std::process::id()));
    let sensors = hand_models(&config, args, &tmp)?;
    let mut model_name = "lut";
    let mut markers = None;
    let mut pipes = Vec::new();
    let mut frames = Vec::new();
    let mut truths = Vec::new();
    for (id, cam, sim, model) in sensors {
        model_name = model.name();
        let stages = SensorStages {
            decode_scale: args.scale(),
            solver: Some(solver),
            ..pipeline_config.sensors[0].clone()
        };
        if args.markers && markers.is_none() {
            markers = Some(marker_cost(args, &config.layout, &sim, (&stages, &model))?);
        }
        let choice = StageChoice { stages, model };
        let mut pipe = SensorPipeline::new(choice, cam.width, cam.height, cam.mm_per_px);
        let quiet = cam.untouched_frames(3_000_000, NOISE_FRAMES)?;
        let quiet: Vec<&[u8]> = quiet.iter().map(Vec::as_slice).collect();
        pipe.calibrate(&quiet)?;
        let map = cam.builtin_press(&sim);
        truths.push((id, truth(&map, cam.mm_per_px)));
        frames.push(
            (0..8)
                .map(|k| cam.jpeg(&map, 4_000_000 + k))
                .collect::<Result<Vec<_>, _>>()?,
        );
        pipes.push(pipe);
    }
    let _ = std::fs::remove_dir_all(&tmp);
    let needs = Needs::DEPTH;
    let mut results = vec![Ok(ContactSummary::default()); pipes.len()];
    let sets = args.sets as usize;
    let mut times = Vec::with_capacity(sets);
    for set in 0..WARMUP_SETS + sets {
        let set_frames: Vec<&[u8]> = frames.iter().map(|f| f[set % f.len()].as_slice()).collect();
        let start = Instant::now();
        process_set(&mut pipes, &set_frames, needs, &mut results);
        if set >= WARMUP_SETS {
            times.push(start.elapsed().as_secs_f64() * 1e3);
        }
    }
    let results = results.into_iter().collect::<Result<Vec<_>, _>>()?;
    times.sort_by(f64::total_cmp);
    let per_sensor = truths
        .into_iter()
        .zip(&results)
        .map(|((sensor, (area, depth, volume)), r)| SensorRow {
            sensor,
            area_mm2: r.area_mm2,
            true_area_mm2: area,
            area_err_pct: (r.area_mm2 - area) / area * 100.0,
            max_depth_mm: r.max_depth_mm,
            true_max_depth_mm: depth,
            depth_err_mm: r.max_depth_mm.map(|d| d - depth),
            volume_mm3: r.volume_mm3,
            true_volume_mm3: volume,
            force_n: r.force_n,
        })
        .collect();
    let report = Report {
        sensors: pipes.len(),
        model: model_name,
        solver: solver.as_str(),
        decode_scale: args.scale(),
        threads: rayon::current_num_threads(),
        sets,
        ms_per_set: quantile(&times, 0.5),
        ms_per_set_p99: quantile(&times, 0.99),
        full_frame_dst_ms: full_frame_ms(Solver::Dst),
        full_frame_dct_ms: full_frame_ms(Solver::Dct),
        per_sensor,
        markers,
    };
    Ok(report)
}

/// `--markers`: slip detection's cost on the first sensor of `layout`, the bench's press.
fn marker_cost(
    args: &BenchPipelineArgs,
    layout: &HandLayout,
    sim: &SimConfig,
    (stages, model): (&SensorStages, &GradientModel),
) -> anyhow::Result<crate::pipeline_markers::MarkerCost> {
    let press = crate::pipeline_markers::Press {
        ball_mm: args.ball_mm,
        depth_mm: args.press_depth_mm,
    };
    crate::pipeline_markers::measure(layout, sim, press, stages, model)
}

/// Each sensor of `config`, with its simulated camera and settings and the gradient model
/// `args` ask for: `--model-file` for every sensor, else a calibration of the hand on
/// simulated presses in `tmp` (an MLP transferred zero-shot, or baked into a LUT).
fn hand_models(
    config: &gelgrip_controller::config::AppConfig,
    args: &BenchPipelineArgs,
    tmp: &std::path::Path,
) -> anyhow::Result<Vec<(String, SensorCamera, SimConfig, GradientModel)>> {
    let mlp_mode = args.mlp_mode.as_str();
    let mode = MlpMode::parse(mlp_mode).unwrap_or(MlpMode::ContactOnly);
    let fixed = match &args.model_file {
        Some(path) => Some(GradientModel::load(path, mode)?),
        None => None,
    };
    let opts = TrainOptions {
        epochs: args.epochs as usize,
        ..TrainOptions::default()
    };
    let plan = if args.model == ModelKind::Mlp {
        MlpPlan::ZeroShot(&opts, Fit::Offset)
    } else {
        MlpPlan::None
    };
    // With a model file every sensor uses it: nothing to collect or train.
    Ok(match &fixed {
        Some(m) => config
            .layout
            .sensors
            .iter()
            .map(|spec| {
                let id = spec.id.to_string();
                let (cam, sim) = sensor_camera(config, &id)?;
                Ok((id, cam, sim, m.clone()))
            })
            .collect::<anyhow::Result<_>>()?,
        None => sensor_models::calibrate_hand(config, CALIBRATION_PRESSES, tmp, plan)?
            .into_iter()
            .map(|sensor| {
                let model = match sensor.mlp {
                    Some(m) if mlp_mode == "baked" => {
                        GradientModel::lut(bake(&m, BakeOptions::default())?)
                    }
                    Some(m) => GradientModel::mlp(m, mode)?,
                    None => GradientModel::lut(sensor.lut),
                };
                Ok((sensor.id, sensor.cam, sensor.sim, model))
            })
            .collect::<anyhow::Result<_>>()?,
    })
}

fn print_table(r: &Report) {
    println!(
        "bench pipeline: {} sensors, {} + {} (bounding-box solve), decode scale {}, {} threads, {} sets (wall clock)",
        r.sensors, r.model, r.solver, r.decode_scale, r.threads, r.sets
    );
    println!(
        "  ms per set: median {:.3}, p99 {:.3}",
        r.ms_per_set, r.ms_per_set_p99
    );
    println!(
        "  full-frame 240x320 f32 solve: DST-I {:.3} ms, DCT-II {:.3} ms",
        r.full_frame_dst_ms, r.full_frame_dct_ms
    );
    println!(
        "  sensor  area mm2 (true)     err %   max depth mm (true)   volume mm3 (true)   force N"
    );
    let f = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.3}"));
    for s in &r.per_sensor {
        println!(
            "  {:<6} {:>8.2} ({:>6.2}) {:>8.1}   {:>7} ({:.3})        {:>7} ({:.3})     {}",
            s.sensor,
            s.area_mm2,
            s.true_area_mm2,
            s.area_err_pct,
            f(s.max_depth_mm),
            s.true_max_depth_mm,
            f(s.volume_mm3),
            s.true_volume_mm3,
            f(s.force_n)
        );
    }
    if let Some(m) = &r.markers {
        println!(
            "  marker gel (one thread, sensor 0): frame {:.3} ms plain, {:.3} ms with {} dots ({} under the contact): {:.3} ms per frame more",
            m.frame_ms_plain,
            m.frame_ms_markers,
            m.marker_dots,
            m.dots_inside,
            m.marker_gel_ms_per_frame
        );
        println!(
            "    slip detection {:.3} ms per frame (dots found and followed {:.3} ms, shear fitted {:.3} ms); dots filled for the depth {:.3} ms",
            m.slip_detection_ms_per_frame, m.dot_tracking_ms, m.shear_fit_ms, m.dot_fill_ms
        );
    }
}

/// `gelgrip bench pipeline`.
#[derive(Debug, Args)]
pub struct BenchPipelineArgs {
    /// Sensors per set.
    #[arg(long, default_value = "7", value_parser = clap::value_parser!(u8).range(1..=32))]
    pub sensors: u8,
    /// Gradient model kind. `mlp` trains an MLP on the first sensor and transfers it to the
    /// others from one press each (the paper's deployment).
    #[arg(long, value_enum, default_value = "lut")]
    pub model: ModelKind,
    /// How the MLP runs: `contact` (pixels above the noise), `dense`, or `baked` (into a
    /// tiled LUT).
    #[arg(long, default_value = "contact", value_parser = ["contact", "dense", "baked"])]
    pub mlp_mode: String,
    /// MLP training epochs.
    #[arg(long, default_value_t = crate::args::DEFAULT_EPOCHS, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    pub epochs: u32,
    /// Use this trained model for every sensor instead of calibrating each one.
    #[arg(long)]
    pub model_file: Option<PathBuf>,
    /// Depth solver.
    #[arg(long, default_value = "dct", value_parser = ["dst", "dct"])]
    pub solver: String,
    /// JPEG decode scale (1, 2 or 4).
    #[arg(long, default_value = "1", value_parser = ["1", "2", "4"])]
    pub scale_arg: String,
    /// Timed sets (the median needs at least 200).
    #[arg(long, default_value = "200", value_parser = clap::value_parser!(u32).range(1..=100_000))]
    pub sets: u32,
    /// Diameter of the ball pressing every sensor, mm (6: a fingertip probe; 30 with
    /// `--press-depth-mm 1`: a broad contact such as a grasped object makes).
    #[arg(long, default_value_t = 6.0, value_parser = parse_ball_mm)]
    pub ball_mm: f64,
    /// Depth of the press, mm.
    #[arg(long, default_value_t = 0.5, value_parser = parse_press_depth_mm)]
    pub press_depth_mm: f64,
    /// Also time slip detection: the first sensor's press on a marker gel under a
    /// tangential load, frame by frame, against the plain gel (the `markers` object).
    #[arg(long)]
    pub markers: bool,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

fn parse_ball_mm(s: &str) -> Result<f64, String> {
    parse_within(s, "a diameter", "mm", 0.5..=50.0)
}

fn parse_press_depth_mm(s: &str) -> Result<f64, String> {
    parse_within(s, "a depth", "mm", 0.0..=3.0)
}

impl BenchPipelineArgs {
    /// The decode scale as a number.
    pub fn scale(&self) -> usize {
        self.scale_arg.parse().unwrap_or(1)
    }
}
