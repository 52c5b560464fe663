//! `gelgrip bench label [--config FILE] [--balls-mm LIST] [--presses N] [--seed S] [--json]`:
//! `calibrate label`'s contact detection against the simulator's truth, at scale.
//!
//! Each ball is pressed `--presses` times anywhere on f1.tip's pad, from a contact radius of
//! 0.3 of the ball's to 0.95 of it or 2 mm deep, whichever is shallower (the real-sensor
//! issue's range), rendered through the config's optics, noise and JPEG, and labelled
//! against a background of ten untouched frames with the dataset's own camera noise, as
//! `calibrate label` does. Per ball: how many were labelled, how many within 1 px and 5% of
//! the true centre and contact radius (the acceptance), the median and worst errors, and the
//! refusals by code. Then the sphere check ([`crate::label_sphere`]): a LUT trained on the
//! labelled presses as `calibrate train` does, and per ball how many held-out presses give
//! a fitted sphere radius within 10% of the ball's (every press held out once). The
//! default config is the realistic optics (the simulated Mini); the test command runs a few
//! of these presses (`tests/calibrate_label.rs`).

use std::collections::BTreeMap;
use std::path::PathBuf;

use anyhow::Context;
use clap::Args;
use rand::{Rng, SeedableRng};
use serde::Serialize;

use gelgrip_plugins::calibrate::collect::{decode_frame, mean_background};
use gelgrip_plugins::calibrate::label::{ContactCircle, Labeller, Rejection};
use gelgrip_plugins::dataset::DatasetInfo;
use gelgrip_plugins::image::RgbImage;
use gelgrip_sim::pool::SensorCamera;
use gelgrip_sim::press_camera::sensor_camera;

use crate::label_sphere::{self, Labelled, SHARE_BANDS, SphereCheck, by_share};
use crate::progress;
use crate::rig::Rig;

/// The sensor pressed.
const SENSOR: &str = "f1.tip";
/// The shallowest and deepest contact, as shares of the ball's radius.
const CONTACT_SHARE: std::ops::Range<f64> = 0.3..0.95;
/// The deepest press, mm.
const MAX_DEPTH_MM: f64 = 2.0;

