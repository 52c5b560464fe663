//! One simulated sensor's camera as the controller's [`PressCamera`] port: the frames a
//! calibration collects (ball presses and untouched frames) through the same camera model
//! and JPEG encoder as live frames. [`sensor_camera`] finds the camera of a sensor of a
//! config on the simulated hub.

use gelgrip_controller::camera::{CaptureError, PressCamera};
use gelgrip_controller::config::{AppConfig, ConfigError};
use thiserror::Error;

use crate::config::SimConfig;
use crate::pool::SensorCamera;
use crate::scene::HeightMap;

/// Why a sensor has no simulated camera.
#[derive(Debug, Error)]
pub enum SensorCameraError {
    /// The config's hub is not the simulator.
    #[error(
        "{file}: this command runs on the simulator (hub.transport = \"sim\"), not `{transport}`"
    )]
    NotSimulated {
        /// The config file.
        file: String,
        /// Its hub transport.
        transport: String,
    },
    /// The `[hub.sim]` section is invalid (a configuration error).
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// No such sensor in the layout.
    #[error("no sensor `{id}` in layout `{layout}`; sensors: {known}")]
    UnknownSensor {
        /// The id asked for.
        id: String,
        /// The layout's name.
        layout: String,
        /// Its sensors' ids.
        known: String,
    },
}

/// The simulated camera of sensor `id` in `config`, and the simulator's settings.
pub fn sensor_camera(
    config: &AppConfig,
    id: &str,
) -> Result<(SensorCamera, SimConfig), SensorCameraError> {
    if config.hub.transport != "sim" {
        return Err(SensorCameraError::NotSimulated {
            file: config.file.clone(),
            transport: config.hub.transport.clone(),
        });
    }
    let sim = SimConfig::from_section(&config.hub.section, &config.layout)?;
    let unknown = || SensorCameraError::UnknownSensor {
        id: id.to_string(),
        layout: config.layout.name.clone(),
        known: config.layout.id_list(),
    };
    let index = config.layout.index_of(id).ok_or_else(unknown)?;
    let cam = SensorCamera::new(&config.layout, index, &sim).ok_or_else(unknown)?;
    Ok((cam, sim))
}

impl SensorCamera {
    /// `n` untouched JPEG frames, numbered from `first`.
    pub fn untouched_frames(&self, first: u64, n: u64) -> Result<Vec<Vec<u8>>, CaptureError> {
        (first..first + n).map(|k| self.untouched_jpeg(k)).collect()
    }
}

fn capture_error(nth: u64) -> impl FnOnce(crate::pool::EncodeError) -> CaptureError {
    move |e| CaptureError {
        nth,
        detail: e.to_string(),
    }
}

impl PressCamera for SensorCamera {
    fn size_px(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    fn mm_per_px(&self) -> f64 {
        self.mm_per_px
    }

    fn untouched_jpeg(&self, nth: u64) -> Result<Vec<u8>, CaptureError> {
        let flat = HeightMap::flat(self.width, self.height);
        self.jpeg(&flat, nth).map_err(capture_error(nth))
    }

    fn ball_press_jpeg(
        &self,
        centre_px: (f64, f64),
        diameter_mm: f64,
        depth_mm: f64,
        nth: u64,
    ) -> Result<Vec<u8>, CaptureError> {
        let map = self.ball_press_map(centre_px, diameter_mm, depth_mm);
        self.jpeg(&map, nth).map_err(capture_error(nth))
    }
}
