//! The `[hub.sim]` section: raw TOML validated into [`SimConfig`].

use serde::Deserialize;

use gelgrip_controller::config::{BackendSection, ConfigError};
use gelgrip_controller::layout::HandLayout;
use gelgrip_controller::runtime::control::{MAX_CLOCK_DRIFT_PPM, MAX_JITTER_US};

use crate::optics::Optics;
use crate::optics::realistic::{MINI, MINI_GEL};
use crate::scene_spec::SceneSpec;

/// Faults injected into one sensor.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SensorFaults {
    /// The sensor captures this much later than its trigger (spread grows), µs.
    pub capture_delay_us: u32,
    /// Its frame reaches the host this much later (age grows), µs.
    pub delivery_delay_us: u32,
    /// Probability that a frame is lost.
    pub drop_rate: f64,
    /// Probability that a frame has one bit flipped on the bus.
    pub corrupt_rate: f64,
    /// The board stops answering: no frame, reported `Disconnected` for every trigger.
    pub dead: bool,
    /// Each capture is late by a further uniform random 0 to this (per frame), µs.
    pub capture_jitter_us: u32,
    /// The board's clock runs fast (+) or slow (−): its capture stamps drift from true time
    /// by this × the time since the drift took effect (see [`crate::board_clock`]), ppm.
    pub clock_drift_ppm: f64,
}

/// A validated simulated-hub configuration.
#[derive(Debug, Clone, PartialEq)]
pub struct SimConfig {
    /// Seed of every random draw (unit variation, presses, faults; the noise too unless
    /// `noise_seed` is given).
    pub seed: u64,
    /// Seed of the cameras' noise alone (`noise_seed`; `seed` when not given): the same
    /// units, presses and scene under a fresh draw of noise.
    pub noise_seed: u64,
    /// JPEG quality 1–100.
    pub jpeg_quality: u8,
    /// SPI clock, Hz.
    pub spi_clock_hz: u32,
    /// I2C clock, Hz.
    pub i2c_hz: u32,
    /// Board buffering time after capture, µs.
    pub t_buf_us: u32,
    /// Coordinator-to-host forwarding time, µs.
    pub t_usb_us: u32,
    /// Bound on each board's trigger-to-capture jitter, µs.
    pub capture_jitter_us: u32,
    /// Standard deviation of the camera noise, in 8-bit grey levels (the nominal optics';
    /// with realistic optics, the value given or the fitted per-channel noise's mean).
    pub noise_sigma: f64,
    /// The camera noise per channel, grey levels: `noise_sigma` in each, or, with realistic
    /// optics and no `noise_sigma` given, the fitted sensor's.
    pub noise_rgb: [f64; 3],
    /// Image formation (`optics = "nominal"` unless the config asks for `"realistic"`).
    pub optics: Optics,
    /// Distinct noisy frames rendered per sensor (a static scene needs no more).
    pub noise_pool: usize,
    /// Hub clock value at host time 0, µs (to place the u32 wrap anywhere).
    pub hub_clock_start_us: u32,
    /// Ball diameter of the built-in presses, mm.
    pub ball_diameter_mm: f64,
    /// Depth of the built-in presses, mm (0 = no contact).
    pub press_depth_mm: f64,
    /// Faults per sensor index.
    pub faults: Vec<SensorFaults>,
    /// The scene the fingers close on (`None` = the built-in static presses).
    pub scene: Option<SceneSpec>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields, default)]
struct RawSim {
    scene: Option<String>,
    seed: u64,
    noise_seed: Option<u64>,
    jpeg_quality: i64,
    spi_clock_hz: f64,
    i2c_hz: f64,
    t_buf_us: f64,
    t_usb_us: f64,
    capture_jitter_us: f64,
    noise_sigma: Option<f64>,
    optics: String,
    noise_pool: i64,
    hub_clock_start_us: u32,
    ball_diameter_mm: f64,
    press_depth_mm: f64,
    faults: Vec<RawFault>,
}

impl Default for RawSim {
    fn default() -> Self {
        Self {
            scene: None,
            seed: 1,
            noise_seed: None,
            jpeg_quality: 85,
            spi_clock_hz: 40e6,
            i2c_hz: 400e3,
            t_buf_us: 1000.0,
            t_usb_us: 500.0,
            capture_jitter_us: 2.0,
            noise_sigma: None,
            optics: "nominal".into(),
            noise_pool: 8,
            hub_clock_start_us: 0,
            ball_diameter_mm: 6.0,
            press_depth_mm: 0.5,
            faults: Vec::new(),
        }
    }
}

/// Camera noise tuned with quality 85 so a 320×240 contact frame is about 20 KB (the paper's
/// S); see `docs/sim.md` for the measurement.
pub const DEFAULT_NOISE_SIGMA: f64 = 10.0;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawFault {
    sensor: String,
    #[serde(default)]
    capture_delay_us: f64,
    #[serde(default)]
    delivery_delay_us: f64,
    #[serde(default)]
    drop_rate: f64,
    #[serde(default)]
    corrupt_rate: f64,
    #[serde(default)]
    dead: bool,
    #[serde(default)]
    capture_jitter_us: f64,
    #[serde(default)]
    clock_drift_ppm: f64,
}

