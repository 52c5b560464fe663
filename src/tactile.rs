//! The run's sensing built from a config: one `SensorPipeline` per sensor, from the
//! `[pipeline]` section, with each sensor's gradient model either from its configured
//! `model` file or, on the simulator, calibrated from simulated presses of a 6 mm and a
//! 25 mm ball on that very sensor (as `calibrate collect` + `calibrate train` would) and
//! cached on disk, keyed by the recipe's version, the seed, the sensor (its id and its
//! position in the layout, which draws its unit variation), resolution, pixel size, JPEG
//! quality and camera noise, so later runs start at once. The pipelines run behind the
//! runtime's sensing port as [`gelgrip_plugins::sensing::Tactile`].
//!
//! On a hardware hub (`hub.transport` other than `sim`) every sensor needs a model file,
//! and the references come from the first live sets, untouched ([`open`]).

use std::path::PathBuf;

use crate::error::{Context, Error};

use gelgrip_controller::config::AppConfig;
use gelgrip_plugins::calibrate;
use gelgrip_plugins::config::PipelineConfig;
use gelgrip_plugins::dataset::PressDataset;
use gelgrip_plugins::gradient::{GradientModel, MlpMode};
use gelgrip_plugins::lut::Input;
use gelgrip_plugins::lut::{LutModel, LutSpec};
use gelgrip_plugins::pipeline::{SensorPipeline, StageChoice};
use gelgrip_plugins::sensing::{REFERENCE_FRAMES, Tactile};

use gelgrip_sim::config::SimConfig;
use gelgrip_sim::pool::SensorCamera;

use gelgrip_plugins::calibrate::collect::{BallPresses, collect};
use gelgrip_sim::press_camera::sensor_camera;

/// Simulated presses per sensor for an automatic calibration, shared between the balls.
const CALIBRATION_PRESSES: usize = 50;
/// Ball diameters of the automatic calibration, mm: a small ball for steep gradients and a
/// broad one for the shallow gradients of grasped objects (trained on the small ball
/// alone, the LUT read broad contacts 20–30% low).
const CALIBRATION_BALLS_MM: [f64; 2] = [6.0, 25.0];
/// Version of the self-calibration recipe; raise it when the recipe changes so cached
/// models from an older one are not reused (5: the key chosen by [`calibration_input`];
/// 6: the simulator's pixels see their footprint at a contact's rim, so its presses render
/// otherwise; 8: a pixel's label is its footprint's mean slope, `PressTruth::gradients`,
/// and the file says so, `slopes`).
const CALIBRATION_VERSION: u32 = 8;

/// The self-calibrated LUT's key, chosen on its presses' measured pixel noise:
/// - `relative` at ordinary noise, so that the cameras' vignetting (10–22% darker at the
///   middle of a side, up to a third at the corners) does not read a contact at the pad's
///   edge 10–20% shallower than at its centre (docs/control.md, "Against ground truth");
/// - `diff` for presses noisy enough to be read through a blur
///   ([`calibrate::BLUR_ABOVE_NOISE`]): undoing the vignetting also scales up the noise
///   where the pad is darker, and at 5× the nominal noise a finger's force read with the
///   relative key scattered 2.5× as much (σ 0.18 against 0.07 N over a hold), enough to
///   move a steady hold; there the difference key's bias is the lesser error.
fn calibration_input(datasets: &[&PressDataset]) -> crate::Result<Input> {
    let noise = calibrate::pixel_noise(datasets)?;
    Ok(if noise > calibrate::BLUR_ABOVE_NOISE {
        Input::Diff
    } else {
        Input::Relative
    })
}

