//! The JPEG frames each simulated sensor produces.
//!
//! A static scene changes nothing between frames but the camera noise, so each sensor
//! renders `noise_pool` noisy frames once and cycles through them ("model only what the scene
//! requires"). Every frame is a real baseline JPEG at the configured quality; the bus timing
//! uses each frame's actual length.

use std::sync::Arc;

use bytes::Bytes;
use jpeg_encoder::{ColorType, Encoder};

use gelgrip_controller::layout::HandLayout;

use crate::config::SimConfig;
use crate::markers::{GelShear, INK_ALBEDO, MarkerDots};
use crate::optics::{Optics, Shader, render_shaded};
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

thread_local! {
    /// The frame [`SceneCamera::jpeg`] renders before encoding, one per rendering thread
    /// and kept: a frame-sized buffer allocated per frame leaves the allocator's heap to
    /// fragment over a long run (docs/architecture.md, "Memory over a long run").
    static RGB_SCRATCH: std::cell::RefCell<Vec<u8>> = const { std::cell::RefCell::new(Vec::new()) };
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
    noise_seed: u64,
    noise_rgb: [f64; 3],
    optics: Optics,
    quality: u8,
    markers: Option<Arc<MarkerDots>>,
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
            noise_seed: cfg.noise_seed,
            noise_rgb: cfg.noise_rgb,
            optics: cfg.optics.clone(),
            quality: cfg.jpeg_quality,
            markers: s.markers.map(|g| {
                let (w, h) = (
                    s.resolution.width_px as usize,
                    s.resolution.height_px as usize,
                );
                Arc::new(MarkerDots::new(&g, w, h, s.mm_per_px))
            }),
        })
    }

    /// The sensor's position in its layout, which draws its unit variation (two layouts'
    /// sensors of the same id but another position are different units).
    pub fn unit_index(&self) -> usize {
        self.index
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
        let mut rng = rng_for(self.noise_seed, ((self.index as u64) << 40) ^ frame);
        render_shaded(map, &self.shader(), self.noise_rgb, &mut rng)
    }

    /// The camera's noise-free shading.
    pub fn shader(&self) -> Shader {
        Shader::with_optics(
            self.width,
            self.height,
            self.mm_per_px,
            &self.unit,
            &self.optics,
        )
        .with_markers(self.markers.clone())
    }

    /// The camera's optics.
    pub fn optics(&self) -> &Optics {
        &self.optics
    }

    /// The gel's surface under a ball of `diameter_mm` centred at `centre_px` whose cap
    /// inside the contact is `depth_mm` deep (the contact radius `sqrt(2 r d − d²)`, as a
    /// press's labels have it). Realistic optics bring their gel's skirt around the contact
    /// ([`crate::gel`]; the whole press then sits deeper by the skirt's depth at the
    /// contact's edge); otherwise the gel stops at the rim ([`HeightMap::ball_press`]).
    pub fn ball_press_map(
        &self,
        centre_px: (f64, f64),
        diameter_mm: f64,
        depth_mm: f64,
    ) -> HeightMap {
        let skirt_mm = match &self.optics {
            Optics::Realistic(p) => p.skirt_mm,
            Optics::Nominal => 0.0,
        };
        let (w, h) = (self.width, self.height);
        if skirt_mm.is_nan() || skirt_mm <= 0.0 {
            return HeightMap::ball_press(w, h, self.mm_per_px, centre_px, diameter_mm, depth_mm);
        }
        let r = diameter_mm / 2.0;
        let d = depth_mm.clamp(0.0, r);
        let a = (2.0 * r * d - d * d).max(0.0).sqrt();
        crate::gel::BallOnGel::new(r, a, skirt_mm).height_map((w, h), self.mm_per_px, centre_px)
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

/// A camera for scenes in motion: the flat gel's noise-free image is shaded once, each
/// frame re-shades only the pixels around the indentation, and the noise comes from a
/// pre-drawn Gaussian plane read at a different offset per frame (same σ, no per-pixel
/// draws), so one frame costs a fraction of [`SensorCamera::jpeg`].
#[derive(Debug, Clone)]
pub struct SceneCamera {
    camera: SensorCamera,
    shader: Shader,
    base: Vec<f32>,
    noise: Vec<f32>,
}

impl SceneCamera {
    /// The fast path of `camera`.
    pub fn new(camera: SensorCamera) -> Self {
        let (w, h) = (camera.width, camera.height);
        let shader = camera.shader();
        let flat = HeightMap::flat(w, h);
        let base = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .flat_map(|(x, y)| shader.pixel(&flat, x, y).map(|v| v as f32))
            .collect();
        let mut rng = rng_for(camera.noise_seed, ((camera.index as u64) << 40) ^ 0x5CE7E);
        let [r, g, b] = camera.noise_rgb;
        let noise = if r == g && g == b {
            rand_distr::Normal::new(0.0, r.max(0.0) as f32)
                .map(|n| {
                    use rand_distr::Distribution;
                    (0..2 * w * h * 3).map(|_| n.sample(&mut rng)).collect()
                })
                .unwrap_or_else(|_| vec![0.0; 2 * w * h * 3])
        } else {
            // Per-channel σ: a unit plane scaled by each channel's (the plane is read at a
            // multiple of 3 offset, so channels stay aligned).
            use rand_distr::Distribution;
            let unit = rand_distr::StandardNormal;
            (0..2 * w * h * 3)
                .map(|i| {
                    let z: f32 = unit.sample(&mut rng);
                    z * camera.noise_rgb[i % 3].max(0.0) as f32
                })
                .collect()
        };
        Self {
            camera,
            shader,
            base,
            noise,
        }
    }

    /// Render `map`, its markers moved by `shear`, with the noise of frame `frame` and
    /// encode it.
    pub fn jpeg(
        &self,
        map: &HeightMap,
        shear: Option<&GelShear>,
        frame: u64,
    ) -> Result<Vec<u8>, EncodeError> {
        let (w, h) = (self.camera.width, self.camera.height);
        RGB_SCRATCH.with_borrow_mut(|rgb| {
            self.render_into(map, frame, rgb);
            if let (Some(shear), Some(dots)) = (shear, self.shader.markers()) {
                self.shear_markers(map, dots, shear, frame, rgb);
            }
            encode_jpeg(rgb, w as u16, h as u16, self.camera.quality).map_err(|source| {
                EncodeError {
                    sensor: self.camera.index,
                    source,
                }
            })
        })
    }

    /// Whether its gel carries markers.
    pub fn has_markers(&self) -> bool {
        self.shader.markers().is_some()
    }

    /// Where frame `frame` reads the noise plane.
    fn noise_offset(&self, frame: u64) -> usize {
        let n = self.camera.width * self.camera.height * 3;
        let offset = (frame.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 20) as usize % n.max(1);
        // Per-channel noise keeps its channels aligned (uniform noise reads anywhere).
        let [r, g, b] = self.camera.noise_rgb;
        if r == g && g == b {
            offset
        } else {
            offset - offset % 3
        }
    }

    /// Render `map` with the noise of frame `frame` into `rgb` (interleaved 8-bit): the flat
    /// gel's shading everywhere, re-shaded around the indentation, plus the noise plane read
    /// at the frame's offset.
    fn render_into(&self, map: &HeightMap, frame: u64, rgb: &mut Vec<u8>) {
        let (w, h) = (self.camera.width, self.camera.height);
        let n = w * h * 3;
        let offset = self.noise_offset(frame);
        let noise = &self.noise[offset..offset + n];
        let quantise = |v: f32, e: f32| (v + e).round().clamp(0.0, 255.0) as u8;
        rgb.clear();
        rgb.extend(self.base.iter().zip(noise).map(|(v, e)| quantise(*v, *e)));
        if let Some((x0, y0, x1, y1)) = touched_box(map) {
            for y in y0.saturating_sub(1)..(y1 + 1).min(h) {
                for x in x0.saturating_sub(1)..(x1 + 1).min(w) {
                    let shaded = self.shader.pixel(map, x, y);
                    let at = (y * w + x) * 3;
                    for c in 0..3 {
                        rgb[at + c] = quantise(shaded[c] as f32, noise[at + c]);
                    }
                }
            }
        }
    }
}

impl SceneCamera {
    /// Re-shade `rgb` (rendered with the markers at rest) where `shear` moved them: every
    /// pixel a dot covers at rest or moved gets its shade darkened by the moved ink, and
    /// the frame's noise.
    fn shear_markers(
        &self,
        map: &HeightMap,
        dots: &MarkerDots,
        shear: &GelShear,
        frame: u64,
        rgb: &mut [u8],
    ) {
        let (w, h) = (self.camera.width, self.camera.height);
        let noise = &self.noise[self.noise_offset(frame)..];
        SHEAR_SCRATCH.with_borrow_mut(|(ink, touched)| {
            ink.clear();
            ink.resize(w * h, 0.0);
            touched.clear();
            dots.paint(Some(shear), ink, touched);
            for &p in touched.iter() {
                let dark = 1.0 - f64::from(ink[p]) * (1.0 - INK_ALBEDO);
                let shaded = self.shader.shade(map, p % w, p / w);
                for c in 0..3 {
                    let v = (shaded[c] * dark) as f32 + noise[3 * p + c];
                    rgb[3 * p + c] = v.round().clamp(0.0, 255.0) as u8;
                }
            }
        });
    }
}

thread_local! {
    /// [`SceneCamera::shear_markers`]'s ink plane and pixel list, kept per thread.
    static SHEAR_SCRATCH: std::cell::RefCell<(Vec<f32>, Vec<usize>)> =
        const { std::cell::RefCell::new((Vec::new(), Vec::new())) };
}

/// The smallest box (x0, y0, x1 exclusive, y1 exclusive) holding every indented pixel.
fn touched_box(map: &HeightMap) -> Option<(usize, usize, usize, usize)> {
    let w = map.width_px;
    let mut b: Option<(usize, usize, usize, usize)> = None;
    for (i, d) in map.depth_mm.iter().enumerate() {
        if *d != 0.0 {
            let (x, y) = (i % w, i / w);
            b = Some(match b {
                None => (x, y, x + 1, y + 1),
                Some((x0, y0, x1, y1)) => (x0.min(x), y0.min(y), x1.max(x + 1), y1.max(y + 1)),
            });
        }
    }
    b
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

    /// The shipped three-finger layout.
    pub(crate) fn three_finger_layout() -> HandLayout {
        HandLayout::from_toml(
            "three-finger.toml",
            include_str!("../../../configs/layouts/three-finger.toml"),
        )
        .expect("layout")
    }

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

    #[test]
    fn the_scene_camera_matches_the_reference_render_in_colour_noise_and_size() {
        let layout = HandLayout::generated(1).expect("layout");
        let cfg = default_config(&layout);
        let cam = SensorCamera::new(&layout, 0, &cfg).expect("camera");
        let map = cam.builtin_press(&cfg);
        let fast = SceneCamera::new(cam.clone());
        let decode = |jpeg: &[u8]| {
            let mut dec =
                zune_jpeg::JpegDecoder::new(zune_jpeg::zune_core::bytestream::ZCursor::new(jpeg));
            dec.decode().expect("valid JPEG")
        };
        let reference = cam.jpeg(&map, 3).expect("reference");
        let scene = fast.jpeg(&map, None, 3).expect("scene");
        let size_ratio = scene.len() as f64 / reference.len() as f64;
        assert!((0.9..1.1).contains(&size_ratio), "{size_ratio}");
        let (a, b) = (decode(&reference), decode(&scene));
        let mean = |img: &[u8], c: usize| {
            img.iter()
                .skip(c)
                .step_by(3)
                .map(|v| f64::from(*v))
                .sum::<f64>()
                / (img.len() / 3) as f64
        };
        for c in 0..3 {
            assert!((mean(&a, c) - mean(&b, c)).abs() < 1.0, "channel {c}");
        }
        assert_ne!(
            fast.jpeg(&map, None, 4).expect("frame 4"),
            scene,
            "noise differs per frame"
        );
    }

    #[test]
    fn markers_darken_their_dots_and_move_with_the_gels_shear() {
        let text = include_str!("../../../configs/layouts/three-finger-markers.toml");
        let layout = HandLayout::from_toml("three-finger-markers.toml", text).expect("layout");
        let cfg = default_config(&layout);
        let cam = SceneCamera::new(SensorCamera::new(&layout, 0, &cfg).expect("camera"));
        let flat = HeightMap::flat(320, 240);
        let decode = |jpeg: &[u8]| {
            let mut dec =
                zune_jpeg::JpegDecoder::new(zune_jpeg::zune_core::bytestream::ZCursor::new(jpeg));
            dec.decode().expect("valid JPEG")
        };
        // Mean green over a 3 × 3 patch centred at (x, y) (pixel centres at +0.5).
        let green = |img: &[u8], x: f64, y: f64| {
            let (x, y) = (x.floor() as usize, y.floor() as usize);
            let sum: f64 = (y - 1..=y + 1)
                .flat_map(|py| (x - 1..=x + 1).map(move |px| (py * 320 + px) * 3 + 1))
                .map(|i| f64::from(img[i]))
                .sum();
            sum / 9.0
        };
        let rest = decode(&cam.jpeg(&flat, None, 1).expect("frame"));
        let (dot, gel) = (green(&rest, 160.0, 120.0), green(&rest, 169.6, 120.0));
        assert!(dot < 0.45 * gel, "dot {dot} on gel {gel}");
        let shear = GelShear {
            centre_px: (160.0, 120.0),
            direction: (1.0, 0.0),
            traction: crate::traction::Traction::new(1.0, 0.3, 0.9, 2.0),
        };
        let (dx, _) = shear.shift_px((160.0, 120.0), 0.0625);
        assert!((4.0..9.0).contains(&dx), "{dx} px");
        let moved = decode(&cam.jpeg(&flat, Some(&shear), 1).expect("frame"));
        assert!(green(&moved, 160.0 + dx, 120.0) < 0.45 * gel);
        assert!(green(&moved, 160.0 - 3.0, 120.0) > 0.8 * gel, "left behind");
        // Far from the contact the dots stay where they were.
        let far = (160.0 - 7.0 * 19.2, 120.0 - 5.0 * 19.2);
        assert!((green(&moved, far.0, far.1) - green(&rest, far.0, far.1)).abs() < 8.0);
    }

    #[test]
    fn a_noise_seed_redraws_the_noise_alone() {
        let layout = HandLayout::generated(1).expect("layout");
        let cfg = default_config(&layout);
        assert_eq!(
            cfg.noise_seed, cfg.seed,
            "the noise follows `seed` by default"
        );
        let redrawn = SimConfig {
            noise_seed: cfg.seed ^ 0x2,
            ..cfg.clone()
        };
        let cam = SensorCamera::new(&layout, 0, &cfg).expect("camera");
        let other = SensorCamera::new(&layout, 0, &redrawn).expect("camera");
        let map = cam.builtin_press(&cfg);
        assert_eq!(cam.rgb(&map, 5), cam.rgb(&map, 5), "a draw replays");
        let (a, b) = (cam.rgb(&map, 5), other.rgb(&map, 5));
        let differing = a.iter().zip(&b).filter(|(x, y)| x != y).count();
        assert!(differing > a.len() / 2, "{differing} of {} differ", a.len());
        // The same unit: the noise-free shading is the same, and so is the mean colour.
        let flat = HeightMap::flat(cam.width, cam.height);
        for (x, y) in [(0, 0), (160, 120), (319, 239)] {
            assert_eq!(
                cam.shader().pixel(&flat, x, y),
                other.shader().pixel(&flat, x, y)
            );
        }
        let mean = |img: &[u8]| img.iter().map(|v| f64::from(*v)).sum::<f64>() / img.len() as f64;
        assert!(
            (mean(&a) - mean(&b)).abs() < 0.1,
            "{} vs {}",
            mean(&a),
            mean(&b)
        );
    }
}
