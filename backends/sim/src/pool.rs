//! The JPEG frames each simulated sensor produces.
//!
//! A static scene changes nothing between frames but the camera noise, so each sensor
//! renders `noise_pool` noisy frames once and cycles through them ("model only what the scene
//! requires"). Every frame is a real baseline JPEG at the configured quality; the bus timing
//! uses each frame's actual length.

use bytes::Bytes;
use jpeg_encoder::{ColorType, Encoder};

use gelgrip_controller::layout::HandLayout;

use crate::config::SimConfig;
use crate::optics::render;
use crate::scene::HeightMap;
use crate::unit::{UnitVariation, rng_for};

/// JPEG encoding failed.
#[derive(Debug, thiserror::Error)]
#[error("JPEG encoding of sensor {sensor} failed: {source}")]
pub struct EncodeError {
    /// Sensor index.
    pub sensor: usize,
    /// The encoder's error.
    pub source: jpeg_encoder::EncodingError,
}

/// Encode interleaved RGB as a baseline JPEG.
pub fn encode_jpeg(
    rgb: &[u8],
    width_px: u16,
    height_px: u16,
    quality: u8,
) -> Result<Vec<u8>, jpeg_encoder::EncodingError> {
    let mut out = Vec::new();
    Encoder::new(&mut out, quality).encode(rgb, width_px, height_px, ColorType::Rgb)?;
    Ok(out)
}

/// One simulated sensor's camera: its unit variation, optics and encoder.
#[derive(Debug, Clone)]
pub struct SensorCamera {
    index: usize,
    /// Image width, px.
    pub width: usize,
    /// Image height, px.
    pub height: usize,
    /// Pixel size, mm.
    pub mm_per_px: f64,
    unit: UnitVariation,
    seed: u64,
    noise_sigma: f64,
    quality: u8,
}

impl SensorCamera {
    /// The camera of sensor `index` of `layout` under `cfg`.
    pub fn new(layout: &HandLayout, index: usize, cfg: &SimConfig) -> Option<Self> {
        let s = layout.sensors.get(index)?;
        Some(Self {
            index,
            width: s.resolution.width_px as usize,
            height: s.resolution.height_px as usize,
            mm_per_px: s.mm_per_px,
            unit: UnitVariation::draw(cfg.seed, index),
            seed: cfg.seed,
            noise_sigma: cfg.noise_sigma,
            quality: cfg.jpeg_quality,
        })
    }

    /// The built-in press of this sensor (what `hub.sim` serves).
    pub fn builtin_press(&self, cfg: &SimConfig) -> HeightMap {
        HeightMap::builtin_press(
            self.index,
            self.width,
            self.height,
            self.mm_per_px,
            cfg.ball_diameter_mm,
            cfg.press_depth_mm,
        )
    }

    /// Render `map` as RGB with the noise of frame number `frame`.
    pub fn rgb(&self, map: &HeightMap, frame: u64) -> Vec<u8> {
        let mut rng = rng_for(self.seed, ((self.index as u64) << 40) ^ frame);
        render(map, self.mm_per_px, &self.unit, self.noise_sigma, &mut rng)
    }

    /// Render `map` and encode it as the sensor's JPEG.
    pub fn jpeg(&self, map: &HeightMap, frame: u64) -> Result<Vec<u8>, EncodeError> {
        let rgb = self.rgb(map, frame);
        encode_jpeg(&rgb, self.width as u16, self.height as u16, self.quality).map_err(|source| {
            EncodeError {
                sensor: self.index,
                source,
            }
        })
    }
}

/// Pre-rendered frames per sensor.
#[derive(Debug, Clone)]
pub struct FramePool {
    frames: Vec<Vec<Bytes>>,
}

impl FramePool {
    /// Render and encode the pool for every sensor of `layout`.
    pub fn render(layout: &HandLayout, cfg: &SimConfig) -> Result<Self, EncodeError> {
        let frames = (0..layout.sensors.len())
            .filter_map(|i| SensorCamera::new(layout, i, cfg))
            .map(|cam| {
                let map = cam.builtin_press(cfg);
                (0..cfg.noise_pool as u64)
                    .map(|k| cam.jpeg(&map, k).map(Bytes::from))
                    .collect::<Result<Vec<_>, _>>()
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Self { frames })
    }

    /// Render and encode an untouched gel for every sensor of `layout` (what a scene's
    /// sensors show until something touches them).
    pub fn render_flat(layout: &HandLayout, cfg: &SimConfig) -> Result<Self, EncodeError> {
        let frames = (0..layout.sensors.len())
            .filter_map(|i| SensorCamera::new(layout, i, cfg))
            .map(|cam| {
                let map = HeightMap::flat(cam.width, cam.height);
                (0..cfg.noise_pool as u64)
                    .map(|k| cam.jpeg(&map, k).map(Bytes::from))
                    .collect::<Result<Vec<_>, _>>()
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Self { frames })
    }

    /// The frame sensor `sensor` produces for its `nth` capture.
    pub fn frame(&self, sensor: usize, nth: u64) -> Option<&Bytes> {
        let frames = self.frames.get(sensor)?;
        frames.get((nth % frames.len().max(1) as u64) as usize)
    }

    /// Mean JPEG length over all sensors and frames, bytes.
    pub fn mean_jpeg_bytes(&self) -> f64 {
        let (sum, n) = self
            .frames
            .iter()
            .flatten()
            .fold((0usize, 0usize), |(s, n), f| (s + f.len(), n + 1));
        if n == 0 { 0.0 } else { sum as f64 / n as f64 }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use gelgrip_controller::config::DiskFiles;
    use gelgrip_controller::config::{BackendSection, FieldCheck};

    pub(crate) fn default_config(layout: &HandLayout) -> SimConfig {
        let section = BackendSection {
            check: FieldCheck::new("test"),
            prefix: "hub.sim".into(),
            table: toml::Table::new(),
            base_dir: ".".into(),
            files: std::sync::Arc::new(DiskFiles),
        };
        SimConfig::from_section(&section, layout).expect("defaults are valid")
    }

    #[test]
    fn default_contact_frames_are_about_20_kb_and_decode() {
        let layout = HandLayout::generated(7).expect("layout");
        let cfg = default_config(&layout);
        let pool = FramePool::render(&layout, &cfg).expect("render");
        let mean = pool.mean_jpeg_bytes();
        eprintln!("mean JPEG {mean:.0} bytes");
        assert!(
            (17_000.0..23_000.0).contains(&mean),
            "mean JPEG {mean} bytes"
        );
        let jpeg = pool.frame(3, 11).expect("frame");
        let mut dec = zune_jpeg::JpegDecoder::new(zune_jpeg::zune_core::bytestream::ZCursor::new(
            jpeg.as_ref(),
        ));
        let pixels = dec.decode().expect("valid JPEG");
        assert_eq!(pixels.len(), 320 * 240 * 3);
    }
}