/// Where automatic calibrations are cached: `$GELGRIP_CACHE_DIR`, else
/// `$XDG_CACHE_HOME/gelgrip`, else `~/.cache/gelgrip`, else the system temp dir.
pub fn cache_dir() -> PathBuf {
    if let Some(d) = std::env::var_os("GELGRIP_CACHE_DIR") {
        return PathBuf::from(d);
    }
    if let Some(d) = std::env::var_os("XDG_CACHE_HOME") {
        return PathBuf::from(d).join("gelgrip");
    }
    if let Some(h) = std::env::var_os("HOME") {
        return PathBuf::from(h).join(".cache").join("gelgrip");
    }
    std::env::temp_dir().join("gelgrip-cache")
}

/// The run's sensing for `config`: each sensor's pipeline with its model. On the simulator
/// each is referenced at once (model files optional: a missing one is calibrated on
/// simulated presses, cached); on a hardware hub every sensor needs a model file, and the
/// references are taken from the first live sets ([`Tactile::new`]).
pub fn open(config: &AppConfig) -> crate::Result<Tactile> {
    let pipeline = PipelineConfig::from_section(&config.pipeline, &config.layout)?;
    let live = config.hub.transport != "sim";
    let pipes = (0..config.layout.sensors.len())
        .map(|i| {
            if live {
                unreferenced_pipeline(config, &pipeline, i)
            } else {
                Ok(sensor_pipeline(config, &pipeline, i)?.0)
            }
        })
        .collect::<crate::Result<Vec<_>>>()?;
    Ok(Tactile::new(pipes, &config.layout, live))
}

/// The cache file of sensor `id`'s calibration on camera `cam` under `sim`.
fn cache_file(id: &str, cam: &SensorCamera, sim: &SimConfig) -> PathBuf {
    // Everything the calibration depends on is in the key, so a changed camera or recipe
    // never reuses an old model: the unit (its position in the layout draws its optics, so
    // f1.tip of a 16-sensor layout is another unit than the three-finger hand's) and the
    // pixel size besides the id; realistic optics add their name and the revision of their
    // fit (nominal keeps its names).
    let optics = match &sim.optics {
        gelgrip_sim::optics::Optics::Nominal => String::new(),
        o => format!(
            "-{}-fit{}",
            o.name(),
            gelgrip_sim::optics::realistic::FIT_REVISION
        ),
    };
    cache_dir().join(format!(
        "sim-v{CALIBRATION_VERSION}{optics}-seed{}-unit{}-{id}-{}x{}px-{}mm-q{}-noise{}-lut-{}+{}mm.safetensors",
        sim.seed,
        cam.unit_index(),
        cam.width,
        cam.height,
        cam.mm_per_px,
        sim.jpeg_quality,
        sim.noise_sigma,
        CALIBRATION_BALLS_MM[0],
        CALIBRATION_BALLS_MM[1]
    ))
}

