//! Gradient models for a whole simulated hand, as the benches need them: from a press
//! dataset per sensor, a LUT per sensor and an MLP per sensor — either trained on each
//! sensor, or trained on the first and transferred to the others from one press each (the
//! paper's deployment; `bench calibration` scores both).

use std::path::Path;

use gelgrip_controller::config::AppConfig;
use gelgrip_plugins::calibrate;
use gelgrip_plugins::lut::{DEFAULT_BINS, Input, LutModel, LutSpec};
use gelgrip_plugins::mlp::MlpModel;
use gelgrip_plugins::mlp::train::TrainOptions;
use gelgrip_plugins::mlp::transfer::{Fit, transfer};
use gelgrip_sim::config::SimConfig;
use gelgrip_sim::pool::SensorCamera;

use gelgrip_plugins::calibrate::collect::{BallPresses, collect};
use gelgrip_plugins::dataset::PressDataset;
use gelgrip_sim::press_camera::sensor_camera;

use crate::progress;

/// Collect `presses` presses of `sim`'s ball on `cam` into `dir`, seeded by `sim.seed`.
pub fn sim_presses(
    cam: &SensorCamera,
    sim: &SimConfig,
    presses: usize,
    dir: &Path,
) -> anyhow::Result<PressDataset> {
    let balls = BallPresses {
        ball_diameter_mm: sim.ball_diameter_mm,
        presses,
        seed: sim.seed,
    };
    Ok(collect(cam, balls, dir, |_| {})?)
}

/// One sensor's camera, dataset and models.
pub struct SensorModels {
    /// Sensor id.
    pub id: String,
    /// Its simulated camera.
    pub cam: SensorCamera,
    /// The simulator settings it was built with.
    pub sim: SimConfig,
    /// Its own LUT (difference input).
    pub lut: LutModel,
    /// The hand's MLP (difference input), transferred to this sensor.
    pub mlp: Option<MlpModel>,
}

/// How the hand's MLPs are made.
#[derive(Debug, Clone, Copy)]
pub enum MlpPlan<'a> {
    /// No MLP.
    None,
    /// One per sensor, each trained on its own presses.
    Individual(&'a TrainOptions),
    /// Trained on the first sensor, transferred to the others with `Fit`.
    ZeroShot(&'a TrainOptions, Fit),
}

fn train(id: &str, dataset: &PressDataset, opts: &TrainOptions) -> anyhow::Result<MlpModel> {
    eprintln!("training the mlp on {id} ({} epochs)", opts.epochs);
    let bar = progress::epochs(opts.epochs as u64);
    let m = calibrate::train_mlp_on(
        &[dataset],
        Input::Diff,
        opts,
        progress::epoch_reporter(&bar),
    )?;
    bar.finish_and_clear();
    Ok(m)
}

/// Collect `presses` presses on every sensor of `config` into `dir`, train a LUT per sensor
/// and the MLPs `plan` asks for.
pub fn calibrate_hand(
    config: &AppConfig,
    presses: usize,
    dir: &Path,
    plan: MlpPlan<'_>,
) -> anyhow::Result<Vec<SensorModels>> {
    let mut out: Vec<SensorModels> = Vec::new();
    for (i, spec) in config.layout.sensors.iter().enumerate() {
        let id = spec.id.to_string();
        let (cam, sim) = sensor_camera(config, &id)?;
        eprintln!("calibrating {id}: {presses} presses, LUT training");
        let presses_sim = SimConfig {
            seed: sim.seed ^ (0x5EED_0000 + i as u64),
            ..sim.clone()
        };
        let dataset = sim_presses(&cam, &presses_sim, presses, &dir.join(&id))?;
        let lut = calibrate::train_lut(&dataset, LutSpec::means(Input::Diff, DEFAULT_BINS))?;
        let source = out.first().and_then(|s| s.mlp.as_ref());
        let model = match (plan, source) {
            (MlpPlan::None, _) => None,
            (MlpPlan::Individual(opts), _) | (MlpPlan::ZeroShot(opts, _), None) => {
                Some(train(&id, &dataset, opts)?)
            }
            (MlpPlan::ZeroShot(_, fit), Some(source)) => {
                let press = calibrate::press_pixels(&dataset, 0, Input::Diff)?;
                Some(transfer(source, &press, fit)?.0)
            }
        };
        out.push(SensorModels {
            id,
            cam,
            sim,
            lut,
            mlp: model,
        });
    }
    Ok(out)
}