/// `gelgrip bench label`.
#[derive(Debug, Args)]
pub struct BenchLabelArgs {
    /// The simulated gripper's config (default: configs/gelgripper-sim-realistic.toml).
    #[arg(long, default_value = "configs/gelgripper-sim-realistic.toml")]
    pub config: PathBuf,
    /// Ball diameters, mm, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "3,4.5,6")]
    pub balls_mm: Vec<f64>,
    /// Presses per ball.
    #[arg(long, default_value_t = 40)]
    pub presses: usize,
    /// Seed of the presses' places and depths.
    #[arg(long, default_value_t = 41)]
    pub seed: u64,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// One ball's row.
#[derive(Debug, Serialize)]
struct BallRow {
    ball_mm: f64,
    presses: usize,
    labelled: usize,
    within_1px_5pct: usize,
    centre_err_px_median: Option<f64>,
    centre_err_px_max: Option<f64>,
    radius_err_pct_median: Option<f64>,
    radius_err_pct_max: Option<f64>,
    refused: BTreeMap<&'static str, usize>,
    sphere: SphereCheck,
}

#[derive(Debug, Serialize)]
struct Report {
    config: String,
    sensor: &'static str,
    seed: u64,
    rows: Vec<BallRow>,
    presses: usize,
    within_1px_5pct: usize,
    within_share: f64,
    sphere_held_out: usize,
    sphere_within_10pct: usize,
    sphere_within_share: f64,
}

/// A press's true centre and contact radius, px.
type Truth = (f64, f64, f64);

/// One press: its truth and what the labeller made of it.
struct Pressed {
    truth: Truth,
    found: Result<ContactCircle, Rejection>,
}

/// Run `bench label`; the exit code.
pub fn run(rig: &dyn Rig, args: BenchLabelArgs) -> anyhow::Result<u8> {
    let config = rig.load_config(Some(&args.config))?;
    let (cam, _) = sensor_camera(&config, SENSOR).context("the sensor's camera")?;
    let background = mean_background(&cam).context("the background")?;
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(args.seed);
    let bar = progress::bar((args.balls_mm.len() * args.presses) as u64, "presses");
    let mut rows = Vec::new();
    for &ball_mm in &args.balls_mm {
        let (images, truths) = press_ball(&cam, ball_mm, args.presses, &mut rng, &bar)?;
        let refs: Vec<&RgbImage> = images.iter().collect();
        let ball_px = ball_mm / 2.0 / cam.mm_per_px;
        let labeller = Labeller::new(&background, ball_px)
            .with_dataset_noise(&refs)
            .with_dataset_rims(&refs);
        let pressed: Vec<Pressed> = images
            .iter()
            .zip(truths)
            .map(|(img, truth)| Pressed {
                truth,
                found: labeller.detect(img),
            })
            .collect();
        let labelled = labelled(&images, &pressed, ball_px);
        let info = DatasetInfo {
            ball_diameter_mm: ball_mm,
            mm_per_px: cam.mm_per_px,
        };
        let sphere = label_sphere::check(&std::env::temp_dir(), &background, &info, &labelled)?;
        rows.push(ball_row(ball_mm, &pressed, sphere));
    }
    bar.finish_and_clear();
    let presses: usize = rows.iter().map(|r| r.presses).sum();
    let within: usize = rows.iter().map(|r| r.within_1px_5pct).sum();
    let held_out: usize = rows.iter().map(|r| r.sphere.held_out).sum();
    let metric: usize = rows.iter().map(|r| r.sphere.within_10pct).sum();
    let report = Report {
        config: args.config.display().to_string(),
        sensor: SENSOR,
        seed: args.seed,
        rows,
        presses,
        within_1px_5pct: within,
        within_share: within as f64 / presses.max(1) as f64,
        sphere_held_out: held_out,
        sphere_within_10pct: metric,
        sphere_within_share: metric as f64 / held_out.max(1) as f64,
    };
    if args.json {
        println!("{}", serde_json::to_string(&report)?);
    } else {
        print_table(&report);
    }
    Ok(0)
}

/// The presses the labeller labelled, with its circles.
fn labelled<'a>(images: &'a [RgbImage], pressed: &[Pressed], ball_px: f64) -> Vec<Labelled<'a>> {
    images
        .iter()
        .zip(pressed)
        .filter_map(|(image, p)| {
            let c = p.found.as_ref().ok()?;
            Some(Labelled {
                image,
                circle: (c.center_x_px, c.center_y_px, c.contact_radius_px),
                true_contact_share: p.truth.2 / ball_px,
            })
        })
        .collect()
}

/// `n` presses of a ball of `ball_mm`: the decoded frames and each one's true centre and
/// contact radius, px.
fn press_ball(
    cam: &SensorCamera,
    ball_mm: f64,
    n: usize,
    rng: &mut impl Rng,
    bar: &indicatif::ProgressBar,
) -> anyhow::Result<(Vec<RgbImage>, Vec<Truth>)> {
    let r_mm = ball_mm / 2.0;
    let (mut images, mut truths) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for i in 0..n {
        let share: f64 = rng.random_range(CONTACT_SHARE);
        let depth = (r_mm - (r_mm * r_mm * (1.0 - share * share)).sqrt()).min(MAX_DEPTH_MM);
        let a_px = (r_mm * r_mm - (r_mm - depth).powi(2)).sqrt() / cam.mm_per_px;
        let margin = a_px + 4.0;
        let cx = rng.random_range(margin..cam.width as f64 - margin);
        let cy = rng.random_range(margin..cam.height as f64 - margin);
        let map = cam.ball_press_map((cx, cy), ball_mm, depth);
        let jpeg = cam.jpeg(&map, 2_000_000 + i as u64)?;
        images.push(decode_frame(cam, &jpeg)?);
        truths.push((cx, cy, a_px));
        progress::advance(bar, "presses");
    }
    Ok((images, truths))
}