/// The gradient model of sensor `id`: its configured file, else (on the simulator) a
/// calibration from simulated presses, cached.
fn sensor_model(
    id: &str,
    model: Option<&std::path::Path>,
    cam: &SensorCamera,
    sim: &SimConfig,
) -> crate::Result<LutModel> {
    if let Some(path) = model {
        return LutModel::load(path)
            .with_context(|| format!("sensor {id}: model {}", path.display()));
    }
    let cached = cache_file(id, cam, sim);
    if let Ok(m) = LutModel::load(&cached) {
        return Ok(m);
    }
    tracing::info!(
        sensor = id,
        presses = CALIBRATION_PRESSES,
        "calibrating on simulated presses (cached for later runs)"
    );
    // Runs in one process may calibrate the same sensor at once (tests do, with a cold
    // cache): each calibration collects into its own directories.
    static CALIBRATIONS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let run = CALIBRATIONS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let mut datasets = Vec::new();
    for (k, ball_mm) in CALIBRATION_BALLS_MM.into_iter().enumerate() {
        let tmp = std::env::temp_dir().join(format!(
            "gelgrip-autocal-{}-{run}-{id}-{ball_mm}mm",
            std::process::id()
        ));
        let balls = BallPresses {
            ball_diameter_mm: ball_mm,
            presses: CALIBRATION_PRESSES / CALIBRATION_BALLS_MM.len(),
            seed: sim.seed ^ k as u64,
        };
        datasets.push(collect(cam, balls, &tmp, |_| {})?);
    }
    let refs: Vec<&PressDataset> = datasets.iter().collect();
    let model = calibration_input(&refs).and_then(|input| {
        // The table of bin means the recipe has always used (`calibrate train`'s LUT
        // takes Huber estimates; with these, every simulated run's figures stand as measured).
        let spec = LutSpec::means(input, gelgrip_plugins::lut::DEFAULT_BINS);
        Ok(calibrate::train_lut_on(&refs, spec)?)
    });
    // The images are read while training; the temporary datasets go afterwards.
    for ds in &datasets {
        let _ = std::fs::remove_dir_all(&ds.dir);
    }
    let model = model?;
    if let Some(dir) = cached.parent() {
        let _ = std::fs::create_dir_all(dir);
    }
    // Write aside, then rename: a concurrent run never reads half a file.
    let partial = cached.with_extension(format!("part-{}", std::process::id()));
    match model.save(&partial) {
        Ok(()) => {
            if let Err(e) = std::fs::rename(&partial, &cached) {
                tracing::warn!("could not cache the calibration: {e}");
            }
        }
        Err(e) => tracing::warn!("could not cache the calibration: {e}"),
    }
    Ok(model)
}

/// Sensor `index`'s pipeline, with its model and its reference from no-contact frames, and
/// its simulated camera.
pub fn sensor_pipeline(
    config: &AppConfig,
    pipeline: &PipelineConfig,
    index: usize,
) -> crate::Result<(SensorPipeline, SensorCamera)> {
    let id = config
        .layout
        .sensors
        .get(index)
        .map(|s| s.id.to_string())
        .ok_or(Error::NoSensor { index })?;
    let stages = pipeline.sensors[index].clone();
    let (cam, sim) = sensor_camera(config, &id).with_context(|| {
        format!(
            "sensor {id}: live tactile processing needs the simulated hub for its reference frames"
        )
    })?;
    let model = match (&stages.model, stages.mlp) {
        (Some(path), mode) => {
            let model = GradientModel::load(path, mode.unwrap_or(MlpMode::ContactOnly))
                .with_context(|| format!("sensor {id}: model {}", path.display()))?;
            let is_mlp = matches!(model, GradientModel::Mlp { .. });
            if is_mlp != mode.is_some() {
                return Err(Error::ModelKind {
                    sensor: id,
                    path: path.display().to_string(),
                    kind: if is_mlp { "mlp" } else { "lut" },
                    stage: if mode.is_some() { "mlp" } else { "lut" },
                });
            }
            model
        }
        (None, _) => GradientModel::lut(sensor_model(&id, None, &cam, &sim)?),
    };
    let mut pipe = SensorPipeline::new(
        StageChoice { stages, model },
        cam.width,
        cam.height,
        cam.mm_per_px,
    );
    let quiet = cam.untouched_frames(7_000_000, REFERENCE_FRAMES)?;
    let quiet: Vec<&[u8]> = quiet.iter().map(Vec::as_slice).collect();
    pipe.calibrate(&quiet)
        .with_context(|| format!("sensor {id}: reference frames"))?;
    Ok((pipe, cam))
}

/// The sensors a run's pipelines cannot be built for: on a hardware hub, those without a
/// model file (none on the simulator).
pub fn sensors_without_model(config: &AppConfig) -> crate::Result<Vec<String>> {
    if config.hub.transport == "sim" {
        return Ok(Vec::new());
    }
    let pipeline = PipelineConfig::from_section(&config.pipeline, &config.layout)?;
    Ok(config
        .layout
        .sensors
        .iter()
        .zip(&pipeline.sensors)
        .filter(|(_, stages)| stages.model.is_none())
        .map(|(spec, _)| spec.id.to_string())
        .collect())
}