impl SimConfig {
    /// Validate `section` for `layout`.
    pub fn from_section(
        section: &BackendSection,
        layout: &HandLayout,
    ) -> Result<Self, ConfigError> {
        let check = &section.check;
        let p = |k: &str| format!("{}.{k}", section.prefix);
        let raw: RawSim = check.parse_table(&section.prefix, &section.table)?;
        let scene = match &raw.scene {
            None => None,
            Some(rel) => {
                let path = section.base_dir.join(rel);
                let text = section.files.read(&path)?;
                Some(SceneSpec::from_toml(
                    &path.display().to_string(),
                    &text,
                    layout,
                )?)
            }
        };
        let optics = match raw.optics.as_str() {
            "nominal" => Optics::Nominal,
            "realistic" => Optics::Realistic(Box::new(MINI)),
            "realistic-gel" => Optics::Realistic(Box::new(MINI_GEL)),
            other => {
                return Err(check.invalid(
                    &p("optics"),
                    other,
                    "\"nominal\", \"realistic\" or \"realistic-gel\"",
                ));
            }
        };
        let (noise_sigma, noise_rgb) = match (raw.noise_sigma, &optics) {
            (Some(s), _) => {
                let s = check.range(&p("noise_sigma"), s, 0.0, 64.0)?;
                (s, [s; 3])
            }
            (None, Optics::Nominal) => (DEFAULT_NOISE_SIGMA, [DEFAULT_NOISE_SIGMA; 3]),
            (None, Optics::Realistic(r)) => (r.noise_rgb.iter().sum::<f64>() / 3.0, r.noise_rgb),
        };
        let faults = sensor_faults(section, &raw.faults, layout)?;
        Ok(Self {
            seed: raw.seed,
            noise_seed: raw.noise_seed.unwrap_or(raw.seed),
            jpeg_quality: check.range(&p("jpeg_quality"), raw.jpeg_quality as f64, 1.0, 100.0)?
                as u8,
            spi_clock_hz: check.range(&p("spi_clock_hz"), raw.spi_clock_hz, 1e5, 6e7)? as u32,
            i2c_hz: check.range(&p("i2c_hz"), raw.i2c_hz, 1e4, 1e6)? as u32,
            t_buf_us: check.range(&p("t_buf_us"), raw.t_buf_us, 0.0, 1e6)? as u32,
            t_usb_us: check.range(&p("t_usb_us"), raw.t_usb_us, 0.0, 1e6)? as u32,
            capture_jitter_us: check.range(
                &p("capture_jitter_us"),
                raw.capture_jitter_us,
                0.0,
                1e4,
            )? as u32,
            noise_sigma,
            noise_rgb,
            optics,
            noise_pool: check.range(&p("noise_pool"), raw.noise_pool as f64, 1.0, 256.0)? as usize,
            hub_clock_start_us: raw.hub_clock_start_us,
            ball_diameter_mm: check.range(
                &p("ball_diameter_mm"),
                raw.ball_diameter_mm,
                0.5,
                50.0,
            )?,
            press_depth_mm: check.range(&p("press_depth_mm"), raw.press_depth_mm, 0.0, 3.0)?,
            faults,
            scene,
        })
    }
}

/// The `faults` of the `[hub.sim]` section, one per sensor of `layout` (none where unset).
fn sensor_faults(
    section: &BackendSection,
    raw_faults: &[RawFault],
    layout: &HandLayout,
) -> Result<Vec<SensorFaults>, ConfigError> {
    let check = &section.check;
    let mut faults = vec![SensorFaults::default(); layout.sensors.len()];
    for (i, f) in raw_faults.iter().enumerate() {
        let field = |k: &str| format!("{}.faults[{i}].{k}", section.prefix);
        let Some(idx) = layout.index_of(&f.sensor) else {
            let expected = format!("a sensor of the layout: {}", layout.id_list());
            return Err(check.invalid(&field("sensor"), &f.sensor, &expected));
        };
        faults[idx] = SensorFaults {
            capture_delay_us: check.range(
                &field("capture_delay_us"),
                f.capture_delay_us,
                0.0,
                1e6,
            )? as u32,
            delivery_delay_us: check.range(
                &field("delivery_delay_us"),
                f.delivery_delay_us,
                0.0,
                1e7,
            )? as u32,
            drop_rate: check.range(&field("drop_rate"), f.drop_rate, 0.0, 1.0)?,
            corrupt_rate: check.range(&field("corrupt_rate"), f.corrupt_rate, 0.0, 1.0)?,
            dead: f.dead,
            capture_jitter_us: check.range(
                &field("capture_jitter_us"),
                f.capture_jitter_us,
                0.0,
                f64::from(MAX_JITTER_US),
            )? as u32,
            clock_drift_ppm: check.range(
                &field("clock_drift_ppm"),
                f.clock_drift_ppm,
                -MAX_CLOCK_DRIFT_PPM,
                MAX_CLOCK_DRIFT_PPM,
            )?,
        };
    }
    Ok(faults)
}

#[cfg(test)]
mod tests;
