//! Image formation: Lambertian shading of the indented gel under three coloured side lights.
//!
//! The gel's reflective skin is lit by a red, a green and a blue LED placed around the pad at
//! a low elevation. Its normal follows the indentation: with depth `d(x, y)` into the gel
//! (mm) the surface normal is `n ∝ (∂d/∂x, ∂d/∂y, 1)`. Channel `c` then sees
//!
//! `I_c = gain_c · V(r) · base_c · (ambient + k · max(0, n·L_c)) / (ambient + k · L_c,z) + offset_c + noise`
//!
//! so a flat gel shows the base colour, slopes facing an LED brighten its channel and slopes
//! facing away darken it. `V(r) = 1 − v·r²` is the lens vignetting (r = 1 at the corner).
//! Values are clamped to 0–255, so saturated and black pixels occur naturally at extremes.
//!
//! That is the nominal optics. A config may ask for [`realistic`] optics instead
//! (`[hub.sim] optics = "realistic"`), fitted to a real GelSight Mini by [`fit`].

pub mod facet;
pub mod fit;
pub mod realistic;
pub mod response;

use std::sync::Arc;

use rand::Rng;
use rand_distr::{Distribution, Normal};

use crate::markers::MarkerDots;

use crate::scene::HeightMap;
use crate::unit::UnitVariation;

/// LED azimuths (degrees, image x towards y) of the red, green and blue lights.
const LED_AZIMUTH_DEG: [f64; 3] = [90.0, 210.0, 330.0];
/// LED elevation above the gel plane, degrees.
const LED_ELEVATION_DEG: f64 = 30.0;
/// Flat-gel colour before unit variation, grey levels.
const BASE_RGB: [f64; 3] = [150.0, 140.0, 130.0];
/// Diffuse share of the light that does not depend on the normal.
const AMBIENT: f64 = 0.3;
/// Directional share.
const DIRECTIONAL: f64 = 1.0;

fn light_directions() -> [[f64; 3]; 3] {
    let el = LED_ELEVATION_DEG.to_radians();
    LED_AZIMUTH_DEG.map(|az| {
        let az = az.to_radians();
        [el.cos() * az.cos(), el.cos() * az.sin(), el.sin()]
    })
}

/// Which image formation a simulated camera uses.
#[derive(Debug, Clone, PartialEq, Default)]
pub enum Optics {
    /// Lambertian shading, radial vignetting, one noise σ (this module's model).
    #[default]
    Nominal,
    /// [`realistic`]: specular lobe, shadowing, LED falloff, crosstalk, gamma, per-channel
    /// noise.
    Realistic(Box<realistic::RealisticParams>),
}

impl Optics {
    /// The config's name of these optics.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Nominal => "nominal",
            // The gel's skirt renders presses otherwise (cached models are keyed apart).
            Self::Realistic(p) if p.skirt_mm > 0.0 => "realistic-gel",
            Self::Realistic(_) => "realistic",
        }
    }
}

/// The noise-free shading of one camera: its unit variation and lights, per pixel.
#[derive(Debug, Clone)]
pub struct Shader {
    lights: [[f64; 3]; 3],
    half_diag2: f64,
    mm_per_px: f64,
    unit: UnitVariation,
    realistic: Option<Box<realistic::RealisticShader>>,
    /// The dots printed on the gel, if any.
    markers: Option<Arc<MarkerDots>>,
}

impl Shader {
    /// The shader of a camera with pixels of `mm_per_px` and `unit`'s variation.
    pub fn new(width_px: usize, height_px: usize, mm_per_px: f64, unit: &UnitVariation) -> Self {
        Self::with_optics(width_px, height_px, mm_per_px, unit, &Optics::Nominal)
    }

    /// [`Shader::new`] with `optics`.
    pub fn with_optics(
        width_px: usize,
        height_px: usize,
        mm_per_px: f64,
        unit: &UnitVariation,
        optics: &Optics,
    ) -> Self {
        let (w, h) = (width_px, height_px);
        Self {
            lights: light_directions(),
            half_diag2: ((w * w + h * h) as f64 / 4.0).max(1.0),
            mm_per_px,
            unit: *unit,
            realistic: match optics {
                Optics::Nominal => None,
                Optics::Realistic(p) => {
                    Some(Box::new(realistic::RealisticShader::new(p, w, h, unit)))
                }
            },
            markers: None,
        }
    }

    /// This shader with `markers` printed on its gel.
    pub fn with_markers(mut self, markers: Option<Arc<MarkerDots>>) -> Self {
        self.markers = markers;
        self
    }

    /// The dots printed on the gel, if any.
    pub fn markers(&self) -> Option<&MarkerDots> {
        self.markers.as_deref()
    }

    /// Noise-free RGB of pixel (`x`, `y`) of `map` with the markers at rest: [`Self::shade`]
    /// darkened where a dot's ink is.
    pub fn pixel(&self, map: &HeightMap, x: usize, y: usize) -> [f64; 3] {
        let rgb = self.shade(map, x, y);
        match &self.markers {
            Some(m) => rgb.map(|v| v * m.rest_factor(x, y)),
            None => rgb,
        }
    }

