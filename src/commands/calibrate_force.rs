//! `gelgrip calibrate force --sensor ID [--presses N] [--weights-g G,…] [--frames N] [--json]`:
//! fit the force proxy.
//!
//! The pipeline's force is `indentation volume × stiffness_n_per_mm3`. On the simulator the
//! sensor is pressed in turn by balls of 6, 30 and 66 mm (a fingertip-sized probe to a
//! tennis ball) and by cylinders of 20 and 40 mm lying across the pad at random angles (a
//! tool handle, a bottle), at depths spread over 0.1–1.0 mm at varied places; the broad
//! balls and the cylinders also press across the pad's edge, as objects in a grasp do. The
//! report gives the fit's error by indenter, since the proxy's accuracy depends on the
//! contact's shape (docs/control.md). Each press's ground-truth normal force comes from
//! the simulator's gel law (the same one that loads the fingers), and the pipeline measures
//! the volume from the rendered JPEG. The stiffness minimises the relative error over the
//! presses above 0.1 N, `Σ(V/F) / Σ(V/F)²`, and goes into
//! `[pipeline] stiffness_n_per_mm3`. On a hardware hub (`hub.transport` other than `sim`)
//! the same fit takes known weights placed on the sensor in turn
//! ([`crate::commands::calibrate_force_hw`]).

use clap::Args;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;
use serde::Serialize;
use std::path::PathBuf;

use gelgrip_plugins::config::PipelineConfig;
use gelgrip_plugins::pipeline::Needs;
use gelgrip_sim::contact::pressure_n_per_mm2;
use gelgrip_sim::scene::HeightMap;

use gelgrip_controller::config::AppConfig;

use crate::commands::calibrate_force_hw::{KNOWN_WEIGHTS, WeightReading, weigh};
use gelgrip::{tactile, wiring};

/// What presses the pad, in turn.
#[derive(Debug, Clone, Copy)]
enum Indenter {
    /// A ball of this diameter, mm.
    Ball(f64),
    /// A cylinder of this diameter, mm, lying across the pad at a random angle.
    Cylinder(f64),
}

impl Indenter {
    /// `ball 6 mm`, `cylinder 20 mm`.
    fn name(self) -> String {
        match self {
            Indenter::Ball(mm) => format!("ball {mm} mm"),
            Indenter::Cylinder(mm) => format!("cylinder {mm} mm"),
        }
    }
}

/// The presses' indenters, in turn: balls from a fingertip-sized probe to a tennis ball, and
/// cylinders from a tool handle to a bottle (a grasp holds both kinds; the pipeline reads a
/// long, shallow cylinder's volume lower than a ball's, docs/control.md).
const INDENTERS: [Indenter; 5] = [
    Indenter::Ball(6.0),
    Indenter::Ball(30.0),
    Indenter::Ball(66.0),
    Indenter::Cylinder(20.0),
    Indenter::Cylinder(40.0),
];
/// Presses below this true force are left out of the worst-case error (their relative
/// error is dominated by the sensor's noise floor), N.
pub const WORST_CASE_FROM_N: f64 = 0.1;

#[derive(Debug, Serialize)]
struct ForceReport {
    sensor: String,
    presses: usize,
    stiffness_n_per_mm3: f64,
    configured_stiffness_n_per_mm3: f64,
    r2: f64,
    rmse_n: f64,
    mean_abs_err_pct: f64,
    /// Largest |error| of a press above 0.1 N, %.
    worst_abs_err_pct: f64,
    force_range_n: [f64; 2],
    /// The fit's error by indenter: how the proxy's accuracy depends on the contact's shape.
    per_indenter: Vec<IndenterError>,
    /// On hardware, each known weight's reading.
    #[serde(skip_serializing_if = "Option::is_none")]
    per_weight: Option<Vec<WeightReading>>,
}