/// Sensor `index`'s pipeline for frames from a hardware hub: the layout's camera geometry
/// and the configured model file (required: there is no simulated camera to calibrate a
/// LUT on), not yet referenced ([`SensorPipeline::calibrate`] on untouched frames).
pub fn unreferenced_pipeline(
    config: &AppConfig,
    pipeline: &PipelineConfig,
    index: usize,
) -> crate::Result<SensorPipeline> {
    let spec = config
        .layout
        .sensors
        .get(index)
        .ok_or(Error::NoSensor { index })?;
    let stages = pipeline.sensors[index].clone();
    let Some(path) = stages.model.clone() else {
        return Err(Error::Usage(crate::UsageError(format!(
            "{}: sensor {} has no gradient model file; on a hardware hub the pipeline cannot \
             calibrate a LUT on a simulated camera: train one on this sensor's presses \
             (`gelgrip calibrate train`, docs/calibration.md) and set it with \
             [[pipeline.sensors]] id = \"{}\" model = \"….safetensors\"",
            config.file, spec.id, spec.id
        ))));
    };
    let model = GradientModel::load(&path, stages.mlp.unwrap_or(MlpMode::ContactOnly))
        .with_context(|| format!("sensor {}: model {}", spec.id, path.display()))?;
    Ok(SensorPipeline::new(
        StageChoice { stages, model },
        spec.resolution.width_px as usize,
        spec.resolution.height_px as usize,
        spec.mm_per_px,
    ))
}

/// How the sensors are calibrated, as the pipelines decide it ([`open`]): a
/// sensor with a `model` file uses it; the others self-calibrate on simulated presses.
pub fn calibration_text(config: &AppConfig) -> String {
    let sensors = config.layout.sensors.len();
    let from_files = PipelineConfig::from_section(&config.pipeline, &config.layout)
        .map_or(0, |p| {
            p.sensors.iter().filter(|s| s.model.is_some()).count()
        });
    match from_files {
        0 => "self-calibrated LUT per sensor (simulated presses, cached)".into(),
        n if n == sensors => "model files per sensor ([pipeline] model)".into(),
        n => format!(
            "{n} of {sensors} sensors from model files, the others self-calibrated on simulated presses"
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use gelgrip_controller::layout::HandLayout;

    fn layout(file: &str) -> HandLayout {
        let path = format!("{}/configs/layouts/{file}", env!("CARGO_MANIFEST_DIR"));
        let text = std::fs::read_to_string(&path).expect("layout file");
        HandLayout::from_toml(&path, &text).expect("a valid layout")
    }

    /// The same id at another position in another layout is another unit (other optics):
    /// it must not reuse the other's cached calibration.
    #[test]
    fn the_calibration_cache_tells_units_of_the_same_id_apart() {
        let path = format!("{}/configs/gelgripper-sim.toml", env!("CARGO_MANIFEST_DIR"));
        let config = crate::wiring::load_config(
            Some(std::path::Path::new(&path)),
            &crate::wiring::registry(),
        )
        .expect("the shipped config");
        let sim = SimConfig::from_section(&config.hub.section, &config.layout).expect("sim");
        let (three, five) = (layout("three-finger.toml"), layout("five-finger.toml"));
        let file = |l: &HandLayout, id: &str| {
            let i = l.index_of(id).expect("the sensor");
            cache_file(id, &SensorCamera::new(l, i, &sim).expect("camera"), &sim)
        };
        // Each of these ids sits at another position in the five-finger layout.
        for id in ["f1.tip", "f2.middle", "palm"] {
            assert_ne!(three.index_of(id), five.index_of(id), "{id}");
            assert_ne!(file(&three, id), file(&five, id), "{id}");
            assert_eq!(file(&three, id), file(&three, id), "{id}");
        }
    }
}