    /// Noise-free RGB of pixel (`x`, `y`) of `map` without markers: the light of its footprint, the
    /// pressed share's slope and the rest flat ([`facet`]).
    pub fn shade(&self, map: &HeightMap, x: usize, y: usize) -> [f64; 3] {
        let f = facet::facet(map, x, y, self.mm_per_px);
        if let Some(r) = &self.realistic {
            return r.shade_covered(x, y, (f.gx, f.gy), f.coverage);
        }
        let (w, h) = (map.width_px, map.height_px);
        let dx = x as f64 - w as f64 / 2.0;
        let dy = y as f64 - h as f64 / 2.0;
        let vignette = 1.0 - self.unit.vignetting * (dx * dx + dy * dy) / self.half_diag2;
        let pressed = self.shades(f.gx, f.gy);
        let mut rgb = [0.0; 3];
        for (c, v) in rgb.iter_mut().enumerate() {
            // A flat facet's shade is 1; the camera's light is linear in it.
            let shade = f.coverage * pressed[c] + (1.0 - f.coverage);
            *v = self.unit.led_gain[c] * vignette * BASE_RGB[c] * shade + self.unit.offset[c];
        }
        rgb
    }

    /// The nominal optics' shade per channel of a facet with gradient (`gx`, `gy`),
    /// relative to a flat one's.
    fn shades(&self, gx: f64, gy: f64) -> [f64; 3] {
        let norm = (gx * gx + gy * gy + 1.0).sqrt();
        let n = [gx / norm, gy / norm, 1.0 / norm];
        self.lights.map(|l| {
            let lambert = (n[0] * l[0] + n[1] * l[1] + n[2] * l[2]).max(0.0);
            (AMBIENT + DIRECTIONAL * lambert) / (AMBIENT + DIRECTIONAL * l[2])
        })
    }
}

/// Render `map` (pixel size `mm_per_px`) as interleaved 8-bit RGB.
pub fn render(
    map: &HeightMap,
    mm_per_px: f64,
    unit: &UnitVariation,
    noise_sigma: f64,
    rng: &mut impl Rng,
) -> Vec<u8> {
    let shader = Shader::new(map.width_px, map.height_px, mm_per_px, unit);
    render_shaded(map, &shader, [noise_sigma; 3], rng)
}

/// Render `map` with `shader` and Gaussian noise of `noise_rgb` grey levels per channel.
pub fn render_shaded(
    map: &HeightMap,
    shader: &Shader,
    noise_rgb: [f64; 3],
    rng: &mut impl Rng,
) -> Vec<u8> {
    let (w, h) = (map.width_px, map.height_px);
    let uniform = noise_rgb[0] == noise_rgb[1] && noise_rgb[1] == noise_rgb[2];
    let noise = noise_rgb.map(|s| Normal::new(0.0, s.max(0.0)).ok());
    let mut out = Vec::with_capacity(w * h * 3);
    for y in 0..h {
        for x in 0..w {
            for (c, mut v) in shader.pixel(map, x, y).into_iter().enumerate() {
                // One distribution for all channels when they share σ (the nominal draws).
                if let Some(n) = &noise[if uniform { 0 } else { c }] {
                    v += n.sample(rng);
                }
                // NaN casts to 0.
                out.push(v.round().clamp(0.0, 255.0) as u8);
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::unit::rng_for;

    const UNIT: UnitVariation = UnitVariation::NEUTRAL;

    #[test]
    fn flat_gel_shows_the_base_colour() {
        let img = render(&HeightMap::flat(8, 6), 0.1, &UNIT, 0.0, &mut rng_for(1, 1));
        assert_eq!(&img[0..3], &[150, 140, 130]);
        assert!(img.chunks(3).all(|p| p == [150, 140, 130]));
    }

    #[test]
    fn slope_towards_the_red_led_brightens_red() {
        // Red LED at azimuth 90° lies towards +y. A surface whose normal tips towards +y has
        // depth increasing with y (n ∝ (∂d/∂x, ∂d/∂y, 1)).
        let mut map = HeightMap::flat(8, 8);
        for y in 0..8 {
            for x in 0..8 {
                map.depth_mm[y * 8 + x] = y as f32 * 0.05;
            }
        }
        let img = render(&map, 0.1, &UNIT, 0.0, &mut rng_for(1, 1));
        let centre = &img[(4 * 8 + 4) * 3..(4 * 8 + 4) * 3 + 3];
        assert!(centre[0] > 150, "{centre:?}");
        assert!(centre[1] < 140 && centre[2] < 130, "{centre:?}");
    }

    #[test]
    fn extreme_slopes_stay_in_range() {
        let mut map = HeightMap::flat(4, 4);
        map.depth_mm[5] = 1e6;
        let img = render(&map, 1e-4, &UNIT, 30.0, &mut rng_for(1, 1));
        assert_eq!(img.len(), 48);
    }
}
