//! `gelgrip calibrate force --sensor ID [--presses N] [--json]`: fit the force proxy.
//!
//! The pipeline's force is `indentation volume × stiffness_n_per_mm3`. On the simulator the
//! sensor is pressed by balls of 6, 30 and 66 mm (a fingertip-sized probe to a tennis ball)
//! at depths spread over 0.1–1.0 mm at varied places; the broad balls also press across the
//! pad's edge, as objects in a grasp do. Each press's ground-truth normal force comes from
//! the simulator's gel law (the same one that loads the fingers), and the pipeline measures
//! the volume from the rendered JPEG. The stiffness minimises the relative error over the
//! presses above 0.1 N, `Σ(V/F) / Σ(V/F)²`, and goes into
//! `[pipeline] stiffness_n_per_mm3`. On hardware the same fit takes known weights pressed on
//! a sensor; that needs the hardware hub (`hub.transport` other than `sim`), which is
//! reported as such.

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;
use serde::Serialize;

use gelgrip_plugins::config::PipelineConfig;
use gelgrip_plugins::pipeline::Needs;
use gelgrip_sim::contact::pressure_n_per_mm2;
use gelgrip_sim::scene::HeightMap;

use crate::cli::ForceArgs;
use crate::{tactile, wiring};

/// Ball diameters of the presses, in turn, mm.
const BALLS_MM: [f64; 3] = [6.0, 30.0, 66.0];
/// Presses below this true force are left out of the worst-case error (their relative
/// error is dominated by the sensor's noise floor), N.
const WORST_CASE_FROM_N: f64 = 0.1;

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
}

/// Run the command; returns the exit code.
pub fn run(args: ForceArgs) -> anyhow::Result<u8> {
    let registry = wiring::registry();
    let config = wiring::load_config(args.config.as_deref(), &registry)?;
    if config.hub.transport != "sim" {
        anyhow::bail!(crate::cli::UsageError(format!(
            "{}: force calibration with known weights on hardware needs the hardware hub, \
             which this build does not drive yet; on the simulator use hub.transport = \"sim\"",
            config.file
        )));
    }
    let index = config.layout.index_of(&args.sensor).ok_or_else(|| {
        crate::cli::UsageError(format!(
            "no sensor `{}` in layout {}; sensors: {}",
            args.sensor,
            config.layout.name,
            config.layout.id_list()
        ))
    })?;
    let pipeline = PipelineConfig::from_section(&config.pipeline, &config.layout)?;
    let configured = pipeline.sensors[index].stiffness_n_per_mm3;
    let (mut pipe, cam) = tactile::sensor_pipeline(&config, &pipeline, index)?;
    let mut rng = Pcg64Mcg::seed_from_u64(0xF0_4CE);
    let n = args.presses as usize;
    let px_mm2 = cam.mm_per_px * cam.mm_per_px;
    let mut pairs = Vec::with_capacity(n);
    for i in 0..n {
        let depth = 0.1 + 0.9 * i as f64 / (n - 1) as f64;
        let ball = BALLS_MM[i % BALLS_MM.len()];
        // Small balls press inside the pad; broad ones anywhere, up to across its edge.
        let margin = if ball > 10.0 { 0.0 } else { 60.0 };
        let cx = rng.random_range(margin..cam.width as f64 - margin);
        let cy = rng.random_range(margin..cam.height as f64 - margin);
        let map =
            HeightMap::ball_press(cam.width, cam.height, cam.mm_per_px, (cx, cy), ball, depth);
        let truth: f64 = map
            .depth_mm
            .iter()
            .map(|d| pressure_n_per_mm2(f64::from(*d)) * px_mm2)
            .sum();
        let jpeg = cam.jpeg(&map, 9_000_000 + i as u64)?;
        let summary = pipe.process(&jpeg, Needs::DEPTH)?;
        let volume = summary.volume_mm3.unwrap_or(0.0);
        pairs.push((volume, truth));
        if !args.json && (i + 1) % 10 == 0 {
            eprintln!("  {}/{n} presses", i + 1);
        }
    }
    // Least squares on the relative error, so light and heavy presses count alike (a grasp
    // regulates at 1–2 N, far below the heaviest press): k = Σ(V/F) / Σ(V/F)² over the
    // presses above the noise floor.
    let (a, b) = pairs
        .iter()
        .filter(|(_, f)| *f >= WORST_CASE_FROM_N)
        .fold((0.0, 0.0), |(a, b), (v, f)| {
            (a + v / f, b + (v / f).powi(2))
        });
    if b <= 0.0 {
        anyhow::bail!(
            "the pipeline saw no indentation in {n} presses: check the sensor's calibration"
        );
    }
    let k = a / b;
    let mean_f = pairs.iter().map(|(_, f)| f).sum::<f64>() / n as f64;
    let ss_res: f64 = pairs.iter().map(|(v, f)| (f - k * v).powi(2)).sum();
    let ss_tot: f64 = pairs.iter().map(|(_, f)| (f - mean_f).powi(2)).sum();
    let report = ForceReport {
        sensor: args.sensor.clone(),
        presses: n,
        stiffness_n_per_mm3: k,
        configured_stiffness_n_per_mm3: configured,
        r2: if ss_tot > 0.0 {
            1.0 - ss_res / ss_tot
        } else {
            0.0
        },
        rmse_n: (ss_res / n as f64).sqrt(),
        worst_abs_err_pct: pairs
            .iter()
            .filter(|(_, f)| *f >= WORST_CASE_FROM_N)
            .map(|(v, f)| ((k * v - f) / f).abs() * 100.0)
            .fold(0.0, f64::max),
        mean_abs_err_pct: pairs
            .iter()
            .filter(|(_, f)| *f > 0.0)
            .map(|(v, f)| ((k * v - f) / f).abs() * 100.0)
            .sum::<f64>()
            / n as f64,
        force_range_n: pairs
            .iter()
            .fold([f64::MAX, 0.0], |[lo, hi], (_, f)| [lo.min(*f), hi.max(*f)]),
    };
    if args.json {
        println!("{}", serde_json::to_string(&report)?);
    } else {
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
            n,
            report.force_range_n[0],
            report.force_range_n[1],
            report.sensor,
            report.stiffness_n_per_mm3,
        );
    }
    Ok(0)
}