/// The fitted proxy's error on one indenter's presses above 0.1 N.
#[derive(Debug, Serialize)]
struct IndenterError {
    indenter: String,
    presses: usize,
    /// Mean signed error, % (negative: the proxy reads this shape low).
    mean_err_pct: f64,
    worst_abs_err_pct: f64,
    /// Mean signed error of the light presses (0.1 N to [`LIGHT_BELOW_N`], the force a pad
    /// takes in a gentle grasp), %; `None` without any.
    light_mean_err_pct: Option<f64>,
}

/// Presses below this true force are "light": a gentle grasp's force per pad, N.
const LIGHT_BELOW_N: f64 = 1.0;

fn mean(v: &[f64]) -> Option<f64> {
    (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
}

/// A press or weighing: what pressed (its group in the report), the volume read and the
/// true force.
pub struct Pair {
    /// The indenter, or "known weights".
    pub group: String,
    /// Indentation volume the pipeline read, mm³.
    pub volume_mm3: f64,
    /// The true normal force, N.
    pub force_n: f64,
}

impl Pair {
    /// The proxy's error under stiffness `k` (N/mm³), % of the true force.
    pub fn err_pct(&self, k: f64) -> f64 {
        (k * self.volume_mm3 - self.force_n) / self.force_n * 100.0
    }
}

/// [`IndenterError`] of each group of `pairs`, in the order of `groups`, for stiffness `k`.
fn per_group(pairs: &[Pair], groups: &[String], k: f64) -> Vec<IndenterError> {
    groups
        .iter()
        .map(|group| {
            let errors: Vec<(f64, f64)> = pairs
                .iter()
                .filter(|p| p.group == *group && p.force_n >= WORST_CASE_FROM_N)
                .map(|p| (p.force_n, p.err_pct(k)))
                .collect();
            let all: Vec<f64> = errors.iter().map(|(_, e)| *e).collect();
            let light: Vec<f64> = errors
                .iter()
                .filter(|(f, _)| *f < LIGHT_BELOW_N)
                .map(|(_, e)| *e)
                .collect();
            IndenterError {
                indenter: group.clone(),
                presses: all.len(),
                mean_err_pct: mean(&all).unwrap_or(0.0),
                worst_abs_err_pct: all.iter().map(|e| e.abs()).fold(0.0, f64::max),
                light_mean_err_pct: mean(&light),
            }
        })
        .collect()
}

/// Run the command; returns the exit code.
pub async fn run(args: ForceArgs) -> anyhow::Result<u8> {
    let registry = wiring::registry();
    let config = wiring::load_config(args.config.as_deref(), &registry)?;
    let index = config.layout.index_of(&args.sensor).ok_or_else(|| {
        gelgrip::UsageError(format!(
            "no sensor `{}` in layout {}; sensors: {}",
            args.sensor,
            config.layout.name,
            config.layout.id_list()
        ))
    })?;
    let pipeline = PipelineConfig::from_section(&config.pipeline, &config.layout)?;
    let configured = pipeline.sensors[index].stiffness_n_per_mm3;
    let report = if config.hub.transport == "sim" {
        let pairs = simulated_presses(&args, &config, &pipeline, index)?;
        let groups: Vec<String> = INDENTERS.iter().map(|i| i.name()).collect();
        fit(&args.sensor, configured, &pairs, &groups)?
    } else {
        let readings = weigh(&args, &config, &pipeline, index).await?;
        let pairs: Vec<Pair> = readings.iter().map(WeightReading::pair).collect();
        let mut report = fit(&args.sensor, configured, &pairs, &[KNOWN_WEIGHTS.into()])?;
        let k = report.stiffness_n_per_mm3;
        report.per_weight = Some(readings.into_iter().map(|r| r.with_fit(k)).collect());
        report
    };
    print(&report, args.json)?;
    Ok(0)
}

/// The simulator's presses of every indenter in turn: (indenter, volume read, true force).
fn simulated_presses(
    args: &ForceArgs,
    config: &AppConfig,
    pipeline: &PipelineConfig,
    index: usize,
) -> anyhow::Result<Vec<Pair>> {
    let (mut pipe, cam) = tactile::sensor_pipeline(config, pipeline, index)?;
    let mut rng = Pcg64Mcg::seed_from_u64(0xF0_4CE);
    let n = args.presses as usize;
    let px_mm2 = cam.mm_per_px * cam.mm_per_px;
    let mut pairs = Vec::with_capacity(n);
    for i in 0..n {
        let depth = 0.1 + 0.9 * i as f64 / (n - 1) as f64;
        let indenter = INDENTERS[i % INDENTERS.len()];
        // Small balls press inside the pad; broad ones and cylinders anywhere, up to across
        // its edge.
        let margin = match indenter {
            Indenter::Ball(mm) if mm < 10.0 => 60.0,
            _ => 0.0,
        };
        let cx = rng.random_range(margin..cam.width as f64 - margin);
        let cy = rng.random_range(margin..cam.height as f64 - margin);
        let size = (cam.width, cam.height);
        let map = match indenter {
            Indenter::Ball(mm) => {
                HeightMap::ball_press(size.0, size.1, cam.mm_per_px, (cx, cy), mm, depth)
            }
            Indenter::Cylinder(mm) => {
                let axis_deg = rng.random_range(0.0..180.0);
                HeightMap::cylinder_press(size, cam.mm_per_px, (cx, cy), axis_deg, mm, depth)
            }
        };
        let truth: f64 = map
            .depth_mm
            .iter()
            .map(|d| pressure_n_per_mm2(f64::from(*d)) * px_mm2)
            .sum();
        let jpeg = cam.jpeg(&map, 9_000_000 + i as u64)?;
        let summary = pipe.process(&jpeg, Needs::DEPTH)?;
        pairs.push(Pair {
            group: indenter.name(),
            volume_mm3: summary.volume_mm3.unwrap_or(0.0),
            force_n: truth,
        });
        if !args.json && (i + 1) % 10 == 0 {
            eprintln!("  {}/{n} presses", i + 1);
        }
    }
    Ok(pairs)
}

/// The stiffness fitted to `pairs` and its errors, by group in the order of `groups`.
fn fit(
    sensor: &str,
    configured: f64,
    pairs: &[Pair],
    groups: &[String],
) -> anyhow::Result<ForceReport> {
    let n = pairs.len();
    // Least squares on the relative error, so light and heavy presses count alike (a grasp
    // regulates at 1–2 N, far below the heaviest press): k = Σ(V/F) / Σ(V/F)² over the
    // presses above the noise floor.
    let above = || pairs.iter().filter(|p| p.force_n >= WORST_CASE_FROM_N);
    let (a, b) = above().fold((0.0, 0.0), |(a, b), p| {
        let r = p.volume_mm3 / p.force_n;
        (a + r, b + r * r)
    });
    if b <= 0.0 || !(a / b).is_finite() {
        anyhow::bail!(
            "the pipeline saw no indentation in {n} presses of {WORST_CASE_FROM_N} N or more: \
             check the sensor's calibration"
        );
    }
    let k = a / b;
    let mean_f = pairs.iter().map(|p| p.force_n).sum::<f64>() / n as f64;
    let ss_res: f64 = pairs
        .iter()
        .map(|p| (p.force_n - k * p.volume_mm3).powi(2))
        .sum();
    let ss_tot: f64 = pairs.iter().map(|p| (p.force_n - mean_f).powi(2)).sum();
    Ok(ForceReport {
        sensor: sensor.to_string(),
        presses: n,
        stiffness_n_per_mm3: k,
        configured_stiffness_n_per_mm3: configured,
        r2: if ss_tot > 0.0 {
            1.0 - ss_res / ss_tot
        } else {
            0.0
        },
        rmse_n: (ss_res / n as f64).sqrt(),
        worst_abs_err_pct: above().map(|p| p.err_pct(k).abs()).fold(0.0, f64::max),
        mean_abs_err_pct: pairs
            .iter()
            .filter(|p| p.force_n > 0.0)
            .map(|p| p.err_pct(k).abs())
            .sum::<f64>()
            / n as f64,
        force_range_n: pairs.iter().fold([f64::MAX, 0.0], |[lo, hi], p| {
            [lo.min(p.force_n), hi.max(p.force_n)]
        }),
        per_indenter: per_group(pairs, groups, k),
        per_weight: None,
    })
}

/// Print `report`: one JSON object, or the text summary.
fn print(report: &ForceReport, json: bool) -> anyhow::Result<()> {
    if json {
        println!("{}", serde_json::to_string(report)?);
        return Ok(());
    }
    println!(
        "sensor {}: stiffness_n_per_mm3 = {:.4} (configured {:.4}); R² {:.4}, RMSE {:.3} N, \
         mean |error| {:.1}% (worst {:.1}% above 0.1 N) over {} presses of {:.2}–{:.2} N\n\
         put it in the config: [[pipeline.sensors]] id = \"{}\" stiffness_n_per_mm3 = {:.4}",
        report.sensor,
        report.stiffness_n_per_mm3,
        report.configured_stiffness_n_per_mm3,
        report.r2,
        report.rmse_n,
        report.mean_abs_err_pct,
        report.worst_abs_err_pct,
        report.presses,
        report.force_range_n[0],
        report.force_range_n[1],
        report.sensor,
        report.stiffness_n_per_mm3,
    );
    if let Some(weights) = &report.per_weight {
        println!("by weight:");
        for w in weights {
            let err = w.err_pct.map_or("- (under 0.1 N, not fitted)".into(), |e| {
                format!("{e:+.1}%")
            });
            println!(
                "  {:7.1} g {:6.3} N  volume {:7.3} ± {:.3} mm³ ({} of {} frames in contact)  \
                 error {err}",
                w.weight_g, w.force_n, w.volume_mm3, w.volume_sd_mm3, w.contact_frames, w.frames,
            );
        }
        return Ok(());
    }
    println!("error by indenter (presses above 0.1 N; light: below 1 N, a grasp's pad):");
    for e in &report.per_indenter {
        let light = e
            .light_mean_err_pct
            .map_or("-".to_string(), |v| format!("{v:+.1}%"));
        println!(
            "  {:16} {:3} presses  mean {:+6.1}%  worst |error| {:5.1}%  light mean {light}",
            e.indenter, e.presses, e.mean_err_pct, e.worst_abs_err_pct
        );
    }
    Ok(())
}

/// `gelgrip calibrate force`.
#[derive(Debug, Args)]
pub struct ForceArgs {
    /// Sensor id (e.g. f1.tip).
    #[arg(long)]
    pub sensor: String,
    /// Simulator: presses (6, 30 and 66 mm balls and 20 and 40 mm cylinders in turn) at
    /// depths spread over 0.1–1.0 mm.
    #[arg(long, default_value_t = 30, value_parser = clap::value_parser!(u32).range(3..=2000))]
    pub presses: u32,
    /// Hardware hub: the known weights to place on the sensor in turn, g (each prompted
    /// on stderr and confirmed with Enter on stdin).
    #[arg(long, value_delimiter = ',', default_value = "20,50,100,200", value_parser = parse_weight_g)]
    pub weights_g: Vec<f64>,
    /// Hardware hub: frames read per weight (and for the untouched reference).
    #[arg(long, default_value_t = 12, value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub frames: u32,
    /// Configuration (default: the embedded simulated gripper).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Print one JSON object on stdout.
    #[arg(long)]
    pub json: bool,
}

fn parse_weight_g(s: &str) -> Result<f64, String> {
    let g: f64 = s
        .trim()
        .parse()
        .map_err(|_| format!("`{s}` is not a weight in g"))?;
    if g.is_finite() && g > 0.0 && g <= 10_000.0 {
        Ok(g)
    } else {
        Err(format!(
            "a weight of {s} g: expected more than 0 and at most 10000 g"
        ))
    }
}