fn ball_row(ball_mm: f64, pressed: &[Pressed], sphere: SphereCheck) -> BallRow {
    let (mut centre, mut radius) = (Vec::new(), Vec::new());
    let mut refused = BTreeMap::new();
    let mut within = 0;
    for p in pressed {
        match &p.found {
            Ok(c) => {
                let (cx, cy, a) = p.truth;
                let dc = (c.center_x_px - cx).hypot(c.center_y_px - cy);
                let dr = (c.contact_radius_px / a - 1.0).abs() * 100.0;
                within += usize::from(dc <= 1.0 && dr <= 5.0);
                centre.push(dc);
                radius.push(dr);
            }
            Err(e) => *refused.entry(e.code()).or_insert(0) += 1,
        }
    }
    BallRow {
        ball_mm,
        presses: pressed.len(),
        labelled: centre.len(),
        within_1px_5pct: within,
        centre_err_px_median: median(&mut centre),
        centre_err_px_max: centre.iter().copied().reduce(f64::max),
        radius_err_pct_median: median(&mut radius),
        radius_err_pct_max: radius.iter().copied().reduce(f64::max),
        refused,
        sphere,
    }
}

fn median(v: &mut [f64]) -> Option<f64> {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied()
}

fn print_table(r: &Report) {
    let f = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.2}"));
    println!("bench label: {} ({}), seed {}", r.config, r.sensor, r.seed);
    println!(
        "| ball mm | presses | labelled | within 1 px and 5% | centre err px (median, max) | radius err % (median, max) | refused |"
    );
    println!("|---|---|---|---|---|---|---|");
    for row in &r.rows {
        let refused: Vec<String> = row
            .refused
            .iter()
            .map(|(k, n)| format!("{k} {n}"))
            .collect();
        println!(
            "| {} | {} | {} | {} | {}, {} | {}, {} | {} |",
            row.ball_mm,
            row.presses,
            row.labelled,
            row.within_1px_5pct,
            f(row.centre_err_px_median),
            f(row.centre_err_px_max),
            f(row.radius_err_pct_median),
            f(row.radius_err_pct_max),
            if refused.is_empty() {
                "none".into()
            } else {
                refused.join(", ")
            }
        );
    }
    println!(
        "{} of {} within 1 px and 5% ({:.1}%)",
        r.within_1px_5pct,
        r.presses,
        r.within_share * 100.0
    );
    println!();
    println!("sphere check: a LUT trained on the labels, every labelled press held out once");
    println!("| ball mm | held out | sphere radius median mm | within 10% of the ball's |");
    println!("|---|---|---|---|");
    for row in &r.rows {
        let s = &row.sphere;
        println!(
            "| {} | {} | {} (ball {:.2}) | {} |",
            row.ball_mm,
            s.held_out,
            s.radius_mm_median
                .map_or("-".to_string(), |v| format!("{v:.3}")),
            s.ball_radius_mm,
            s.within_10pct
        );
    }
    println!(
        "{} of {} held-out presses within 10% of the ball's radius ({:.1}%)",
        r.sphere_within_10pct,
        r.sphere_held_out,
        r.sphere_within_share * 100.0
    );
    println!("\nby the true contact radius over the ball's, every ball");
    println!("| contact share | held out | within 10% | sphere radius error % (median) |");
    println!("|---|---|---|---|");
    let checks: Vec<&SphereCheck> = r.rows.iter().map(|row| &row.sphere).collect();
    for ((lo, hi), (n, within, median)) in SHARE_BANDS.iter().zip(by_share(&checks)) {
        let median = median.map_or("-".to_string(), |m| format!("{m:+.1}"));
        println!("| {lo:.2}–{hi:.2} | {n} | {within} | {median} |");
    }
}
